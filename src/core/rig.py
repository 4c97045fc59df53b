"""The test fixture as data: camera, the transform tree of the paper's Table 1, grids and tags.

Frames (docs/conventions.md §1), all right-handed, lengths in metres, angles in radians:

``eyepoint``
    The camera's optical centre; orientation of the global frame (+X right, +Y forward, +Z up).
``carriage``
    Bottom of the carriage pin; moves along the rail with the pin hole ``p``.
``rail``
    The carriage frame at ``p = 0``; fixed to the table. Renders are built in this frame.
``turntable``
    Turntable centre, rotated by ``theta`` counter-clockwise about +Z.
``tag{i}``
    Marker frame of tag ``i``: z out of the marker, y up, x right (OpenCV ArUco convention).

Fixture errors (mount offset, turntable zero, carriage pitch, tag mounting) are applied on their own
link by :class:`FixtureErrors`, so the same tree gives the nominal (CAD) and the perturbed (true)
geometry.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from simgap.core import lens
from simgap.core import transforms as tf
from simgap.core.aruco import check_dictionary, marker_cells
from simgap.core.config import OMIT_DEFAULT, deep_merge, from_mapping, read_yaml, require

DEFAULT_RIG_FILE = Path(__file__).with_name("rig.yaml")
#: Largest image side accepted (px).
MAX_IMAGE_SIDE_PX = 65536
#: Plausible focal lengths, as multiples of the image width (field of view ~170 deg .. ~1 deg).
FOCAL_RANGE_WIDTHS = (0.05, 50.0)
#: How far the principal point may lie outside the image, as a fraction of the image size.
PRINCIPAL_POINT_MARGIN = 0.25


@dataclass(frozen=True)
class CameraModel:
    """A calibrated camera in OpenCV's convention: intrinsics and one of OpenCV's distortion models.

    Attributes
    ----------
    width, height : int
        Image size (px), 1 .. :data:`MAX_IMAGE_SIDE_PX`.
    fx, fy, cx, cy : float
        Focal lengths and principal point (px); pixel centres at integer coordinates. Focal
        lengths must lie within :data:`FOCAL_RANGE_WIDTHS` times the width, the principal point
        within the image extended by :data:`PRINCIPAL_POINT_MARGIN` of its size on each side.
    distortion : tuple of float
        The model's coefficients in OpenCV's order (:data:`simgap.core.lens.DISTORTION_MODELS`),
        dimensionless (a sensor tilt in rad), each within
        :func:`simgap.core.lens.coefficient_bound`; ``plumb_bob``: ``(k1, k2, p1, p2, k3)``.
    distortion_model : str
        ``plumb_bob`` (Brown-Conrady, the default), ``rational_polynomial``, ``thin_prism``,
        ``tilted`` or ``equidistant`` (OpenCV's fisheye); :mod:`simgap.core.lens`.
    """

    width: int = 1920
    height: int = 1080
    fx: float = 1386.0
    fy: float = 1386.0
    cx: float = 959.5
    cy: float = 539.5
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    distortion_model: str = field(default="plumb_bob", metadata=OMIT_DEFAULT)

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            size = getattr(self, name)
            require(
                0 < size <= MAX_IMAGE_SIDE_PX,
                f"{name}: expected positive pixel sizes 1..{MAX_IMAGE_SIDE_PX} (px), got {size}",
            )
        values = (self.fx, self.fy, self.cx, self.cy, *self.distortion)
        require(
            all(math.isfinite(v) for v in values),
            f"fx/fy/cx/cy/distortion: expected finite numbers, got {values}",
        )
        require(self.fx > 0 and self.fy > 0, "fx/fy: expected positive focal lengths (px)")
        lo, hi = (r * self.width for r in FOCAL_RANGE_WIDTHS)
        for name in ("fx", "fy"):
            f = getattr(self, name)
            require(
                lo <= f <= hi,
                f"{name}: expected a focal length of {FOCAL_RANGE_WIDTHS[0]:g}.."
                f"{FOCAL_RANGE_WIDTHS[1]:g} x the image width = {lo:g}..{hi:g} px, got {f:g}",
            )
        for name, size in (("cx", self.width), ("cy", self.height)):
            c, m = getattr(self, name), PRINCIPAL_POINT_MARGIN * size
            require(
                -0.5 - m <= c <= size - 0.5 + m,
                f"{name}: expected a principal point within the image (with a margin of "
                f"{PRINCIPAL_POINT_MARGIN:g} x its size): {-0.5 - m:g}..{size - 0.5 + m:g} px, "
                f"got {c:g}",
            )
        names = lens.DISTORTION_MODELS.get(self.distortion_model)
        require(
            names is not None,
            f"distortion_model: expected one of {', '.join(lens.DISTORTION_MODELS)}, got "
            f"{self.distortion_model!r}",
        )
        require(
            len(self.distortion) == len(names),
            f"distortion: expected the {len(names)} coefficients of {self.distortion_model} "
            f"({', '.join(names)}), got {len(self.distortion)}",
        )
        for i, (name, value) in enumerate(zip(names, self.distortion, strict=True)):
            bound = lens.coefficient_bound(name, self.distortion_model)
            require(
                abs(value) <= bound,
                f"distortion[{i}] ({name}): expected |{name}| <= {bound:g}, got {value:g}",
            )

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix K (px)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """Distortion coefficients as OpenCV expects them for the model (4, 5, 8, 12 or 14,)."""
        return np.asarray(self.distortion, dtype=float)

    @property
    def is_fisheye(self) -> bool:
        """Whether the model is OpenCV's fisheye (``cv2.fisheye``) rather than the pinhole one."""
        return lens.is_fisheye(self.distortion_model)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) (px) of OpenCV camera-frame points (..., 3) (m) in front of it."""
        return lens.project(points, self.matrix, self.distortion_model, self.dist_coeffs)

    def normalise(self, uv: np.ndarray) -> np.ndarray:
        """Normalised coordinates (..., 2) of pixels (..., 2): the inverse of :meth:`project`."""
        return lens.normalise(uv, self.matrix, self.distortion_model, self.dist_coeffs)

    def replace(self, **changes) -> CameraModel:
        """Return a copy with some fields changed."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class Links:
    """Static and dynamic links of the transform tree (m)."""

    eyepoint_to_carriage: tuple[float, float, float] = (-0.004249, -0.03860486, -0.0798068)
    carriage_to_turntable: tuple[float, float, float] = (0.036749, 0.321749, 0.02396)
    pin_pitch: float = 0.0254
    tag_height: float = 0.03967814

    def __post_init__(self) -> None:
        require(self.pin_pitch > 0, "pin_pitch: expected a positive length (m)")


