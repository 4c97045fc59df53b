"""ROS bags in and out, without a ROS installation (the ``rosbags`` and ``rosbags-image`` packages).

In: a ROS 1 ``.bag`` file or a ROS 2 bag folder (``metadata.yaml`` + storage files) is converted
into a capture folder (DESIGN §3), the common interchange, which
:func:`simgap.pipeline.capture.ingest` then turns into a result dataset: there is one ingest path.

- frames: one image topic, ``sensor_msgs/Image`` (any 8-bit encoding rosbags-image converts to
  ``bgr8``; written as lossless PNG) or ``sensor_msgs/CompressedImage`` (its original bytes are
  kept, JPEG or PNG);
- calibration: one ``sensor_msgs/CameraInfo`` topic (every message must agree);
- the fixture configuration (p, theta) of each frame, from either
  a time-range CSV (:data:`RANGE_COLUMNS`: ``start_ns,end_ns,p,theta_rad``; a frame belongs to the
  range holding its time stamp, frames outside every range are skipped and counted), or
  a ``sensor_msgs/JointState`` topic (:data:`FIXTURE_TOPIC` by default) with the joints
  :data:`CARRIAGE_JOINT` (carriage travel from pin hole 0, m) and :data:`TURNTABLE_JOINT` (rad);
  a frame takes the latest joint state at or before its time stamp.

A frame's time stamp is its ``header.stamp`` (the bag's record time where the stamp is zero), in
nanoseconds. The frames of one (p, theta) are numbered as repeats 0, 1, ... in time order.

Out: :func:`write_bag` writes frames as ``sensor_msgs/Image`` (``bgr8``) or
``sensor_msgs/CompressedImage`` with a ``sensor_msgs/CameraInfo`` per frame, the fixture
configuration as ``sensor_msgs/JointState``, and poses as ``geometry_msgs/PoseStamped`` in the
camera's optical frame (x right, y down, z forward; what aruco_ros publishes):
``/simgap/tag<ID>/expected`` (ground truth of the rig's CAD) and, when known,
``/simgap/tag<ID>/estimated``. :func:`capture_to_bag` exports a capture folder,
:func:`experiment_to_bag` the cached renders of an experiment or a simulated result dataset.

Every problem with a bag or a CSV raises :class:`~simgap.core.config.ConfigError` naming the file,
the topic or row, and what was expected.
"""

from __future__ import annotations

import csv
import io
import math
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import xarray as xr
import yaml

from simgap.core import transforms as tf
from simgap.core.atomic import atomic_write, staged_path
from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel, Rig, load_rig
from simgap.pipeline.capture import read_calibration
from simgap.pipeline.capture.folder import CALIBRATION_FILE, IMAGES_DIR, MANIFEST_FILE, read_capture
from simgap.pipeline.capture.ingest import DEFAULT_DETECTOR, DEFAULT_PNP, ingest
from simgap.pipeline.capture.manifest import turntable_stop
from simgap.pipeline.capture.writer import image_name
from simgap.pose.detect import DetectorSettings
from simgap.pose.estimate import PnPSettings

BagFormat = Literal["ros1", "ros2"]
BAG_FORMATS: tuple[str, ...] = ("ros1", "ros2")
IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO_TYPE = "sensor_msgs/msg/CameraInfo"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
#: Default topics of an exported bag (RealSense driver naming).
IMAGE_TOPIC = "/camera/color/image_raw"
COMPRESSED_TOPIC = "/camera/color/image_raw/compressed"
CAMERA_INFO_TOPIC = "/camera/color/camera_info"
FIXTURE_TOPIC = "/simgap/fixture"
CARRIAGE_JOINT = "carriage"
TURNTABLE_JOINT = "turntable"
OPTICAL_FRAME = "camera_color_optical_frame"
RANGE_COLUMNS = ("start_ns", "end_ns", "p", "theta_rad")
#: How far a carriage joint position may be from a pin hole, in pin pitches.
PIN_TOLERANCE = 0.02
#: Time stamp of the first exported frame and the period between frames (ns).
START_NS = 1_700_000_000 * 10**9
PERIOD_NS = 100_000_000


