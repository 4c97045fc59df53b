"""External reference poses for a folder of board photos: a poses file, or a robot and its hand-eye.

By default a photo's reference is the board's pose from its own points
(:mod:`simgap.pose.board_pose`, docs/conventions.md §6). A rig that knows where its camera was
gives the reference instead:

- :class:`PosesReference` (``--poses CSV``): per photo, ``camera_from_board``, the board's pose in
  the OpenCV camera frame (a tracker's, or a simulator's ground truth);
- :class:`RobotReference` (``--robot-poses CSV --hand-eye FILE [--board-in-base FILE]``): per
  photo, ``base_from_flange``, the robot flange's pose in the robot base frame, with the fixed
  ``flange_from_camera`` (hand-eye) and ``base_from_board``; the reference is
  ``camera_from_board = (base_from_flange flange_from_camera)^-1 base_from_board``. Without a
  board-in-base file, ``base_from_board`` is solved from the photos' own board poses
  (:func:`solve_board_in_base`).

Transforms are 4 x 4 ``a_from_b`` matrices (:mod:`simgap.core.transforms`; m). The frames
(docs/conventions.md §6): ``board`` (OpenCV's board frame), ``camera`` (OpenCV's camera frame: x
right, y down, z forward), ``flange`` and ``base`` (the robot's). Files:

- a pose CSV has the header ``image,tx,ty,tz,qx,qy,qz,qw`` (:data:`POSE_COLUMNS`, any order): the
  photo's file name, the translation (m) and the unit quaternion ``x y z w`` (scalar last, as
  ROS and :class:`scipy.spatial.transform.Rotation` write it) of the named transform;
- a transform file (hand-eye, board-in-base) is YAML with ``translation: [x, y, z]`` (m) and
  ``quaternion: [qx, qy, qz, qw]``, or ``matrix:`` its 4 x 4 rows.

Every problem is a :class:`~simgap.core.config.ConfigError` naming the file, the row or key and
what was expected.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from simgap.core import transforms as tf
from simgap.core.atomic import atomic_write
from simgap.core.config import ConfigError, parse_yaml, read_text
from simgap.core.robust import mad_sigma
from simgap.pipeline.capture.calibration import numbers

#: Columns of a pose CSV: the photo's file name, translation (m), quaternion x y z w.
POSE_COLUMNS = ("image", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
#: How far a quaternion's norm may be from 1 before it is refused (it is then normalised): a
#: quaternion written to 4 decimals is within 1e-4 of unit norm, and anything further than 1e-3
#: is not a rotation written out but a mistake (a swapped column, a scaled value).
QUATERNION_NORM_TOLERANCE = 1e-3
#: Frames whose ``base_from_board`` rotation lies further than this many robust sigmas (MAD)
#: above the median deviation from the first mean are left out of the solved rotation: the
#: three-sigma outlier cut (keeps 99.7 % of a Gaussian scatter).
BOARD_IN_BASE_CUT_SIGMAS = 3.0
#: Attribute ``reference`` of a photo dataset measured against a poses file.
POSES_REFERENCE = "poses file"
#: Attribute ``reference`` of a photo dataset measured against robot poses and a hand-eye.
ROBOT_REFERENCE = "robot poses and hand-eye"
#: The external references (a photo set measured against one is simulated against it too).
EXTERNAL_REFERENCES = (POSES_REFERENCE, ROBOT_REFERENCE)
#: Attribute ``reference`` of a simulated photo set measured against its render poses.
RENDERED_REFERENCE = "the pose each frame was rendered at"


def pose_matrix(
    translation: Sequence[float], quaternion: Sequence[float], where: str
) -> np.ndarray:
    """The 4 x 4 transform of a translation (m) and a quaternion ``x y z w``.

    Raises
    ------
    simgap.core.config.ConfigError
        ``where`` and the norm, for a quaternion further than :data:`QUATERNION_NORM_TOLERANCE`
        from unit norm.
    """
    q = np.asarray(quaternion, float)
    norm = float(np.linalg.norm(q))
    if not abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE:
        raise ConfigError(
            f"{where}: expected a unit quaternion qx, qy, qz, qw (norm 1 within "
            f"{QUATERNION_NORM_TOLERANCE:g}), got norm {norm:.6g}"
        )
    return tf.make(Rotation.from_quat(q / norm).as_matrix(), translation)


def _number(text: str, where: str) -> float:
    """A finite number written in a CSV field."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ConfigError(f"{where}: expected a finite number, got {text!r}")
    return value


