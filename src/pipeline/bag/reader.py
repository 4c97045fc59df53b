"""Read a ROS bag into a capture folder (then :func:`simgap.pipeline.capture.ingest`)."""

from __future__ import annotations

import csv
import io
import json
import math
import re
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
import yaml

from simgap.core.atomic import atomic_write, remove_dead_writers, writer_tag
from simgap.core.config import ConfigError, shown
from simgap.core.limits import MAX_PIXELS
from simgap.core.paths import CALIBRATION_FILE, IMAGES_DIR, MANIFEST_FILE
from simgap.core.rig import CameraModel, Rig, load_rig
from simgap.pipeline.bag.formats import (
    CAMERA_INFO_TYPE,
    CARRIAGE_JOINT,
    COMPRESSED_TYPE,
    FIXTURE_TOPIC,
    IMAGE_TYPE,
    JOINT_STATE_TYPE,
    PIN_TOLERANCE,
    RANGE_COLUMNS,
    TURNTABLE_JOINT,
    BagFormat,
    bag_format,
)
from simgap.pipeline.bag.frame_bytes import frame_bytes
from simgap.pipeline.bag.ranges import TimeRange, read_time_ranges
from simgap.pipeline.capture import CaptureWarning, read_calibration
from simgap.pipeline.capture.folder import check_pixel_budget
from simgap.pipeline.capture.ingest import ingest
from simgap.pipeline.capture.manifest import turntable_stop
from simgap.pipeline.capture.writer import image_name


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
    #: each written frame's path in the capture folder (relative) -> ``BAG: topic T: message I``
    messages: dict[str, str] = field(default_factory=dict)


def bag_messages(reader: Any, conns: list, bag: Path) -> Iterator[tuple[int, Any, int, Any]]:
    """``(index from 1, connection, record time ns, message)`` of the messages on ``conns``.

    A damaged bag (a corrupt database page, a record cut short, a message that does not
    deserialise as its type) is a ConfigError naming the bag, the topic and the message; the
    reader's own error types vary by format (rosbags, SQLite, MCAP), so any of them is caught
    around the reader's calls alone.
    """
    topic = conns[0].topic if conns else "?"
    records = reader.messages(connections=conns)
    i = 0
    while True:
        try:
            conn, t, raw = next(records)
        except StopIteration:
            return
        except Exception as exc:  # the reader's, on damaged data
            raise ConfigError(
                f"{bag}: topic {topic}: message {i + 1}: cannot be read, the bag is damaged "
                f"({type(exc).__name__}: {shown(str(exc), 120)})"
            ) from None
        i += 1
        try:
            msg = reader.deserialize(raw, conn.msgtype)
        except Exception as exc:  # the deserialiser's, on damaged data
            raise ConfigError(
                f"{bag}: topic {conn.topic}: message {i}: cannot be read as {conn.msgtype} "
                f"({type(exc).__name__}: {shown(str(exc), 120)})"
            ) from None
        yield i, conn, t, msg


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


def _read_calibration(
    reader: Any, conns: list, bag: Path, folder: Path, max_pixels: int
) -> CameraModel:
    """The bag's calibration, written as ``camera.yaml`` and validated like a capture's.

    Its image size is held to the pixel budget (``max_pixels``) before any frame is read.
    """
    texts = []
    for i, conn, _, msg in bag_messages(reader, conns, bag):
        where = f"{bag}: topic {conn.topic}: message {i}"
        check_pixel_budget(int(msg.width), int(msg.height), max_pixels, where, "width x height")
        texts.append(_camera_info_yaml(msg))
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


def _in_recording_order(stamp_ns: int, previous: tuple[int, int] | None, where: str) -> None:
    """Refuse a stamp earlier than the previous message's of its topic (``(stamp, index)``).

    A sensor's stamps increase with the recording; stamps that go back contradict the other
    topics they are matched with, and would assign frames the wrong poses
    (docs/results/inputs_that_lie.md).
    """
    if previous is not None and stamp_ns < previous[0]:
        raise ConfigError(
            f"{where}: header.stamp: {stamp_ns} ns is earlier than message {previous[1]}'s "
            f"{previous[0]} ns; expected stamps that increase with the recording (they assign "
            "the frames their fixture configurations)"
        )


def _fixture_from_joints(reader: Any, conns: list, bag: Path, rig: Rig) -> list[tuple]:
    """``(stamp_ns, p, theta)`` of every joint-state message, in time order.

    Raises ConfigError for stamps that go back in the recording (:func:`_in_recording_order`)
    and for two messages at one stamp that claim different configurations.
    """
    topic = conns[0].topic
    out = []
    previous: tuple[int, int] | None = None
    at_stamp: dict[int, tuple[int, int, float]] = {}
    for i, _, t, msg in bag_messages(reader, conns, bag):
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
        ns = _stamp_ns(msg, t)
        _in_recording_order(ns, previous, where)
        first = at_stamp.setdefault(ns, (i, p, theta))
        if first[1:] != (p, theta):
            raise ConfigError(
                f"{where}: position: (p={p}, theta={math.degrees(theta):g} deg) at the stamp of "
                f"message {first[0]}, which claims (p={first[1]}, "
                f"theta={math.degrees(first[2]):g} deg); expected one configuration a stamp"
            )
        previous = (ns, i)
        out.append((ns, p, theta))
    if not out:
        raise ConfigError(f"{bag}: topic {topic}: no messages (expected JointState)")
    return sorted(out, key=lambda x: x[0])