# --- reading ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class TimeRange:
    """A time range of a bag during which the fixture stood still (ns, inclusive; rad)."""

    start_ns: int
    end_ns: int
    p: int
    theta: float
    row: int


@dataclass
class BagConversion:
    """What :func:`bag_to_capture` did: the topics used and frame counts."""

    bag: Path
    format: BagFormat
    image_topic: str
    camera_info_topic: str
    fixture_source: str
    frames: int = 0
    frames_skipped: int = 0
    ranges_without_frames: list[int] = field(default_factory=list)


def bag_format(path: Path) -> BagFormat:
    """``"ros1"`` for a ``.bag`` file, ``"ros2"`` for a folder with ``metadata.yaml``.

    Raises
    ------
    simgap.core.config.ConfigError
        If ``path`` is neither.
    """
    path = Path(path)
    if path.is_file() and path.suffix == ".bag":
        return "ros1"
    if path.is_dir() and (path / "metadata.yaml").is_file():
        return "ros2"
    raise ConfigError(
        f"{path}: not a ROS bag: expected a ROS 1 .bag file or a ROS 2 bag folder "
        "(with metadata.yaml)"
    )


def is_bag(path: Path) -> bool:
    """Whether ``path`` looks like a ROS 1 or ROS 2 bag (see :func:`bag_format`)."""
    try:
        bag_format(path)
    except ConfigError:
        return False
    return True