@dataclass(frozen=True)
class Grid:
    """Carriage pin holes and turntable stops."""

    p: tuple[int, ...] = tuple(range(15))
    theta_step_deg: float = 10.0
    theta_count: int = 36

    def __post_init__(self) -> None:
        require(len(self.p) > 0 and min(self.p) >= 0, "p: expected non-negative pin holes")
        dup = sorted({p for p in self.p if self.p.count(p) > 1})
        require(not dup, f"p: expected distinct pin holes, {dup[0] if dup else ''} is repeated")
        require(
            self.theta_step_deg > 0,
            f"theta_step_deg: expected a positive step (deg), got {self.theta_step_deg}",
        )
        require(self.theta_count >= 1, "theta_count: expected an integer >= 1")
        turn = self.theta_step_deg * self.theta_count
        require(
            turn <= 360.0 + 1e-9,
            f"theta_count: expected theta_step_deg x theta_count <= 360 deg (one turn; more stops "
            f"would repeat angles), got {self.theta_step_deg:g} x {self.theta_count} = {turn:g}",
        )

    @property
    def theta(self) -> np.ndarray:
        """Turntable angles (rad)."""
        return np.deg2rad(self.theta_step_deg * np.arange(self.theta_count))


@dataclass(frozen=True)
class TagFace:
    """One tag on the node: id, radius from the turntable axis (m), which face it is on."""

    id: int
    radius: float
    facing: Literal["outward", "inward"] = "outward"

    def __post_init__(self) -> None:
        require(self.radius > 0, "radius: expected a positive length (m)")


@dataclass(frozen=True)
class Tags:
    """ArUco tags: dictionary name (``cv2.aruco`` constant), size (m), quiet zone, faces."""

    dictionary: str = "DICT_ARUCO_MIP_36H12"
    size: float = 0.02032
    quiet_zone_cells: int = 2
    faces: tuple[TagFace, ...] = (TagFace(0, 0.0806, "outward"), TagFace(1, 0.0381, "inward"))

    def __post_init__(self) -> None:
        check_dictionary(self.dictionary)
        require(self.size > 0, "size: expected a positive length (m)")
        require(self.quiet_zone_cells >= 0, "quiet_zone_cells: expected an integer >= 0")
        ids = [f.id for f in self.faces]
        require(len(set(ids)) == len(ids), f"faces: tag ids must be unique, got {ids}")

    @property
    def ids(self) -> tuple[int, ...]:
        """Tag ids in face order."""
        return tuple(f.id for f in self.faces)

    def face(self, tag: int) -> TagFace:
        """Return the face of tag ``tag``."""
        for f in self.faces:
            if f.id == tag:
                return f
        raise KeyError(f"tag {tag} is not on the rig (tags: {self.ids})")


