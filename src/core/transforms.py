"""Rigid transforms as 4x4 homogeneous matrices, named ``a_from_b`` (pytransform3d style).

``a_from_b @ p_b = p_a``. Lengths in metres, angles in radians.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

#: Rotation whose columns are the OpenCV camera axes (x right, y down, z forward) expressed in the
#: global frame (x right, y forward, z up): ``global_from_cv``.
GLOBAL_FROM_CV = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def check_transform(a_from_b: np.ndarray, name: str = "transform") -> np.ndarray:
    """Validate a 4x4 rigid transform and return it as float64.

    Raises
    ------
    ValueError
        If the shape is not (4, 4), the last row is not (0, 0, 0, 1) or the rotation block is not
        orthonormal with determinant +1 (tolerance 1e-6).
    """
    m = np.asarray(a_from_b, dtype=float)
    if m.shape != (4, 4):
        raise ValueError(f"{name} must have shape (4, 4), got {m.shape}")
    if not np.allclose(m[3], [0, 0, 0, 1]):
        raise ValueError(f"{name} last row must be (0, 0, 0, 1), got {m[3]}")
    r = m[:3, :3]
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
        raise ValueError(f"{name} rotation block is not a proper rotation")
    return m


def make(rotation: np.ndarray | None = None, translation=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Build a 4x4 transform from a 3x3 rotation and a translation (m)."""
    m = np.eye(4)
    if rotation is not None:
        m[:3, :3] = rotation
    m[:3, 3] = translation
    return m


def rot_z(angle: float) -> np.ndarray:
    """Return the 3x3 rotation by ``angle`` (rad) counter-clockwise about +Z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotvec_to_matrix(rotvec) -> np.ndarray:
    """Return the 3x3 rotation for a rotation vector (axis * angle, rad)."""
    return Rotation.from_rotvec(np.asarray(rotvec, dtype=float)).as_matrix()


def matrix_to_rotvec(r: np.ndarray) -> np.ndarray:
    """Return the rotation vector (rad) of a 3x3 rotation matrix."""
    return Rotation.from_matrix(np.asarray(r, dtype=float)).as_rotvec()


def perpendicular_axes(direction) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``e1``, ``e2`` perpendicular to ``direction`` and to each other.

    ``e1 = up x d`` normalised with ``up`` the +Z axis (+Y where ``d`` is within 26 deg of it),
    ``e2 = d x e1``: a right-handed frame (``e1``, ``e2``, ``d``) about a unit ``direction``.
    """
    d = np.asarray(direction, float)
    up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(up, d)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def invert(a_from_b: np.ndarray) -> np.ndarray:
    """Invert a rigid transform exactly (no general matrix inverse)."""
    r, t = a_from_b[:3, :3], a_from_b[:3, 3]
    return make(r.T, -r.T @ t)


def apply(a_from_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Apply a transform to points of shape (..., 3)."""
    pts = np.asarray(points_b, dtype=float)
    return pts @ a_from_b[:3, :3].T + a_from_b[:3, 3]