def bag_to_capture(
    bag: Path,
    folder: Path,
    rig: Rig,
    ranges_csv: Path | None = None,
    image_topic: str | None = None,
    camera_info_topic: str | None = None,
    fixture_topic: str | None = None,
    max_pixels: int = MAX_PIXELS,
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
    max_pixels : int
        The pixel budget (:data:`simgap.core.limits.MAX_PIXELS`): a CameraInfo
        whose image is larger is refused before any frame is read.

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
        cal = _read_calibration(reader, infos, bag, folder, max_pixels)
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
        rows = _write_frames(reader, images, bag, folder, ranges, joints, info, cal)
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
    cal: CameraModel,
) -> list[list]:
    """Write each frame that has a configuration; return the manifest rows."""
    stamps = [j[0] for j in joints]
    counts: dict[tuple[int, float], int] = {}
    used: set[int] = set()
    rows = []
    previous: tuple[int, int] | None = None
    for i, conn, t, msg in bag_messages(reader, conns, bag):
        ns = _stamp_ns(msg, t)
        _in_recording_order(ns, previous, f"{bag}: topic {conn.topic}: message {i}")
        previous = (ns, i)
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
        where = f"{bag}: topic {conn.topic}: message {i}"
        data, ext = frame_bytes(msg, conn.msgtype, where, cal)
        repeat = counts.get(config, 0)
        counts[config] = repeat + 1
        name = f"{IMAGES_DIR}/{image_name(config[0], config[1], repeat, ext)}"
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        atomic_write(folder / name, data)
        info.messages[name] = where
        rows.append([name, config[0], f"{config[1]:.9f}", repeat])
        info.frames += 1
    info.ranges_without_frames = sorted({r.row for r in ranges or []} - used)
    return rows


#: Prefix of the temporary capture folders of bag conversions (``simgap-bag-<host>-<pid>-...``).
BAG_TEMPORARY_PREFIX = "simgap-bag-"
_BAG_FOLDER = re.compile(rf"^{BAG_TEMPORARY_PREFIX}(?P<host>[0-9a-f]{{6}})-(?P<pid>\d+)-")


def _named_by_message(text: str, by_path: dict[str, str]) -> str:
    """``text`` with each converted frame's path replaced by its bag, topic and message."""
    for path, where in by_path.items():
        text = text.replace(path, where)
    return text


def remove_stale_bag_folders() -> int:
    """Remove the temporary capture folders of bag conversions killed on this host; the count.

    A conversion killed outright (kill -9) leaves its folder in the temporary directory; the
    next bag ingest removes those whose process is gone (:func:`simgap.core.atomic.writer_alive`).
    """
    return remove_dead_writers(Path(tempfile.gettempdir()), _BAG_FOLDER)


def ingest_bag(
    bag: Path,
    rig: Rig | None = None,
    ranges_csv: Path | None = None,
    image_topic: str | None = None,
    camera_info_topic: str | None = None,
    fixture_topic: str | None = None,
    keep_capture: Path | None = None,
    show_progress: bool = False,
    max_pixels: int = MAX_PIXELS,
    **estimator: Any,
) -> xr.Dataset:
    """Ingest a ROS bag: convert it to a capture folder, then ingest that folder.

    Parameters
    ----------
    bag : Path
        ROS 1 ``.bag`` file or ROS 2 bag folder.
    rig : Rig, optional
        The fixture (default: the packaged rig).
    ranges_csv, image_topic, camera_info_topic, fixture_topic
        As :func:`bag_to_capture`.
    keep_capture : Path, optional
        Write the intermediate capture folder here (default: a temporary folder, deleted).
    show_progress : bool
        Show a progress bar.
    max_pixels : int
        The pixel budget (:data:`simgap.core.limits.MAX_PIXELS`), for the bag's
        CameraInfo and its frames.
    **estimator
        ``detector``, ``pnp``, ``calibration`` and ``calibration_file`` (wins over the bag's
        CameraInfo, which still gives the frames' expected size), passed on to
        :func:`simgap.pipeline.capture.ingest` (its defaults where absent).

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
    remove_stale_bag_folders()
    with tempfile.TemporaryDirectory(prefix=f"{BAG_TEMPORARY_PREFIX}{writer_tag()}-") as tmp:
        folder = Path(keep_capture) if keep_capture is not None else Path(tmp) / "capture"
        info = bag_to_capture(
            bag, folder, rig, ranges_csv, image_topic, camera_info_topic, fixture_topic,
            max_pixels,
        )  # fmt: skip
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", CaptureWarning)
            ds = ingest(
                folder, rig, show_progress=show_progress, max_pixels=max_pixels, **estimator
            )
        by_path = {str(folder / name): where for name, where in info.messages.items()}
        for warning in caught:  # the frames by topic and message: the folder may be gone
            if issubclass(warning.category, CaptureWarning):
                warnings.warn(_named_by_message(str(warning.message), by_path), CaptureWarning, 2)
            else:
                warnings.warn_explicit(
                    warning.message, warning.category, warning.filename, warning.lineno
                )
        failed = json.loads(ds.attrs.get("frames_failed", "[]"))
        ds.attrs["frames_failed"] = json.dumps([by_path.get(f, f) for f in failed])
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