@dataclass(frozen=True)
class Visibility:
    """When a tag is expected to be detectable."""

    min_view_angle_deg: float = 15.0

    def __post_init__(self) -> None:
        require(0 <= self.min_view_angle_deg < 90, "min_view_angle_deg: expected 0 <= x < 90 (deg)")


@dataclass(frozen=True)
class FixtureErrors:
    """Differences between the real fixture and its CAD, each on one link of the tree.

    Attributes
    ----------
    mount_translation : tuple of float
        Camera eyepoint offset in the carriage frame (m).
    mount_rotation : tuple of float
        Camera rotation about the eyepoint as a rotation vector in the carriage frame (rad).
    turntable_zero : float
        Turntable zero offset added to every theta (rad).
    pitch_scale : float
        Relative carriage pitch error: the true pitch is ``pin_pitch * (1 + pitch_scale)``.
    tag_offset : tuple of float
        Tag mounting offset in each tag's marker frame (m), the same for every tag.
    """

    mount_translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mount_rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turntable_zero: float = 0.0
    pitch_scale: float = 0.0
    tag_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        require(abs(self.pitch_scale) < 0.5, "pitch_scale: expected |x| < 0.5")


NOMINAL = FixtureErrors()


@dataclass(frozen=True)
class Rig:
    """The whole fixture description, loaded from ``rig.yaml``."""

    camera: CameraModel = field(default_factory=CameraModel)
    links: Links = field(default_factory=Links)
    grid: Grid = field(default_factory=Grid)
    tags: Tags = field(default_factory=Tags)
    visibility: Visibility = field(default_factory=Visibility)

    # --- the transform tree ---------------------------------------------------------------

    def carriage_from_eyepoint(self, err: FixtureErrors = NOMINAL) -> np.ndarray:
        """Pose of the camera eyepoint in the carriage frame."""
        t = -np.asarray(self.links.eyepoint_to_carriage) + np.asarray(err.mount_translation)
        return tf.make(tf.rotvec_to_matrix(err.mount_rotation), t)

    def rail_from_carriage(self, p: float, err: FixtureErrors = NOMINAL) -> np.ndarray:
        """Pose of the carriage at pin hole ``p`` in the rail frame (carriage at p=0)."""
        pitch = self.links.pin_pitch * (1.0 + err.pitch_scale)
        return tf.make(None, (0.0, -pitch * p, 0.0))

    def rail_from_turntable(self, theta: float, err: FixtureErrors = NOMINAL) -> np.ndarray:
        """Pose of the turntable (rotated by ``theta`` rad) in the rail frame."""
        return tf.make(tf.rot_z(theta + err.turntable_zero), self.links.carriage_to_turntable)

    def turntable_from_tag(self, tag: int, err: FixtureErrors = NOMINAL) -> np.ndarray:
        """Pose of tag ``tag``'s marker frame in the turntable frame."""
        face = self.tags.face(tag)
        r = _FACE_ROTATIONS[face.facing]
        centre = np.array([0.0, -face.radius, self.links.tag_height])
        return tf.make(r, centre + r @ np.asarray(err.tag_offset))

    def rail_from_tag(self, tag: int, theta: float, err: FixtureErrors = NOMINAL) -> np.ndarray:
        """Pose of tag ``tag``'s marker frame in the rail frame, turntable at ``theta`` rad.

        Its third column is the tag's normal (the marker's +z, towards a camera that sees it).
        """
        return self.rail_from_turntable(theta, err) @ self.turntable_from_tag(tag, err)

    def rail_from_eyepoint(self, p: float, err: FixtureErrors = NOMINAL) -> np.ndarray:
        """Pose of the eyepoint in the rail frame."""
        return self.rail_from_carriage(p, err) @ self.carriage_from_eyepoint(err)

    def eyepoint_from_tag(
        self, tag: int, p: float, theta: float, err: FixtureErrors = NOMINAL
    ) -> np.ndarray:
        """Tag pose in the eyepoint (global) frame; the expected pose when ``err`` is nominal."""
        return tf.invert(self.rail_from_eyepoint(p, err)) @ self.rail_from_tag(tag, theta, err)

    def eyepoints_from_tags(
        self, tags: np.ndarray, ps: np.ndarray, thetas: np.ndarray, err: FixtureErrors = NOMINAL
    ) -> np.ndarray:
        """:meth:`eyepoint_from_tag` for many configurations at once, shape (N, 4, 4).

        Parameters
        ----------
        tags, ps, thetas : array_like (N,)
            Tag ids, pin holes and turntable angles (rad).
        err : FixtureErrors
            Fixture errors.
        """
        tags = np.asarray(tags, dtype=int)
        ps, thetas = np.asarray(ps, dtype=float), np.asarray(thetas, dtype=float)
        if len(tags) == 0:
            return np.empty((0, 4, 4))
        eye_from_carriage = tf.invert(self.carriage_from_eyepoint(err))
        pitch = self.links.pin_pitch * (1.0 + err.pitch_scale)
        eye_from_rail = np.repeat(eye_from_carriage[None], len(ps), axis=0)
        # rail -> carriage at pin hole p is a translation by +pitch * p along y
        eye_from_rail[:, :3, 3] += np.outer(pitch * ps, eye_from_carriage[:3, 1])
        angle = thetas + err.turntable_zero
        c, s = np.cos(angle), np.sin(angle)
        rail_from_turntable = np.repeat(np.eye(4)[None], len(ps), axis=0)
        rail_from_turntable[:, 0, 0], rail_from_turntable[:, 0, 1] = c, -s
        rail_from_turntable[:, 1, 0], rail_from_turntable[:, 1, 1] = s, c
        rail_from_turntable[:, :3, 3] = self.links.carriage_to_turntable
        ids, inverse = np.unique(tags, return_inverse=True)
        turntable_from_tag = np.stack([self.turntable_from_tag(int(t), err) for t in ids])
        return eye_from_rail @ rail_from_turntable @ turntable_from_tag[inverse]

    def expected_pose(self, tag: int, p: float, theta: float) -> np.ndarray:
        """Expected pose ``(tx, ty, tz, rx, ry, rz)``: translation (m) and rotation vector (rad).

        The rotation vector is that of the marker frame's orientation in the global frame.
        """
        m = self.eyepoint_from_tag(tag, p, theta)
        return np.concatenate([m[:3, 3], tf.matrix_to_rotvec(m[:3, :3])])

    def view_angle(self, tag: int, p: float, theta: float, err: FixtureErrors = NOMINAL) -> float:
        """Angle between the line of sight and the tag plane (rad); negative when facing away."""
        return float(view_angles(self.eyepoint_from_tag(tag, p, theta, err)))

    def is_visible(self, tag: int, p: float, theta: float) -> bool:
        """Whether the tag is expected to be detectable (faces the camera steeply enough)."""
        return self.view_angle(tag, p, theta) > np.deg2rad(self.visibility.min_view_angle_deg)

    def marker_cells(self) -> int:
        """Cells across a marker of the rig's dictionary, including its one-cell black border."""
        return marker_cells(self.tags.dictionary)

    def sticker_size(self) -> float:
        """Side of the white sticker including the quiet zone (m)."""
        cells = self.marker_cells()
        return self.tags.size * (cells + 2 * self.tags.quiet_zone_cells) / cells


