"""A board's pose from all its points, and each marker's own pose measured against it.

With no external reference (no tracker, no robot), the board itself is the reference
(docs/conventions.md §6): its pose from all the points it shows is far better determined than
one marker's from four corners. A ChArUco board's reference points are its chessboard corners
(saddle points, refined by OpenCV's ``CharucoDetector``): unlike a marker's corners they do not
move with the ink's edge (blur, exposure, a print's darkness), so a marker's error against them
is the single-marker error a robot using that marker would see. A grid board has only its
markers' corners; its reference shares their edge bias and is reported as such
(:attr:`BoardView.reference`).

Errors are in the OpenCV camera frame (x right, y down, z forward: z is depth): translation of
the marker centre (m, estimated - reference) and ``rotvec(R_est R_ref^T)`` (rad), as
:func:`simgap.pose.estimate.pose_error` defines them for the PASS rig.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import cv2
import numpy as np

from simgap.core import transforms as tf
from simgap.pose.estimate import PnPSettings, estimate_pose

if TYPE_CHECKING:
    from simgap.core.board import Board
    from simgap.core.rig import CameraModel
    from simgap.pose.detect import Detector

#: Fewest reference points a board pose is solved from: six points over a plane fix its pose
#: with two to spare (a ChArUco corner or a marker corner is one point).
MIN_REFERENCE_POINTS = 6


@dataclass(frozen=True)
class BoardView:
    """What one photo shows of a board.

    Attributes
    ----------
    markers : dict of int to ndarray
        Detected marker id -> its corners TL, TR, BR, BL (4, 2) px.
    rvec_cv, tvec_cv : ndarray or None
        The board's pose in the OpenCV camera frame (rotation vector, rad; translation, m);
        None where fewer than :data:`MIN_REFERENCE_POINTS` reference points were found.
    reference : {"chessboard corners", "marker corners"}
        Which points the pose was solved from.
    points : int
        How many.
    reproj_px : float
        RMS reprojection error of those points through the camera's own model (px); NaN
        without a pose.
    """

    markers: dict[int, np.ndarray]
    rvec_cv: np.ndarray | None
    tvec_cv: np.ndarray | None
    reference: Literal["chessboard corners", "marker corners"]
    points: int
    reproj_px: float

    def camera_from_board(self) -> np.ndarray | None:
        """The board pose as a 4 x 4 transform (board frame -> OpenCV camera frame), or None."""
        if self.rvec_cv is None or self.tvec_cv is None:
            return None
        return tf.make(tf.rotvec_to_matrix(self.rvec_cv), self.tvec_cv)


def reference_points(
    gray: np.ndarray, board: Board, markers: dict[int, np.ndarray]
) -> tuple[np.ndarray, np.ndarray, Literal["chessboard corners", "marker corners"]]:
    """Matched board points (n, 3) m and image points (n, 2) px, and which kind they are.

    ChArUco: the chessboard corners OpenCV's ``CharucoDetector`` interpolates and refines from
    the detected ``markers``; a grid board: the markers' own corners.
    """
    if board.kind == "charuco" and markers:
        ids = np.array(list(markers), np.int32).reshape(-1, 1)
        corners = [c.reshape(1, 4, 2).astype(np.float32) for c in markers.values()]
        found, found_ids, _, _ = cv2.aruco.CharucoDetector(board.opencv).detectBoard(
            gray, markerCorners=corners, markerIds=ids
        )
        if found_ids is None:
            return np.zeros((0, 3)), np.zeros((0, 2)), "chessboard corners"
        obj = board.chessboard_corners[found_ids.ravel()]
        return obj, np.asarray(found, np.float64).reshape(-1, 2), "chessboard corners"
    known = [i for i in markers if i in board.marker_corners]
    obj = np.concatenate([board.marker_corners[i] for i in known]) if known else np.zeros((0, 3))
    img = np.concatenate([markers[i] for i in known]) if known else np.zeros((0, 2))
    return obj, img, "marker corners"


def solve_board_pose(
    obj: np.ndarray, img: np.ndarray, camera: CameraModel
) -> tuple[np.ndarray, np.ndarray, float]:
    """Pose of planar points ``obj`` (n, 3) m seen at ``img`` (n, 2) px: rvec, tvec, RMS px.

    Solved on normalised image coordinates (:meth:`simgap.core.rig.CameraModel.normalise`:
    every distortion model, fisheye included) with SQPnP, polished by Levenberg-Marquardt;
    the RMS reprojection is through the camera's own model.
    """
    norm = camera.normalise(img).reshape(-1, 1, 2)
    k, dist = np.eye(3), np.zeros(5)
    _, rvec, tvec = cv2.solvePnP(obj, norm, k, dist, flags=cv2.SOLVEPNP_SQPNP)
    rvec, tvec = cv2.solvePnPRefineLM(obj, norm, k, dist, rvec, tvec)
    rvec, tvec = rvec.ravel(), tvec.ravel()
    return rvec, tvec, reprojection_rms(obj, img, camera, tf.make(tf.rotvec_to_matrix(rvec), tvec))


def reprojection_rms(
    obj: np.ndarray, img: np.ndarray, camera: CameraModel, camera_from_board: np.ndarray
) -> float:
    """RMS reprojection (px) of board points ``obj`` (n, 3) m against ``img`` (n, 2) px.

    Through the camera's own model, with the board at ``camera_from_board`` (4 x 4, m).
    """
    pose = np.asarray(camera_from_board, float)
    proj = camera.project(obj @ pose[:3, :3].T + pose[:3, 3]).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum((proj - img) ** 2, axis=1))))


def view_board(
    gray: np.ndarray, board: Board, camera: CameraModel, detector: Detector
) -> BoardView:
    """Detect the board's markers in an 8-bit grey photo and solve its reference pose."""
    markers = {i: c for i, c in detector.detect(gray).items() if i in board.marker_corners}
    obj, img, kind = reference_points(gray, board, markers)
    if len(obj) < MIN_REFERENCE_POINTS:
        return BoardView(markers, None, None, kind, len(obj), float("nan"))
    rvec, tvec, rms = solve_board_pose(obj, img, camera)
    return BoardView(markers, rvec, tvec, kind, len(obj), rms)