def read_pose_csv(path: Path, what: str) -> dict[str, np.ndarray]:
    """A pose CSV (:data:`POSE_COLUMNS`): photo file name -> the 4 x 4 transform of its row.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        The transform the rows hold, for messages (e.g. ``"camera_from_board"``).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file, the row (and its line) and the column: a header other than
        :data:`POSE_COLUMNS`, a field that is not a finite number, a non-unit quaternion, a photo
        named twice, no rows.
    """
    path = Path(path)
    reader = csv.reader(io.StringIO(read_text(path, f"{what} pose CSV")))
    try:
        header = [h.strip() for h in next(reader, [])]
        if sorted(header) != sorted(POSE_COLUMNS):
            raise ConfigError(
                f"{path}: header: expected the columns {','.join(POSE_COLUMNS)} ({what}: "
                f"translation in m, quaternion x y z w), got {','.join(header)}"
            )
        poses: dict[str, np.ndarray] = {}
        for cells in reader:
            if not any(c.strip() for c in cells):
                continue
            where = f"{path}: row {len(poses) + 1} (line {reader.line_num})"
            if len(cells) != len(header):
                raise ConfigError(f"{where}: expected {len(header)} fields, got {len(cells)}")
            rec = {k: c.strip() for k, c in zip(header, cells, strict=True)}
            name = rec["image"]
            if not name:
                raise ConfigError(f"{where}: image: expected a photo's file name, got ''")
            if name in poses:
                raise ConfigError(f"{where}: image: {name} has a row already")
            v = {k: _number(rec[k], f"{where}: {k}") for k in POSE_COLUMNS[1:]}
            poses[name] = pose_matrix(
                [v["tx"], v["ty"], v["tz"]],
                [v["qx"], v["qy"], v["qz"], v["qw"]],
                f"{where}: qx,qy,qz,qw",
            )
    except csv.Error as exc:
        raise ConfigError(f"{path}: line {reader.line_num}: not valid CSV ({exc})") from exc
    if not poses:
        raise ConfigError(f"{path}: no rows (expected one {what} pose per photo)")
    return poses


