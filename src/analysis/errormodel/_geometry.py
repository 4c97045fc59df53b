"""Covariates of the error model from tag poses, and poses perturbed by errors."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from simgap.core.distance import camera_to_tag_distance
from simgap.core.rig import view_angles


def pose_matrices(poses: np.ndarray) -> np.ndarray:
    """4x4 ``eyepoint_from_tag`` of poses ``(..., 6)`` (translation m, rotation vector rad)."""
    poses = np.asarray(poses, dtype=float)
    flat = poses.reshape(-1, 6)
    out = np.repeat(np.eye(4)[None], len(flat), axis=0)
    out[:, :3, :3] = Rotation.from_rotvec(flat[:, 3:]).as_matrix()
    out[:, :3, 3] = flat[:, :3]
    return out.reshape(poses.shape[:-1] + (4, 4))


def covariates(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) and signed obliquity (rad) of tag poses ``(..., 6)`` in the global frame."""
    m = pose_matrices(poses)
    t, normal = m[..., :3, 3], m[..., :3, 2]
    distance = camera_to_tag_distance(t)
    to_camera = -t / distance[..., None]
    turn = to_camera[..., 0] * normal[..., 1] - to_camera[..., 1] * normal[..., 0]
    side = np.where(turn < 0, -1.0, 1.0)
    return distance, side * (np.pi / 2 - view_angles(m))


def perturb(poses: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """Estimated poses from expected poses and errors (docs/conventions.md §1), both ``(..., 6)``.

    Translation: ``t + e_t``; rotation: ``R_est = R(e_r) R_exp``, the inverse of
    :func:`simgap.pose.estimate.pose_error`.
    """
    poses, errors = np.asarray(poses, float), np.asarray(errors, float)
    shape = np.broadcast_shapes(poses.shape, errors.shape)
    p = np.array(np.broadcast_to(poses, shape)).reshape(-1, 6)
    e = np.array(np.broadcast_to(errors, shape)).reshape(-1, 6)
    rot = Rotation.from_rotvec(e[:, 3:]) * Rotation.from_rotvec(p[:, 3:])
    return np.concatenate([p[:, :3] + e[:, :3], rot.as_rotvec()], axis=1).reshape(shape)
