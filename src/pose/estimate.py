"""Marker pose from corners (``cv2.solvePnP``), in the global frame, and its error.

Conventions (DESIGN §1): pose = translation of the tag centre (m) and rotation vector of the marker
frame (rad), both in the global frame. Error = estimated - expected translation per axis and
``rotvec(R_est @ R_expected.T)`` per axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from simgap import transforms as tf

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
    """

    method: Literal["IPPE_SQUARE", "IPPE", "ITERATIVE", "SQPNP", "EPNP"] = "IPPE_SQUARE"
    refine_lm: bool = False


def marker_object_points(size: float) -> np.ndarray:
    """Marker corners TL, TR, BR, BL in the marker frame (m), shape (4, 3)."""
    h = size / 2
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


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
    camera_matrix: np.ndarray,
    dist_coeffs: np.ndarray,
    settings: PnPSettings = PnPSettings(),
) -> PoseEstimate | None:
    """Solve the marker pose from its four corners (px); None if PnP fails."""
    obj = marker_object_points(size)
    img = np.asarray(corners, dtype=np.float64).reshape(4, 1, 2)
    ok, rvec, tvec = cv2.solvePnP(
        obj, img, camera_matrix, dist_coeffs, flags=PNP_METHODS[settings.method]
    )
    if not ok:
        return None
    if settings.refine_lm:
        rvec, tvec = cv2.solvePnPRefineLM(obj, img, camera_matrix, dist_coeffs, rvec, tvec)
    proj, _ = cv2.projectPoints(obj, rvec, tvec, camera_matrix, dist_coeffs)
    reproj = float(np.sqrt(np.mean(np.sum((proj.reshape(4, 2) - img.reshape(4, 2)) ** 2, axis=1))))
    r_global = tf.GLOBAL_FROM_CV @ tf.rotvec_to_matrix(rvec.ravel())
    t_global = tf.GLOBAL_FROM_CV @ tvec.ravel()
    pose = np.concatenate([t_global, tf.matrix_to_rotvec(r_global)])
    return PoseEstimate(pose, rvec.ravel(), tvec.ravel(), reproj)


def pose_error(estimated: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Signed error (6,): translation difference (m) and ``rotvec(R_est R_exp^T)`` (rad)."""
    dt = estimated[:3] - expected[:3]
    dr = tf.matrix_to_rotvec(
        tf.rotvec_to_matrix(estimated[3:]) @ tf.rotvec_to_matrix(expected[3:]).T
    )
    return np.concatenate([dt, dr])


def project_tag_corners(
    eyepoint_from_tag: np.ndarray, size: float, camera_matrix: np.ndarray, dist_coeffs: np.ndarray
) -> np.ndarray:
    """Project a tag's corners TL, TR, BR, BL into the image (px), shape (4, 2)."""
    cv_from_tag = tf.make(tf.GLOBAL_FROM_CV.T) @ eyepoint_from_tag
    pts = tf.apply(cv_from_tag, marker_object_points(size))
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), camera_matrix, dist_coeffs)
    return uv.reshape(4, 2)
