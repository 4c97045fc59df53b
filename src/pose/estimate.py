"""Marker pose from corners (``cv2.solvePnP``), in the global frame, and its error.

Conventions (docs/conventions.md §1): pose = translation of the tag centre (m) and rotation vector
of the marker frame (rad), both in the global frame. Error = estimated - expected translation per
axis and ``rotvec(R_est @ R_expected.T)`` per axis. Marker corners and their projection live in
:mod:`simgap.core.aruco` (``marker_object_points``, ``project_tag_corners`` re-exported here).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import cv2
import numpy as np

from simgap.core import transforms as tf
from simgap.core.aruco import marker_object_points, project_tag_corners
from simgap.core.lens import UNDISTORT_CRITERIA

if TYPE_CHECKING:
    from simgap.core.rig import CameraModel

__all__ = [
    "PNP_METHODS",
    "PnPSettings",
    "PoseEstimate",
    "estimate_pose",
    "marker_object_points",
    "pose_error",
    "project_tag_corners",
]

PNP_METHODS = {
    "IPPE_SQUARE": cv2.SOLVEPNP_IPPE_SQUARE,
    "IPPE": cv2.SOLVEPNP_IPPE,
    "ITERATIVE": cv2.SOLVEPNP_ITERATIVE,
    "SQPNP": cv2.SOLVEPNP_SQPNP,
    "EPNP": cv2.SOLVEPNP_EPNP,
}


@dataclass(frozen=True)
class PnPSettings:
    """PnP solver settings.

    Attributes
    ----------
    method : str
        ``cv2.solvePnP`` flag name without the ``SOLVEPNP_`` prefix.
    refine_lm : bool
        Polish the solution with ``cv2.solvePnPRefineLM``.
    fallback_reproj_px : float or None
        If the best solution of ``method`` reprojects worse than this (px) or is not finite, also
        solve with ``ITERATIVE`` and keep the better one. OpenCV's IPPE is degenerate when the
        marker's rotation in the camera frame is exactly pi (a level camera facing a vertical tag,
        as in the nominal rig) and then returns wrong poses with 1-5 px reprojection error on
        perfect corners. None disables the guard (raw solver behaviour).
    """

    method: Literal["IPPE_SQUARE", "IPPE", "ITERATIVE", "SQPNP", "EPNP"] = "IPPE_SQUARE"
    refine_lm: bool = False
    fallback_reproj_px: float | None = 1.0


@dataclass(frozen=True)
class PoseEstimate:
    """One marker pose: global-frame pose (6,), PnP solution in the camera frame, reprojection."""

    pose: np.ndarray
    rvec_cv: np.ndarray
    tvec_cv: np.ndarray
    reproj_px: float


def estimate_pose(
    corners: np.ndarray,
    size: float,
    camera: CameraModel,
    settings: PnPSettings = PnPSettings(),
) -> PoseEstimate | None:
    """Solve the marker pose from its four corners (px) seen by ``camera``; None if PnP fails.

    OpenCV's PnP solvers take the pinhole family of distortion models; for a fisheye
    (``equidistant``) camera the corners are undistorted to normalised coordinates first
    (:meth:`simgap.core.rig.CameraModel.normalise`) and solved there. The reprojection error is
    in pixels through the camera's own model either way.
    """
    obj = marker_object_points(size)
    img = np.asarray(corners, dtype=np.float64).reshape(4, 1, 2)
    best = _solve(obj, img, camera, settings.method, settings.refine_lm)
    limit = settings.fallback_reproj_px
    if limit is not None and settings.method != "ITERATIVE" and (best is None or best[2] > limit):
        other = _solve(obj, img, camera, "ITERATIVE", settings.refine_lm)
        if other is not None and (best is None or other[2] < best[2]):
            best = other
    if best is None:
        return None
    rvec, tvec, reproj = best
    r_global = tf.GLOBAL_FROM_CV @ tf.rotvec_to_matrix(rvec.ravel())
    t_global = tf.GLOBAL_FROM_CV @ tvec.ravel()
    pose = np.concatenate([t_global, tf.matrix_to_rotvec(r_global)])
    return PoseEstimate(pose, rvec.ravel(), tvec.ravel(), reproj)


#: IPPE's rotation-to-vector step is degenerate for a rotation of exactly pi, which is what a level
#: camera facing a vertical tag gives (the nominal rig). IPPE methods therefore solve in a virtual
#: camera turned by this known rotation (0.5 rad about (1, 2, 3)/sqrt(14)), and the result is turned
#: back; the geometry is unchanged, only the degenerate parametrisation is avoided.
VIRTUAL_FROM_CAMERA = tf.rotvec_to_matrix(0.5 * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0))


def _solutions(obj, img, camera_matrix, dist_coeffs, method: str):
    """All (rvec, tvec) of one PnP method in the real camera frame."""
    flags = PNP_METHODS[method]
    if method not in ("IPPE", "IPPE_SQUARE"):
        n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, camera_matrix, dist_coeffs, flags=flags)
        return list(zip(rvecs[:n], tvecs[:n], strict=True))
    dist = np.zeros(5) if dist_coeffs is None else dist_coeffs
    norm = cv2.undistortPoints(img, camera_matrix, dist, criteria=UNDISTORT_CRITERIA)
    rays = np.concatenate([norm.reshape(-1, 2), np.ones((len(obj), 1))], axis=1)
    rays = rays @ VIRTUAL_FROM_CAMERA.T
    virtual = (rays[:, :2] / rays[:, 2:]).reshape(-1, 1, 2)
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, virtual, np.eye(3), None, flags=flags)
    back = VIRTUAL_FROM_CAMERA.T
    return [
        (
            cv2.Rodrigues(back @ tf.rotvec_to_matrix(r.ravel()))[0],
            (back @ t.reshape(3)).reshape(3, 1),
        )
        for r, t in zip(rvecs[:n], tvecs[:n], strict=True)
    ]


def _solve(obj, img, camera: CameraModel, method: str, refine_lm: bool):
    """All solutions of one PnP method; the finite one that reprojects best (rvec, tvec, px)."""
    if camera.is_fisheye:  # solved on normalised coordinates (estimate_pose)
        points, matrix, dist = camera.normalise(img), np.eye(3), np.zeros(5)
    else:
        points, matrix, dist = img, camera.matrix, camera.dist_coeffs
    try:
        solutions = _solutions(obj, points, matrix, dist, method)
    except cv2.error:
        return None
    best = None
    for rvec, tvec in solutions:
        rvec, tvec = np.asarray(rvec, float).reshape(3, 1), np.asarray(tvec, float).reshape(3, 1)
        if refine_lm:
            rvec, tvec = cv2.solvePnPRefineLM(obj, points, matrix, dist, rvec, tvec)
        if not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
            continue
        proj = camera.project(obj @ tf.rotvec_to_matrix(rvec.ravel()).T + tvec.reshape(1, 3))
        rms = float(np.sqrt(np.mean(np.sum((proj.reshape(4, 2) - img.reshape(4, 2)) ** 2, axis=1))))
        if best is None or rms < best[2]:
            best = (rvec, tvec, rms)
    return best


def pose_error(estimated: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Signed error (6,): translation difference (m) and ``rotvec(R_est R_exp^T)`` (rad)."""
    dt = estimated[:3] - expected[:3]
    dr = tf.matrix_to_rotvec(
        tf.rotvec_to_matrix(estimated[3:]) @ tf.rotvec_to_matrix(expected[3:]).T
    )
    return np.concatenate([dt, dr])
