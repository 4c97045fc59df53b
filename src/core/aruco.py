"""ArUco facts every layer shares: predefined dictionaries, marker geometry, corner projection.

Conventions (docs/conventions.md §1): a marker's corners are TL, TR, BR, BL at ``(-L/2, L/2, 0)``,
``(L/2, L/2, 0)``, ``(L/2, -L/2, 0)``, ``(-L/2, -L/2, 0)`` in the marker frame (x right, y up,
z out of the marker), ``L`` the side of the black square (m). The OpenCV camera frame is x right,
y down, z forward; :data:`simgap.core.transforms.GLOBAL_FROM_CV` turns it into the eyepoint frame.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from simgap.core import transforms as tf
from simgap.core.config import require

if TYPE_CHECKING:
    from simgap.core.rig import CameraModel

#: OpenCV's predefined ArUco / AprilTag dictionaries: the ``cv2.aruco.DICT_*`` constants that
#: ``getPredefinedDictionary`` accepts (other ``cv2.aruco`` names, e.g. ``ArucoDetector`` or
#: ``CORNER_REFINE_NONE``, are not dictionaries).
DICTIONARIES: frozenset[str] = frozenset(
    n for n in dir(cv2.aruco) if n.startswith("DICT_") and type(getattr(cv2.aruco, n)) is int
)
#: Black border of an ArUco marker, in cells on each side (``generateImageMarker(borderBits=1)``).
BORDER_CELLS = 1


def check_dictionary(name: str) -> None:
    """Refuse a name that is not an OpenCV predefined dictionary (:data:`DICTIONARIES`).

    Raises
    ------
    ValueError
        ``"dictionary: ..."`` listing the valid names.
    """
    require(
        name in DICTIONARIES,
        f"dictionary: expected a cv2.aruco predefined dictionary name, got {name!r} (one of "
        f"{', '.join(sorted(DICTIONARIES))})",
    )


def predefined_dictionary(name: str) -> cv2.aruco.Dictionary:
    """The OpenCV dictionary called ``name`` (a ``cv2.aruco.DICT_*`` name)."""
    check_dictionary(name)
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def marker_cells(dictionary: str) -> int:
    """Cells across a marker of ``dictionary``, including its black border (both sides)."""
    return int(predefined_dictionary(dictionary).markerSize) + 2 * BORDER_CELLS


def marker_object_points(size: float) -> np.ndarray:
    """Corners TL, TR, BR, BL of a square of side ``size`` (m) in its marker frame, shape (4, 3)."""
    h = size / 2
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def project_tag_corners(
    eyepoint_from_tag: np.ndarray, size: float, camera: CameraModel
) -> np.ndarray:
    """Project a square's corners TL, TR, BR, BL into the image (the camera's OpenCV model).

    The one corner projection of the package: expected corners, sticker boxes for render crops
    and projection-stage fits all use it.

    Parameters
    ----------
    eyepoint_from_tag : ndarray, shape (4, 4) or (..., 4, 4)
        The marker frame in the eyepoint (global-orientation) frame (m); batched poses allowed.
    size : float
        Side of the square (m): the marker, or a sticker with its quiet zone.
    camera : CameraModel
        Intrinsics (px) and distortion (:meth:`simgap.core.rig.CameraModel.project`).

    Returns
    -------
    ndarray, shape (4, 2) or (..., 4, 2)
        Pixel coordinates (px), OpenCV convention (pixel centres at integers).
    """
    m = np.asarray(eyepoint_from_tag, dtype=float)
    cv_from_tag = tf.make(tf.GLOBAL_FROM_CV.T) @ m
    obj = marker_object_points(size)
    pts = obj @ np.swapaxes(cv_from_tag[..., :3, :3], -1, -2) + cv_from_tag[..., None, :3, 3]
    return camera.project(pts).reshape(m.shape[:-2] + (4, 2))