@dataclass(frozen=True)
class MarkerError:
    """One marker's single-marker pose against the board's reference (OpenCV camera frame).

    Attributes
    ----------
    translation_m : ndarray (3,)
        Estimated - reference position of the marker centre (m; x right, y down, z depth).
    rotation_rad : ndarray (3,)
        ``rotvec(R_est R_ref^T)`` (rad).
    board_translation_m : ndarray (3,)
        The estimated centre in the board frame (by the reference pose) - its printed place (m).
    distance_m : float
        Reference distance from the camera centre to the marker centre (m).
    view_angle_deg : float
        Angle between the marker's normal and its line of sight (deg; 0: facing the camera).
    centre_px : ndarray (2,)
        The marker centre's reference projection (px).
    reproj_px : float
        RMS reprojection error of the single-marker solution (px).
    """

    translation_m: np.ndarray
    rotation_rad: np.ndarray
    board_translation_m: np.ndarray
    distance_m: float
    view_angle_deg: float
    centre_px: np.ndarray
    reproj_px: float


def marker_error(
    view: BoardView,
    board: Board,
    marker: int,
    camera: CameraModel,
    pnp: PnPSettings | None = None,
) -> MarkerError | None:
    """Marker ``marker``'s own pose (its four corners, :func:`estimate_pose`) against the board.

    None where the board has no reference pose, the marker was not detected or PnP fails.
    ``pnp``: the single-marker solver (default :class:`~simgap.pose.estimate.PnPSettings`).
    """
    camera_from_board = view.camera_from_board()
    if camera_from_board is None or marker not in view.markers:
        return None
    est = estimate_pose(view.markers[marker], board.marker_m, camera, pnp or PnPSettings())
    if est is None:
        return None
    ref = camera_from_board @ board.board_from_marker(marker)
    r_ref, t_ref = ref[:3, :3], ref[:3, 3]
    r_est = tf.rotvec_to_matrix(est.rvec_cv)
    normal = r_ref[:, 2]  # the marker's z: out of the print, towards the camera
    cos_view = float(np.clip(-normal @ t_ref / np.linalg.norm(t_ref), -1.0, 1.0))
    centre_board = tf.apply(tf.invert(camera_from_board), est.tvec_cv)
    return MarkerError(
        translation_m=est.tvec_cv - t_ref,
        rotation_rad=tf.matrix_to_rotvec(r_est @ r_ref.T),
        board_translation_m=centre_board - board.board_from_marker(marker)[:3, 3],
        distance_m=float(np.linalg.norm(t_ref)),
        view_angle_deg=float(np.degrees(np.arccos(cos_view))),
        centre_px=camera.project(t_ref.reshape(1, 3)).reshape(2),
        reproj_px=est.reproj_px,
    )


__all__ = [
    "MIN_REFERENCE_POINTS",
    "BoardView",
    "MarkerError",
    "marker_error",
    "reference_points",
    "reprojection_rms",
    "solve_board_pose",
    "view_board",
]
