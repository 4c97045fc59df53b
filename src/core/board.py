"""A planar board of markers: OpenCV's ChArUco and grid boards, their frames and their points.

Conventions (docs/conventions.md §6): the board frame is OpenCV's (``cv2.aruco.Board``): origin
at the board's top-left corner as printed, x along its first row, y down its columns, z into the
board, metres. A marker's own frame is simgap's (:mod:`simgap.core.aruco`: origin at the centre
of its black square, x right, y up, z out of the print), so each marker's rotation in the board
frame is ``diag(1, -1, -1)`` and its corners TL, TR, BR, BL are OpenCV's board object points.
A ChArUco board's chessboard corners (the saddle points between black squares) are its
reference points: their position does not depend on the ink's edge, unlike a marker's corners.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from simgap.core import transforms as tf
from simgap.core.aruco import check_dictionary, predefined_dictionary
from simgap.core.config import from_mapping, read_yaml, require

#: Board kinds: OpenCV's ``CharucoBoard`` (markers in the white squares of a chessboard) and
#: ``GridBoard`` (a grid of markers with a gap between them).
BOARD_KINDS = ("charuco", "grid")

#: A marker's axes in the board frame (module doc): x along the board's x, y and z opposite.
BOARD_FROM_MARKER_ROTATION = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class Board:
    """A printed board of markers (lengths in metres, as printed).

    Attributes
    ----------
    kind : {"charuco", "grid"}
        ``charuco``: ``columns`` x ``rows`` chessboard squares of side ``square_m``, a marker of
        side ``marker_m`` in each white square (``cv2.aruco.CharucoBoard``); ``grid``:
        ``columns`` x ``rows`` markers of side ``marker_m`` with ``separation_m`` between them
        (``cv2.aruco.GridBoard``).
    columns, rows : int
        Squares (ChArUco) or markers (grid) along the board's x and y.
    marker_m : float
        Side of a marker's black square (m).
    dictionary : str
        ``cv2.aruco`` predefined dictionary name; markers take its ids from 0 in OpenCV's order.
    square_m : float or None
        ChArUco only: side of a chessboard square (m), larger than ``marker_m``.
    separation_m : float or None
        Grid only: gap between neighbouring markers (m).
    legacy_pattern : bool
        ChArUco only: OpenCV's pattern before 4.6 for an even number of rows
        (``setLegacyPattern``).
    """

    kind: Literal["charuco", "grid"]
    columns: int
    rows: int
    marker_m: float
    dictionary: str = "DICT_6X6_250"
    square_m: float | None = None
    separation_m: float | None = None
    legacy_pattern: bool = False

    def __post_init__(self) -> None:
        require(self.kind in BOARD_KINDS, f"kind: expected one of {', '.join(BOARD_KINDS)}")
        require(self.columns >= 2, "columns: expected an integer >= 2")
        require(self.rows >= 2, "rows: expected an integer >= 2")
        require(self.marker_m > 0, "marker_m: expected a positive length (m)")
        check_dictionary(self.dictionary)
        if self.kind == "charuco":
            require(
                self.square_m is not None and self.square_m > self.marker_m,
                "square_m: expected the chessboard square's side (m), larger than marker_m",
            )
            require(self.separation_m is None, "separation_m: only for kind: grid")
        else:
            require(
                self.separation_m is not None and self.separation_m > 0,
                "separation_m: expected the gap between markers (m), > 0",
            )
            require(self.square_m is None, "square_m: only for kind: charuco")
        n_markers = len(self.opencv.getIds())
        require(
            n_markers <= predefined_dictionary(self.dictionary).bytesList.shape[0],
            f"dictionary: {self.dictionary} has fewer markers than the board's {n_markers}",
        )

    @cached_property
    def opencv(self) -> cv2.aruco.Board:
        """The board as OpenCV's ``CharucoBoard`` or ``GridBoard``."""
        dictionary = predefined_dictionary(self.dictionary)
        size = (self.columns, self.rows)
        if self.kind == "charuco":
            assert self.square_m is not None
            board = cv2.aruco.CharucoBoard(size, self.square_m, self.marker_m, dictionary)
            board.setLegacyPattern(self.legacy_pattern)
            return board
        assert self.separation_m is not None
        return cv2.aruco.GridBoard(size, self.marker_m, self.separation_m, dictionary)

    @cached_property
    def marker_corners(self) -> dict[int, np.ndarray]:
        """Marker id -> its corners TL, TR, BR, BL in the board frame, (4, 3) m."""
        ids = self.opencv.getIds().ravel()
        points = self.opencv.getObjPoints()
        return {
            int(i): np.asarray(p, np.float64).reshape(4, 3)
            for i, p in zip(ids, points, strict=True)
        }

    def board_from_marker(self, marker: int) -> np.ndarray:
        """The 4 x 4 transform from marker ``marker``'s own frame to the board frame."""
        return tf.make(BOARD_FROM_MARKER_ROTATION, self.marker_corners[marker].mean(axis=0))

    @property
    def chessboard_corners(self) -> np.ndarray:
        """ChArUco only: the chessboard corners in the board frame, (n, 3) m, by corner id."""
        require(self.kind == "charuco", "kind: chessboard corners need a ChArUco board")
        return np.asarray(self.opencv.getChessboardCorners(), np.float64).reshape(-1, 3)


def read_board(path: str | Path) -> Board:
    """Read a board file (YAML with the fields of :class:`Board`).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file, the key and what was expected, e.g.
        ``board.yaml: square_m: expected the chessboard square's side (m), larger than marker_m``.
    """
    return from_mapping(Board, read_yaml(path), where=f"{path}: ")


__all__ = ["BOARD_FROM_MARKER_ROTATION", "BOARD_KINDS", "Board", "read_board"]
