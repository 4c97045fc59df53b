"""The camera-to-tag distance: the one distance that figures, tables and models use.

The global frame is the camera's eyepoint frame, origin at the optical centre
(docs/conventions.md §1), so the distance of a tag from the camera is the length of its pose's
translation. Pin hole, carriage position and turntable angle are grid coordinates, not distances:
a tag on the turntable is up to its mounting radius (0.0806 m for tag 0) nearer or farther than
the turntable centre.
"""

from __future__ import annotations

from typing import Final

import numpy as np

DISTANCE_LABEL: Final[str] = "camera-to-tag distance [m]"
"""Axis label of every distance axis (figures) and distance column (tables)."""


def camera_to_tag_distance(poses: np.ndarray) -> np.ndarray:
    """Distance of each tag centre from the camera's optical centre (m).

    Parameters
    ----------
    poses : array_like (..., 6) or (..., 3)
        Tag poses in the global (eyepoint) frame: translation (m) first, then (optionally) the
        rotation vector (rad), as the result dataset's ``expected``.

    Returns
    -------
    numpy.ndarray (...)
        ``|t|``, the Euclidean length of the translation, in metres.
    """
    poses = np.asarray(poses, dtype=float)
    if poses.shape[-1] not in (3, 6):
        raise ValueError(f"poses must end in 3 or 6 components; got shape {poses.shape}")
    return np.linalg.norm(poses[..., :3], axis=-1)


#: Names of the three distance bands of :func:`distance_thirds`, nearest first.
BAND_NAMES: Final[tuple[str, str, str]] = ("near", "mid", "far")


def distance_thirds(distances: np.ndarray) -> np.ndarray:
    """Band index (0 near, 1 mid, 2 far; -1 where NaN) of each distance, by the data's terciles.

    Thirds of the finite distances given (m): each band holds a third of them, so the bands
    of a photo set follow its own range of distances.
    """
    d = np.asarray(distances, dtype=float)
    out = np.full(d.shape, -1, dtype=int)
    finite = np.isfinite(d)
    if not finite.any():
        return out
    edges = np.quantile(d[finite], [1 / 3, 2 / 3])
    out[finite] = np.searchsorted(edges, d[finite], side="right")
    return out