def _int_field(text: str, where: str, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise ConfigError(f"{where}: {what}: expected an integer, got {text!r}") from None
    return value


def read_time_ranges(path: Path, rig: Rig) -> list[TimeRange]:
    """Read and validate a time-range CSV (header ``start_ns,end_ns,p,theta_rad``).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file, row and column: missing or unknown column, a non-integer time,
        ``end_ns < start_ns``, a ``p`` that is not a pin hole, a ``theta_rad`` that is not a
        turntable stop, overlapping ranges, or no rows.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the time-range CSV: {exc}") from exc
    reader = csv.reader(io.StringIO(text))
    header = [h.strip() for h in next(reader, [])]
    if sorted(header) != sorted(RANGE_COLUMNS):
        raise ConfigError(
            f"{path}: header: expected the columns {','.join(RANGE_COLUMNS)}, got {header}"
        )
    ranges: list[TimeRange] = []
    for cells in reader:
        if not any(c.strip() for c in cells):
            continue
        row = len(ranges) + 1
        where = f"{path}: row {row} (line {reader.line_num})"
        if len(cells) != len(header):
            raise ConfigError(f"{where}: expected {len(header)} fields, got {len(cells)}")
        rec = {k: c.strip() for k, c in zip(header, cells, strict=True)}
        start = _int_field(rec["start_ns"], where, "start_ns")
        end = _int_field(rec["end_ns"], where, "end_ns")
        if end < start:
            raise ConfigError(f"{where}: end_ns: expected >= start_ns ({start}), got {end}")
        p = _int_field(rec["p"], where, "p")
        if p not in rig.grid.p:
            raise ConfigError(f"{where}: p: expected a pin hole of the rig, got {p}")
        theta = turntable_stop(rec["theta_rad"], rig, f"{where}: theta_rad")
        ranges.append(TimeRange(start, end, p, theta, row))
    if not ranges:
        raise ConfigError(f"{path}: no rows (expected one time range per fixture configuration)")
    ordered = sorted(ranges, key=lambda r: r.start_ns)
    for a, b in zip(ordered, ordered[1:], strict=False):
        if b.start_ns <= a.end_ns:
            raise ConfigError(f"{path}: row {b.row}: overlaps row {a.row}")
    return ranges


def _stamp_ns(msg: Any, record_ns: int) -> int:
    stamp = msg.header.stamp
    ns = int(stamp.sec) * 10**9 + int(stamp.nanosec)
    return ns if ns > 0 else int(record_ns)


def _pick_topic(reader: Any, bag: Path, wanted: str | None, types: Sequence[str], what: str):
    """The connection of the topic ``wanted`` (or the only topic of ``types``)."""
    conns = [c for c in reader.connections if c.msgtype in types]
    listing = ", ".join(f"{c.topic} ({c.msgtype})" for c in reader.connections) or "none"
    if wanted is not None:
        named = [c for c in reader.connections if c.topic == wanted]
        if not named:
            raise ConfigError(f"{bag}: topic {wanted}: not in the bag (topics: {listing})")
        if named[0].msgtype not in types:
            raise ConfigError(
                f"{bag}: topic {wanted}: expected {' or '.join(types)} for the {what}, "
                f"got {named[0].msgtype}"
            )
        return named
    topics = sorted({c.topic for c in conns})
    if not topics:
        raise ConfigError(
            f"{bag}: no {' or '.join(types)} topic for the {what} (topics: {listing})"
        )
    if len(topics) > 1:
        raise ConfigError(
            f"{bag}: several topics could hold the {what} ({', '.join(topics)}); name one"
        )
    return [c for c in conns if c.topic == topics[0]]


def _camera_info_yaml(msg: Any) -> str:
    """The ROS camera_info YAML of a ``sensor_msgs/CameraInfo`` message (ROS 1 or ROS 2)."""
    k = getattr(msg, "k", None)
    k = msg.K if k is None else k
    d = getattr(msg, "d", None)
    d = msg.D if d is None else d
    d = [float(v) for v in d]
    model = msg.distortion_model or "plumb_bob"
    if model != "plumb_bob" and not any(d):
        model = "plumb_bob"  # no distortion at all: any model name means the same
    data = {
        "image_width": int(msg.width),
        "image_height": int(msg.height),
        "camera_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in k]},
        "distortion_model": model,
        "distortion_coefficients": {"rows": 1, "cols": len(d), "data": d},
    }
    return yaml.safe_dump(data, sort_keys=False)


def _read_calibration(reader: Any, conns: list, bag: Path, folder: Path) -> CameraModel:
    """The bag's calibration, written as ``camera.yaml`` and validated like a capture's."""
    texts = []
    for conn, _, raw in reader.messages(connections=conns):
        texts.append(_camera_info_yaml(reader.deserialize(raw, conn.msgtype)))
        if texts[-1] != texts[0]:
            raise ConfigError(
                f"{bag}: topic {conns[0].topic}: message {len(texts)}: the calibration differs "
                "from message 1 (expected one calibration for the whole bag)"
            )
    if not texts:
        raise ConfigError(f"{bag}: topic {conns[0].topic}: no messages (expected a CameraInfo)")
    folder.mkdir(parents=True, exist_ok=True)
    path = atomic_write(folder / CALIBRATION_FILE, texts[0])
    try:
        return read_calibration(path)
    except ConfigError as exc:
        where = f"{bag}: topic {conns[0].topic}: message 1"
        raise ConfigError(str(exc).replace(str(path), where)) from None


def _fixture_from_joints(reader: Any, conns: list, bag: Path, rig: Rig) -> list[tuple]:
    """``(stamp_ns, p, theta)`` of every joint-state message, in time order."""
    topic = conns[0].topic
    out = []
    for i, (conn, t, raw) in enumerate(reader.messages(connections=conns), start=1):
        msg = reader.deserialize(raw, conn.msgtype)
        where = f"{bag}: topic {topic}: message {i}"
        names = list(msg.name)
        for joint in (CARRIAGE_JOINT, TURNTABLE_JOINT):
            if joint not in names:
                raise ConfigError(f"{where}: name: expected a joint {joint!r}, got {names}")
        if len(msg.position) != len(names):
            raise ConfigError(
                f"{where}: position: expected {len(names)} values, got {len(msg.position)}"
            )
        travel = float(msg.position[names.index(CARRIAGE_JOINT)])
        pins = travel / rig.links.pin_pitch
        p = round(pins) if math.isfinite(pins) else -1
        if abs(pins - p) > PIN_TOLERANCE or p not in rig.grid.p:
            raise ConfigError(
                f"{where}: {CARRIAGE_JOINT}: expected the travel of a pin hole (a multiple of "
                f"{rig.links.pin_pitch} m within {PIN_TOLERANCE} pitch), got {travel} m"
            )
        theta = turntable_stop(
            msg.position[names.index(TURNTABLE_JOINT)], rig, f"{where}: turntable"
        )
        out.append((_stamp_ns(msg, t), p, theta))
    if not out:
        raise ConfigError(f"{bag}: topic {topic}: no messages (expected JointState)")
    return sorted(out, key=lambda x: x[0])


def _image_bytes(msg: Any, msgtype: str, where: str) -> tuple[bytes, str]:
    """The frame as file bytes and extension: a CompressedImage's own bytes, else a PNG."""
    import cv2

    if msgtype == COMPRESSED_TYPE:
        data = bytes(msg.data)
        if data.startswith(b"\x89PNG"):
            return data, "png"
        if data.startswith(b"\xff\xd8"):
            return data, "jpg"
        return data, "img"  # undecodable: ingest records it as a detection failure
    from rosbags.image import ImageError, message_to_cvimage

    try:
        bgr = message_to_cvimage(msg, "bgr8")
    except (ImageError, ValueError, KeyError) as exc:
        raise ConfigError(
            f"{where}: encoding: expected an 8-bit encoding (mono8, bgr8, rgb8, ...), "
            f"got {msg.encoding!r}: {exc}"
        ) from None
    ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise ConfigError(f"{where}: the image cannot be encoded as PNG")
    return buf.tobytes(), "png"


def bag_to_capture(
    bag: Path,
    folder: Path,
    rig: Rig,
    ranges_csv: Path | None = None,
    image_topic: str | None = None,
    camera_info_topic: str | None = None,
    fixture_topic: str | None = None,
) -> BagConversion:
    """Convert a bag into a capture folder (``camera.yaml``, ``images/``, ``manifest.csv``).

    Parameters
    ----------
    bag : Path
        ROS 1 ``.bag`` file or ROS 2 bag folder.
    folder : Path
        The capture folder to write (created).
    rig : Rig
        Its pin holes, pitch (m) and turntable stops validate the configurations.
    ranges_csv : Path, optional
        Time-range CSV giving (p, theta) of each frame; default: the fixture topic.
    image_topic, camera_info_topic : str, optional
        Topics of the frames and of the calibration; default: the only one of its type.
    fixture_topic : str, optional
        ``sensor_msgs/JointState`` topic of the fixture; default :data:`FIXTURE_TOPIC`.

    Returns
    -------
    BagConversion
        Topics used, frames written and skipped (outside every time range, or before the
        first joint state), and time-range rows without a frame.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the bag and topic, or the CSV and row, and what was expected.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag, folder = Path(bag), Path(folder)
    fmt = bag_format(bag)
    ranges = read_time_ranges(ranges_csv, rig) if ranges_csv is not None else None
    (folder / IMAGES_DIR).mkdir(parents=True, exist_ok=True)
    try:
        reader_cm = AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader = reader_cm.__enter__()
    except Exception as exc:  # rosbags raises its own error types for damaged bags
        raise ConfigError(f"{bag}: cannot open the bag: {exc}") from None
    try:
        images = _pick_topic(reader, bag, image_topic, (IMAGE_TYPE, COMPRESSED_TYPE), "frames")
        infos = _pick_topic(reader, bag, camera_info_topic, (CAMERA_INFO_TYPE,), "calibration")
        _read_calibration(reader, infos, bag, folder)
        joints: list[tuple] = []
        if ranges is None:
            topic = fixture_topic or FIXTURE_TOPIC
            if not any(c.topic == topic for c in reader.connections):
                raise ConfigError(
                    f"{bag}: topic {topic}: not in the bag; give the (p, theta) of the frames "
                    f"as a time-range CSV ({','.join(RANGE_COLUMNS)}) or a JointState topic"
                )
            conns = _pick_topic(reader, bag, topic, (JOINT_STATE_TYPE,), "fixture configuration")
            joints = _fixture_from_joints(reader, conns, bag, rig)
            source = f"topic {topic}"
        else:
            source = str(ranges_csv)
        info = BagConversion(bag, fmt, images[0].topic, infos[0].topic, source)
        rows = _write_frames(reader, images, bag, folder, ranges, joints, info)
    finally:
        reader_cm.__exit__(None, None, None)
    if not rows:
        raise ConfigError(
            f"{bag}: topic {info.image_topic}: none of its {info.frames_skipped} frames falls in "
            f"a fixture configuration of {source}"
        )
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["image", "p", "theta_rad", "repeat"])
    writer.writerows(rows)
    atomic_write(folder / MANIFEST_FILE, text.getvalue())
    return info


def _write_frames(
    reader: Any,
    conns: list,
    bag: Path,
    folder: Path,
    ranges: list[TimeRange] | None,
    joints: list[tuple],
    info: BagConversion,
) -> list[list]:
    """Write each frame that has a configuration; return the manifest rows."""
    stamps = [j[0] for j in joints]
    counts: dict[tuple[int, float], int] = {}
    used: set[int] = set()
    rows = []
    for i, (conn, t, raw) in enumerate(reader.messages(connections=conns), start=1):
        msg = reader.deserialize(raw, conn.msgtype)
        ns = _stamp_ns(msg, t)
        if ranges is not None:
            hit = next((r for r in ranges if r.start_ns <= ns <= r.end_ns), None)
            config = None if hit is None else (hit.p, hit.theta)
            if hit is not None:
                used.add(hit.row)
        else:
            k = int(np.searchsorted(stamps, ns, side="right")) - 1
            config = None if k < 0 else joints[k][1:]
        if config is None:
            info.frames_skipped += 1
            continue
        data, ext = _image_bytes(msg, conn.msgtype, f"{bag}: topic {conn.topic}: message {i}")
        repeat = counts.get(config, 0)
        counts[config] = repeat + 1
        name = f"{IMAGES_DIR}/{image_name(config[0], config[1], repeat, ext)}"
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        atomic_write(folder / name, data)
        rows.append([name, config[0], f"{config[1]:.9f}", repeat])
        info.frames += 1
    info.ranges_without_frames = sorted({r.row for r in ranges or []} - used)
    return rows


def ingest_bag(
    bag: Path,
    rig: Rig | None = None,
    detector: DetectorSettings = DEFAULT_DETECTOR,
    pnp: PnPSettings = DEFAULT_PNP,
    ranges_csv: Path | None = None,
    image_topic: str | None = None,
    camera_info_topic: str | None = None,
    fixture_topic: str | None = None,
    keep_capture: Path | None = None,
    show_progress: bool = False,
) -> xr.Dataset:
    """Ingest a ROS bag: convert it to a capture folder, then ingest that folder.

    Parameters
    ----------
    bag : Path
        ROS 1 ``.bag`` file or ROS 2 bag folder.
    rig, detector, pnp
        As :func:`simgap.pipeline.capture.ingest`.
    ranges_csv, image_topic, camera_info_topic, fixture_topic
        As :func:`bag_to_capture`.
    keep_capture : Path, optional
        Write the intermediate capture folder here (default: a temporary folder, deleted).
    show_progress : bool
        Show a progress bar.

    Returns
    -------
    xarray.Dataset
        The result dataset of :func:`simgap.pipeline.capture.ingest`, with the attrs
        ``source = "bag"``, ``bag``, ``bag_format``, ``bag_image_topic``, ``bag_camera_info_topic``,
        ``bag_fixture_source``, ``bag_frames_skipped`` and ``bag_ranges_without_frames``.

    Raises
    ------
    simgap.core.config.ConfigError
        As :func:`bag_to_capture` and :func:`simgap.pipeline.capture.ingest`.
    """
    rig = rig or load_rig()
    with tempfile.TemporaryDirectory(prefix="simgap-bag-") as tmp:
        folder = Path(keep_capture) if keep_capture is not None else Path(tmp) / "capture"
        info = bag_to_capture(
            bag, folder, rig, ranges_csv, image_topic, camera_info_topic, fixture_topic
        )
        ds = ingest(folder, rig, detector, pnp, show_progress=show_progress)
    ds.attrs.update(
        {
            "title": f"simgap result: bag {Path(bag).name}",
            "source": "bag",
            "capture_dir": str(folder.resolve()) if keep_capture is not None else "",
            "bag": str(Path(bag).resolve()),
            "bag_format": info.format,
            "bag_image_topic": info.image_topic,
            "bag_camera_info_topic": info.camera_info_topic,
            "bag_fixture_source": info.fixture_source,
            "bag_frames_skipped": info.frames_skipped,
            "bag_ranges_without_frames": str(info.ranges_without_frames),
        }
    )
    return ds


# --- writing ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class BagFrame:
    """One frame to write.

    Attributes
    ----------
    p, theta, repeat
        Fixture configuration: pin hole, turntable angle (rad), repeat index.
    image : ndarray or (bytes, str)
        An 8-bit RGB (H, W, 3) or grey (H, W) array, or a file's bytes and its extension
        (``"png"`` or ``"jpg"``), kept as they are in a CompressedImage.
    expected, estimated : mapping of int to ndarray (6,)
        Poses per tag id in the global frame (m, rotation vector rad); NaN poses are skipped.
    """

    p: int
    theta: float
    repeat: int
    image: np.ndarray | tuple[bytes, str]
    expected: Mapping[int, np.ndarray] = field(default_factory=dict)
    estimated: Mapping[int, np.ndarray] = field(default_factory=dict)


def _typestore(fmt: BagFormat):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.ROS2_HUMBLE)


class _Messages:
    """Message builders for one typestore (ROS 1 and ROS 2 differ in field names)."""

    def __init__(self, fmt: BagFormat) -> None:
        self.fmt, self.ts = fmt, _typestore(fmt)
        self.types = self.ts.types

    def header(self, ns: int, frame_id: str = OPTICAL_FRAME):
        stamp = self.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        extra = {"seq": 0} if self.fmt == "ros1" else {}
        return self.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id, **extra)

    def serialize(self, msg: Any) -> bytes:
        if self.fmt == "ros1":
            return bytes(self.ts.serialize_ros1(msg, msg.__msgtype__))
        return bytes(self.ts.serialize_cdr(msg, msg.__msgtype__))

    def image(self, ns: int, image: np.ndarray | tuple[bytes, str], compressed: bool):
        import cv2

        if isinstance(image, tuple):
            data, ext = image
            if not compressed:
                bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
                return self.image(ns, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), False)
            fmt = "jpeg" if ext in ("jpg", "jpeg") else "png"
            return self.types[COMPRESSED_TYPE](
                header=self.header(ns), format=fmt, data=np.frombuffer(data, np.uint8)
            )
        img = np.asarray(image)
        if img.dtype != np.uint8 or img.ndim not in (2, 3):
            raise ValueError(f"image: expected 8-bit RGB or grey, got {img.dtype} {img.shape}")
        bgr = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
        if compressed:
            ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
            return self.image(ns, (buf.tobytes(), "png"), True)
        h, w = bgr.shape[:2]
        enc, step = ("mono8", w) if bgr.ndim == 2 else ("bgr8", 3 * w)
        return self.types[IMAGE_TYPE](
            header=self.header(ns), height=h, width=w, encoding=enc, is_bigendian=0,
            step=step, data=np.ascontiguousarray(bgr).reshape(-1),
        )  # fmt: skip

    def camera_info(self, ns: int, cal: CameraModel):
        proj = [cal.fx, 0.0, cal.cx, 0.0, 0.0, cal.fy, cal.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        mats = {
            "d": np.asarray(cal.distortion, float),
            "k": cal.matrix.ravel(),
            "r": np.eye(3).ravel(),
            "p": np.asarray(proj, float),
        }
        if self.fmt == "ros1":
            mats = {k.upper(): v for k, v in mats.items()}
        roi = self.types["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        return self.types[CAMERA_INFO_TYPE](
            header=self.header(ns), height=cal.height, width=cal.width,
            distortion_model="plumb_bob", binning_x=0, binning_y=0, roi=roi, **mats,
        )  # fmt: skip

    def joints(self, ns: int, travel_m: float, theta: float):
        return self.types[JOINT_STATE_TYPE](
            header=self.header(ns, "rail"), name=[CARRIAGE_JOINT, TURNTABLE_JOINT],
            position=np.array([travel_m, theta]), velocity=np.zeros(0), effort=np.zeros(0),
        )  # fmt: skip

    def pose(self, ns: int, pose6: np.ndarray):
        """A PoseStamped in the optical frame from a global-frame pose (m, rotation vector)."""
        from scipy.spatial.transform import Rotation

        eye_from_tag = tf.make(tf.rotvec_to_matrix(pose6[3:]), pose6[:3])
        cv_from_tag = tf.make(tf.GLOBAL_FROM_CV.T) @ eye_from_tag
        x, y, z, w = Rotation.from_matrix(cv_from_tag[:3, :3]).as_quat()
        t = self.types
        point = t["geometry_msgs/msg/Point"](*(float(v) for v in cv_from_tag[:3, 3]))
        quat = t["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w))
        return t[POSE_TYPE](
            header=self.header(ns),
            pose=t["geometry_msgs/msg/Pose"](position=point, orientation=quat),
        )


def write_bag(
    path: Path,
    fmt: BagFormat,
    calibration: CameraModel,
    frames: Iterable[BagFrame],
    rig: Rig,
    compressed: bool = False,
) -> Path:
    """Write frames, calibration, fixture joints and poses as a ROS 1 or ROS 2 bag, atomically.

    Parameters
    ----------
    path : Path
        The ``.bag`` file (ROS 1) or bag folder (ROS 2) to write; replaced if it exists.
    fmt : {"ros1", "ros2"}
        Bag format (ROS 1 noetic messages, or ROS 2 humble messages in SQLite 3 storage).
    calibration : CameraModel
        Published as ``sensor_msgs/CameraInfo`` with every frame.
    frames : iterable of BagFrame
        Consumed once, in order; frame ``i`` is stamped ``START_NS + i * PERIOD_NS`` (ns).
    rig : Rig
        The carriage joint is the travel ``p * pin_pitch`` (m).
    compressed : bool
        Frames as ``sensor_msgs/CompressedImage`` on :data:`COMPRESSED_TOPIC` (array frames
        encoded as PNG, file bytes kept) instead of raw ``bgr8`` on :data:`IMAGE_TOPIC`.

    Returns
    -------
    Path
        ``path``.
    """
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2

    if fmt not in BAG_FORMATS:
        raise ValueError(f"fmt: expected one of {', '.join(BAG_FORMATS)}, got {fmt!r}")
    build = _Messages(fmt)
    with staged_path(path) as tmp:
        writer = Writer1(tmp) if fmt == "ros1" else Writer2(tmp, version=9)
        conns: dict[str, Any] = {}

        def put(topic: str, msg: Any, ns: int) -> None:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msg.__msgtype__, typestore=build.ts)
            writer.write(conns[topic], ns, build.serialize(msg))

        with writer:
            for i, frame in enumerate(frames):
                ns = START_NS + i * PERIOD_NS
                travel = frame.p * rig.links.pin_pitch
                put(FIXTURE_TOPIC, build.joints(ns, travel, float(frame.theta)), ns)
                put(CAMERA_INFO_TOPIC, build.camera_info(ns, calibration), ns)
                topic = COMPRESSED_TOPIC if compressed else IMAGE_TOPIC
                put(topic, build.image(ns, frame.image, compressed), ns)
                for kind, poses in (("expected", frame.expected), ("estimated", frame.estimated)):
                    for tag, pose in sorted(poses.items()):
                        if np.all(np.isfinite(pose)):
                            put(f"/simgap/tag{tag}/{kind}", build.pose(ns, np.asarray(pose)), ns)
    return Path(path)


def _expected(rig: Rig, p: int, theta: float) -> dict[int, np.ndarray]:
    return {t: rig.expected_pose(t, p, theta) for t in rig.tags.ids}


def capture_to_bag(
    folder: Path, bag: Path, fmt: BagFormat, rig: Rig | None = None, compressed: bool = False
) -> Path:
    """Export a capture folder as a bag (frames in manifest order, ground truth from the rig).

    With ``compressed`` the image files' bytes are kept (PNG or JPEG); otherwise frames
    are decoded to raw ``bgr8``. Either way :func:`ingest_bag` of the bag gives the same data as
    :func:`simgap.pipeline.capture.ingest` of the folder (repeats renumbered 0, 1, ... in
    manifest order).

    Raises
    ------
    simgap.core.config.ConfigError
        As :func:`simgap.pipeline.capture.read_capture`.
    """
    rig = rig or load_rig()
    cap = read_capture(Path(folder), rig)

    def frames() -> Iterator[BagFrame]:
        for f in sorted(cap.frames, key=lambda f: f.repeat):
            image = (f.image.read_bytes(), f.image.suffix.lstrip(".").lower())
            yield BagFrame(f.p, f.theta, f.repeat, image, _expected(rig, f.p, f.theta))

    return write_bag(bag, fmt, cap.calibration, frames(), rig, compressed)


def experiment_to_bag(
    exp: Any,
    cache_dir: Path,
    bag: Path,
    fmt: BagFormat,
    dataset: xr.Dataset | None = None,
    variant: str | None = None,
    compressed: bool = False,
) -> Path:
    """Export an experiment's frames (from the render cache, rendered where missing) as a bag.

    Parameters
    ----------
    exp : simgap.pipeline.experiment.Experiment
        The experiment; its configurations are exported, or the dataset's when given.
    cache_dir : Path
        Render cache.
    bag : Path
        Output bag.
    fmt : {"ros1", "ros2"}
        Bag format.
    dataset : xarray.Dataset, optional
        A result dataset of ``exp``: its configurations and its estimated poses are written too.
    variant : str, optional
        Variant to export (default: the first).
    compressed : bool
        As :func:`write_bag`.

    Raises
    ------
    simgap.core.config.ConfigError
        If ``variant`` is not a variant of the experiment.
    """
    from simgap.pipeline.sweep import experiment_pipelines

    names = [name for name, _ in exp.variant_states()]
    variant = variant or names[0]
    if variant not in names:
        raise ConfigError(f"variant: expected one of {', '.join(names)}, got {variant!r}")
    pipe = experiment_pipelines(exp, Path(cache_dir))[names.index(variant)]
    rig = exp.rig_model
    if dataset is not None:
        ds = dataset.sel(variant=variant)
        ps, thetas, repeats = ds.p.values, ds.theta.values, ds.repeat.values
    else:
        ps, thetas, _ = exp.configuration_axes()
        repeats = range(exp.repeats)

    def frames() -> Iterator[BagFrame]:
        for repeat in repeats:
            for p in ps:
                for theta in thetas:
                    render_repeat = int(repeat) if exp.render.reseed_repeats else 0
                    frame = pipe.frame(int(p), float(theta), int(repeat), render_repeat)
                    if frame is None:
                        continue
                    est = {}
                    if dataset is not None:
                        sel = ds.estimated.sel(repeat=repeat, p=p, theta=theta)
                        est = {int(t): sel.sel(tag=t).values for t in sel.tag.values}
                    yield BagFrame(
                        int(p), float(theta), int(repeat), frame.rgb(),
                        _expected(rig, int(p), float(theta)), est,
                    )  # fmt: skip

    return write_bag(bag, fmt, pipe.state.estimation.calibration, frames(), rig, compressed)