def _face_rotation(normal: tuple[float, float, float]) -> np.ndarray:
    """Marker frame of a face (turntable frame): x = z_up x normal, y = up (+z), z = normal."""
    n, y = np.asarray(normal, float), np.array([0.0, 0.0, 1.0])
    r = np.column_stack([np.cross(y, n), y, n])
    r.flags.writeable = False
    return r


#: The marker frame's rotation in the turntable frame per facing (a face's normal points away
#: from the turntable's axis, ``outward``, or towards it).
_FACE_ROTATIONS = {"outward": _face_rotation((0.0, -1.0, 0.0)), "inward": _face_rotation((0, 1, 0))}


def view_angles(eyepoint_from_tags: np.ndarray) -> np.ndarray:
    """Angle between the line of sight and the tag plane (rad) of tag poses, shape (..., 4, 4).

    Positive when the tag faces the camera (pi/2 when it faces it squarely), negative when it
    faces away; the definition behind :meth:`Rig.view_angle` and :meth:`Rig.is_visible`.
    """
    m = np.asarray(eyepoint_from_tags, dtype=float)
    t = m[..., :3, 3]
    to_camera = -t / np.linalg.norm(t, axis=-1, keepdims=True)
    return np.arcsin(np.clip(np.sum(to_camera * m[..., :3, 2], axis=-1), -1.0, 1.0))


def load_rig(
    path: str | Path | None = None, overrides: dict | None = None, where: str | None = None
) -> Rig:
    """Load a rig from YAML (default: the packaged ``rig.yaml``), with optional overrides.

    ``where`` prefixes error messages (default: the rig file's path), e.g. the experiment file
    whose ``rig:`` section holds the overrides.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file and key path of any unknown key, wrong type or out-of-range value.
    """
    path = Path(path) if path else DEFAULT_RIG_FILE
    data = deep_merge(read_yaml(path), overrides or {})
    return from_mapping(Rig, data, where=where if where is not None else f"{path}: ")
