"""ArUco marker detection with recorded, configurable settings (OpenCV ``ArucoDetector``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np

from simgap.config import require

REFINEMENTS = {
    "NONE": cv2.aruco.CORNER_REFINE_NONE,
    "SUBPIX": cv2.aruco.CORNER_REFINE_SUBPIX,
    "CONTOUR": cv2.aruco.CORNER_REFINE_CONTOUR,
    "APRILTAG": cv2.aruco.CORNER_REFINE_APRILTAG,
}
_PARAM_NAMES = {n for n in dir(cv2.aruco.DetectorParameters()) if not n.startswith("_")}


@dataclass(frozen=True)
class DetectorSettings:
    """Settings of OpenCV's ArUco detector.

    Attributes
    ----------
    dictionary : str
        ``cv2.aruco`` predefined dictionary name.
    corner_refinement : {"NONE", "SUBPIX", "CONTOUR", "APRILTAG"}
        Corner refinement method.
    subpix_window_px : int
        Half-size of the SUBPIX refinement window (px).
    subpix_max_iterations : int
        Maximum SUBPIX iterations.
    subpix_min_accuracy_px : float
        SUBPIX stopping accuracy (px).
    extra : dict of str to float
        Any other ``cv2.aruco.DetectorParameters`` attribute, by its OpenCV name.
    """

    dictionary: str = "DICT_ARUCO_MIP_36H12"
    corner_refinement: Literal["NONE", "SUBPIX", "CONTOUR", "APRILTAG"] = "SUBPIX"
    subpix_window_px: int = 5
    subpix_max_iterations: int = 100
    subpix_min_accuracy_px: float = 0.01
    extra: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        require(
            hasattr(cv2.aruco, self.dictionary),
            f"dictionary: unknown cv2.aruco dictionary {self.dictionary!r}",
        )
        require(self.subpix_window_px >= 1, "subpix_window_px: expected an integer >= 1")
        unknown = sorted(set(self.extra) - _PARAM_NAMES)
        require(
            not unknown,
            f"extra.{unknown[0] if unknown else ''}: not a cv2.aruco.DetectorParameters attribute",
        )


class Detector:
    """An ``ArucoDetector`` built from :class:`DetectorSettings`."""

    def __init__(self, settings: DetectorSettings) -> None:
        self.settings = settings
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = REFINEMENTS[settings.corner_refinement]
        params.cornerRefinementWinSize = settings.subpix_window_px
        params.cornerRefinementMaxIterations = settings.subpix_max_iterations
        params.cornerRefinementMinAccuracy = settings.subpix_min_accuracy_px
        for name, value in settings.extra.items():
            setattr(params, name, type(getattr(params, name))(value))
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, settings.dictionary))
        self._detector = cv2.aruco.ArucoDetector(dictionary, params)

    def detect(self, gray: np.ndarray) -> dict[int, np.ndarray]:
        """Detect markers in an 8-bit grey frame.

        Returns
        -------
        dict
            Tag id -> corners (4, 2) in px, ordered TL, TR, BR, BL. A tag id seen twice keeps
            the larger detection.
        """
        return self.detect_with_rejected(gray)[0]

    def detect_with_rejected(
        self, gray: np.ndarray
    ) -> tuple[dict[int, np.ndarray], list[np.ndarray]]:
        """Detected markers (as :meth:`detect`) and the rejected candidate quads (4, 2) in px."""
        corners, ids, rejected = self._detector.detectMarkers(gray)
        rejected_quads = [np.asarray(q, np.float64).reshape(4, 2) for q in rejected]
        found: dict[int, np.ndarray] = {}
        if ids is None:
            return found, rejected_quads
        for c, i in zip(corners, ids.ravel(), strict=True):
            c = c.reshape(4, 2).astype(np.float64)
            if int(i) not in found or cv2.contourArea(c.astype(np.float32)) > cv2.contourArea(
                found[int(i)].astype(np.float32)
            ):
                found[int(i)] = c
        return found, rejected_quads