def write_pose_csv(path: Path, poses: Mapping[str, np.ndarray]) -> Path:
    """Write ``poses`` (photo file name -> 4 x 4 transform, m) as a pose CSV, atomically.

    The columns of :data:`POSE_COLUMNS`, at full precision: :func:`read_pose_csv` gives the
    transforms back to round-off.
    """
    lines = [",".join(POSE_COLUMNS)]
    for name, m in poses.items():
        q = Rotation.from_matrix(np.asarray(m, float)[:3, :3]).as_quat()
        lines.append(",".join([name, *(repr(float(v)) for v in (*m[:3, 3], *q))]))
    text = "\n".join(lines) + "\n"
    atomic_write(Path(path), lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return Path(path)


def write_transform_file(path: Path, transform: np.ndarray) -> Path:
    """Write a 4 x 4 transform (m) as a transform file (``translation`` + ``quaternion``).

    Atomically; :func:`read_transform_file` reads it back.
    """
    m = np.asarray(transform, float)
    q = Rotation.from_matrix(m[:3, :3]).as_quat()
    data = {"translation": [float(v) for v in m[:3, 3]], "quaternion": [float(v) for v in q]}
    text = yaml.safe_dump(data)
    atomic_write(Path(path), lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return Path(path)


def read_transform_file(path: Path, what: str) -> np.ndarray:
    """A transform file (YAML): ``translation`` + ``quaternion``, or a 4 x 4 ``matrix``.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        The transform it holds, for messages (e.g. ``"flange_from_camera"``).

    Returns
    -------
    numpy.ndarray
        The 4 x 4 transform (m).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file and key: not a mapping, both or neither form, a list of the wrong length,
        a non-unit quaternion, a matrix that is not a rigid transform (rotation block orthonormal
        within 1e-6, :func:`simgap.core.transforms.check_transform`).
    """
    path = Path(path)
    data = parse_yaml(read_text(path, f"{what} file"), str(path))
    forms = "translation: [x, y, z] (m) with quaternion: [qx, qy, qz, qw], or matrix: 4 rows of 4"
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping ({what}: {forms}), got {data!r}")
    if "matrix" in data and not ("translation" in data or "quaternion" in data):
        rows = data["matrix"]
        if not isinstance(rows, list) or len(rows) != 4:
            raise ConfigError(f"{path}: matrix: expected 4 rows of 4 numbers, got {rows!r}")
        m = np.array([numbers(r, f"{path}: matrix[{i}]", 4) for i, r in enumerate(rows)])
        try:
            return tf.check_transform(m, "matrix")
        except ValueError as exc:
            raise ConfigError(f"{path}: {exc} (expected a rigid transform, {what})") from None
    if "matrix" in data or not ("translation" in data and "quaternion" in data):
        raise ConfigError(
            f"{path}: expected either {forms}; got the keys {', '.join(map(str, data))}"
        )
    t = numbers(data["translation"], f"{path}: translation", 3)
    q = numbers(data["quaternion"], f"{path}: quaternion", 4)
    return pose_matrix(t, q, f"{path}: quaternion")


@dataclass(frozen=True)
class BoardInBase:
    """The board's fixed pose in the robot base frame, solved from the photos.

    Attributes
    ----------
    base_from_board : numpy.ndarray
        4 x 4 (m): translation the per-axis median of the photos' estimates, rotation the chordal
        mean (:meth:`scipy.spatial.transform.Rotation.mean`) of those within
        :data:`BOARD_IN_BASE_CUT_SIGMAS` of the rest.
    frames : int
        Photos it was solved from (a robot pose and a board pose from the board's points).
    rotation_frames : int
        Of those, the ones the rotation mean kept.
    spread_m : float
        Median distance of the photos' estimates from the solved translation (m): how well the
        robot poses, the hand-eye and the board's own poses agree.
    spread_rad : float
        Median angle between the photos' estimated rotations and the solved one (rad).
    """

    base_from_board: np.ndarray
    frames: int
    rotation_frames: int
    spread_m: float
    spread_rad: float


def solve_board_in_base(estimates: Sequence[np.ndarray]) -> BoardInBase:
    """The fixed ``base_from_board`` most photos agree on, from one estimate (4 x 4) per photo.

    Each photo's estimate is ``base_from_flange flange_from_camera camera_from_board`` with its
    board pose from its own points. Raises ValueError for no estimate.
    """
    if not estimates:
        raise ValueError("no photo with both a robot pose and a board pose to solve from")
    stack = np.asarray(estimates, float)
    translation = np.median(stack[:, :3, 3], axis=0)
    rotations = Rotation.from_matrix(stack[:, :3, :3])
    first = rotations.mean()
    deviation = (first.inv() * rotations).magnitude()
    cut = np.median(deviation) + BOARD_IN_BASE_CUT_SIGMAS * mad_sigma(deviation)
    keep = deviation <= cut
    rotation = rotations[keep].mean()
    return BoardInBase(
        base_from_board=tf.make(rotation.as_matrix(), translation),
        frames=len(stack),
        rotation_frames=int(keep.sum()),
        spread_m=float(np.median(np.linalg.norm(stack[:, :3, 3] - translation, axis=1))),
        spread_rad=float(np.median((rotation.inv() * rotations).magnitude())),
    )


@dataclass(frozen=True)
class ResolvedReference:
    """Each photo's reference pose from an external source, and what the dataset says of it.

    Attributes
    ----------
    camera_from_board : list of numpy.ndarray
        Per photo (the names' order), the board's reference pose in the OpenCV camera frame
        (4 x 4, m).
    attrs : dict of str to str or float
        Global attributes of the photo dataset: ``reference`` (:data:`POSES_REFERENCE` or
        :data:`ROBOT_REFERENCE`) and the files and solved values it came from.
    """

    camera_from_board: list[np.ndarray]
    attrs: dict[str, str | float] = field(default_factory=dict)


class PhotoReference(Protocol):
    """An external source of each photo's reference pose.

    :class:`PosesReference` or :class:`RobotReference`.
    """

    @property
    def uses_board_poses(self) -> bool:
        """Whether :meth:`resolve` reads the photos' own board poses.

        Its poses then depend on the camera those were solved through.
        """

    def check(self, names: Sequence[str]) -> None:
        """Raise ConfigError naming the file where a photo of ``names`` has no pose."""

    def resolve(
        self, names: Sequence[str], board_poses: Sequence[np.ndarray | None]
    ) -> ResolvedReference:
        """The photos' reference poses, given each one's board pose from its points (or None)."""


def _check_rows(path: Path, poses: Mapping[str, np.ndarray], names: Sequence[str]) -> None:
    """Every photo of ``names`` has a row of the pose CSV ``path``."""
    missing = [n for n in names if n not in poses]
    if missing:
        shown = ", ".join(missing[:5]) + (
            f" and {len(missing) - 5} more" if len(missing) > 5 else ""
        )
        raise ConfigError(f"{path}: image: expected a row for every photo, none for {shown}")


@dataclass(frozen=True)
class PosesReference:
    """Each photo's ``camera_from_board`` given (the board in the camera frame).

    From ``--poses CSV``, or the poses a simulation rendered its frames at: photos measured
    against an external reference are rendered at it (:func:`simgap.pipeline.photos.
    render_photos`), and each render's markers are then measured against the pose it was
    rendered at, so the real and the simulated errors share one reference.

    Attributes
    ----------
    path : Path or None
        The pose CSV (:func:`read_pose_csv`); None for render poses.
    camera_from_board : dict of str to numpy.ndarray
        Photo file name -> the board's pose in the OpenCV camera frame (4 x 4, m).
    reference : str
        The dataset's ``reference`` attribute: :data:`POSES_REFERENCE`, or
        :data:`RENDERED_REFERENCE` with the real photos' reference.
    """

    path: Path | None
    camera_from_board: dict[str, np.ndarray]
    reference: str = POSES_REFERENCE

    @classmethod
    def read(cls, path: Path) -> PosesReference:
        """Read the pose CSV at ``path`` (ConfigError as :func:`read_pose_csv`)."""
        return cls(Path(path), read_pose_csv(path, "camera_from_board"))

    @property
    def uses_board_poses(self) -> bool:
        """False: the poses are the file's."""
        return False

    def check(self, names: Sequence[str]) -> None:
        """Raise ConfigError naming the file where a photo of ``names`` has no row."""
        _check_rows(self.path or Path("render poses"), self.camera_from_board, names)

    def resolve(
        self, names: Sequence[str], board_poses: Sequence[np.ndarray | None]
    ) -> ResolvedReference:
        """The rows of ``names``, in their order (``board_poses`` unused)."""
        self.check(names)
        attrs: dict[str, str | float] = {"reference": self.reference}
        if self.path is not None:
            attrs["reference_poses"] = str(self.path)
        return ResolvedReference([self.camera_from_board[n] for n in names], attrs)


@dataclass(frozen=True)
class RobotReference:
    """``--robot-poses CSV --hand-eye FILE [--board-in-base FILE]``: the robot's chain.

    Attributes
    ----------
    robot_path : Path
        The pose CSV of ``base_from_flange`` (the flange in the robot base frame) per photo.
    base_from_flange : dict of str to numpy.ndarray
        Its rows (4 x 4, m).
    hand_eye_path : Path
        The transform file of ``flange_from_camera`` (the OpenCV camera frame in the flange
        frame: OpenCV's ``calibrateHandEye`` ``R_cam2gripper``, ``t_cam2gripper``).
    flange_from_camera : numpy.ndarray
        4 x 4 (m).
    board_in_base_path : Path or None
        The transform file of ``base_from_board``; None: solved (:func:`solve_board_in_base`).
    base_from_board : numpy.ndarray or None
        4 x 4 (m), or None to solve it.
    """

    robot_path: Path
    base_from_flange: dict[str, np.ndarray]
    hand_eye_path: Path
    flange_from_camera: np.ndarray
    board_in_base_path: Path | None = None
    base_from_board: np.ndarray | None = None

    @classmethod
    def read(
        cls, robot_poses: Path, hand_eye: Path, board_in_base: Path | None = None
    ) -> RobotReference:
        """Read the robot's pose CSV and transform files (ConfigError naming file and key)."""
        return cls(
            Path(robot_poses),
            read_pose_csv(robot_poses, "base_from_flange"),
            Path(hand_eye),
            read_transform_file(hand_eye, "flange_from_camera"),
            None if board_in_base is None else Path(board_in_base),
            None
            if board_in_base is None
            else read_transform_file(board_in_base, "base_from_board"),
        )

    @property
    def uses_board_poses(self) -> bool:
        """True where ``base_from_board`` is solved from the photos' own board poses."""
        return self.base_from_board is None

    def check(self, names: Sequence[str]) -> None:
        """Raise ConfigError naming the robot pose CSV where a photo of ``names`` has no row."""
        _check_rows(self.robot_path, self.base_from_flange, names)

    def resolve(
        self, names: Sequence[str], board_poses: Sequence[np.ndarray | None]
    ) -> ResolvedReference:
        """``(base_from_flange flange_from_camera)^-1 base_from_board`` per photo.

        ``base_from_board`` is the file's, or solved from the photos with a board pose in
        ``board_poses`` (``camera_from_board`` from the board's own points).

        Raises
        ------
        simgap.core.config.ConfigError
            Where a photo has no robot pose, or ``base_from_board`` is to be solved and no photo
            shows the board well enough to pose it.
        """
        self.check(names)
        base_from_camera = [self.base_from_flange[n] @ self.flange_from_camera for n in names]
        attrs: dict[str, str | float] = {
            "reference": ROBOT_REFERENCE,
            "robot_poses": str(self.robot_path),
            "hand_eye": str(self.hand_eye_path),
        }
        base_from_board = self.base_from_board
        if base_from_board is not None:
            attrs["board_in_base"] = str(self.board_in_base_path)
        else:
            estimates = [
                b @ c for b, c in zip(base_from_camera, board_poses, strict=True) if c is not None
            ]
            try:
                solved = solve_board_in_base(estimates)
            except ValueError as exc:
                raise ConfigError(
                    f"{self.robot_path}: cannot solve the board's pose in the robot base: {exc}; "
                    "give it (--board-in-base FILE)"
                ) from None
            base_from_board = solved.base_from_board
            attrs["board_in_base"] = (
                f"solved from {solved.frames} photos' board poses: translation the per-axis "
                f"median, rotation the mean of {solved.rotation_frames}"
            )
            attrs["board_in_base_spread_m"] = solved.spread_m
            attrs["board_in_base_spread_rad"] = solved.spread_rad
        rotvec = tf.matrix_to_rotvec(base_from_board[:3, :3])
        attrs["board_in_base_translation_m"] = repr([float(v) for v in base_from_board[:3, 3]])
        attrs["board_in_base_rotvec_rad"] = repr([float(v) for v in rotvec])
        return ResolvedReference([tf.invert(b) @ base_from_board for b in base_from_camera], attrs)


__all__ = [
    "BOARD_IN_BASE_CUT_SIGMAS",
    "EXTERNAL_REFERENCES",
    "POSES_REFERENCE",
    "POSE_COLUMNS",
    "QUATERNION_NORM_TOLERANCE",
    "RENDERED_REFERENCE",
    "ROBOT_REFERENCE",
    "BoardInBase",
    "PhotoReference",
    "PosesReference",
    "ResolvedReference",
    "RobotReference",
    "pose_matrix",
    "read_pose_csv",
    "read_transform_file",
    "solve_board_in_base",
    "write_pose_csv",
    "write_transform_file",
]
