"""Write ROS bags: frames, camera info, fixture joints, the fixture's transform tree and tag poses.

The transform tree (:class:`simgap.core.rig.Rig`'s frames, CAD values) goes on ``/tf_static``
(once, before the first frame; latched / transient local) for the links that never move:
``carriage -> eyepoint``, ``eyepoint -> camera_color_optical_frame`` and ``turntable -> tag<ID>``;
and on ``/tf`` at every frame's stamp for the two that move with the fixture configuration:
``rail -> carriage`` (pin hole p) and ``rail -> turntable`` (theta). ``rail`` is the root.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import xarray as xr

from simgap.core.atomic import staged_path
from simgap.core.config import ConfigError
from simgap.core.progress import ProgressCallback, Steps
from simgap.core.rig import CameraModel, Rig, load_rig
from simgap.pipeline.bag.formats import (
    CAMERA_INFO_TOPIC,
    COMPRESSED_TOPIC,
    FIXTURE_TOPIC,
    IMAGE_TOPIC,
    PERIOD_NS,
    START_NS,
    TF_STATIC_TOPIC,
    TF_TOPIC,
    BagFormat,
    BagStorage,
    BagTarget,
    bag_target,
)
from simgap.pipeline.bag.messages import Messages
from simgap.pipeline.bag.tf_tree import moving_transforms, static_transforms
from simgap.pipeline.capture.folder import read_capture, read_image


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


def _latched_qos():
    """ROS 2 QoS of ``/tf_static`` (keep last 1, reliable, transient local), as tf2 offers it."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    zero = QosTime(0, 0)
    return Qos(
        QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
        zero, zero, QosLiveliness.AUTOMATIC, zero, False,
    )  # fmt: skip


def _open_writer(target: BagTarget, path: Path):
    """A rosbags writer for ``target`` at the fresh path ``path``."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    if target.format == "ros1":
        return Writer1(path)
    plugin = StoragePlugin.MCAP if target.storage == "mcap" else StoragePlugin.SQLITE3
    return Writer2(path, version=9, storage_plugin=plugin)


def write_bag(
    path: Path,
    fmt: BagFormat | None,
    calibration: CameraModel,
    frames: Iterable[BagFrame],
    rig: Rig,
    images: str = "raw",
    storage: BagStorage | None = None,
) -> Path:
    """Write frames, calibration, fixture joints, transforms and poses as a bag, atomically.

    Parameters
    ----------
    path : Path
        What to write (:func:`~simgap.pipeline.bag.formats.bag_target`): ``NAME.bag`` a ROS 1
        bag, ``NAME.mcap`` / ``NAME.db3`` one ROS 2 MCAP / SQLite 3 storage file (it holds the
        message definitions, so it is a whole bag), ``NAME`` a ROS 2 bag folder; replaced if it
        exists.
    fmt : {"ros1", "ros2"} or None
        Bag format (ROS 1 noetic or ROS 2 humble messages); None: from the name.
    calibration : CameraModel
        Published as ``sensor_msgs/CameraInfo`` with every frame.
    frames : iterable of BagFrame
        Consumed once, in order; frame ``i`` is stamped ``START_NS + i * PERIOD_NS`` (ns).
    rig : Rig
        The carriage joint is the travel ``p * pin_pitch`` (m); its transform tree goes on
        ``/tf_static`` and ``/tf`` (module docstring).
    images : {"raw", "png", "jpeg"}
        Frames as raw ``bgr8`` on :data:`IMAGE_TOPIC`, or as ``sensor_msgs/CompressedImage`` on
        :data:`COMPRESSED_TOPIC` (array frames encoded as PNG or JPEG, file bytes kept)
        (:data:`~simgap.pipeline.bag.formats.IMAGE_ENCODINGS`).
    storage : {"sqlite3", "mcap"}, optional
        Storage of a ROS 2 bag folder (default SQLite 3); must agree with a file's extension.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    simgap.core.config.ConfigError
        For a name, ``fmt`` or ``storage`` that do not agree (naming the allowed forms).
    """
    target = bag_target(path, fmt, storage)
    build = Messages(target.format)
    with staged_path(path) as tmp:
        # a single storage file is written as a bag folder beside it, then moved out of it
        folder = tmp.with_name(tmp.name + ".folder") if target.single_file else tmp
        writer = _open_writer(target, folder)
        conns: dict[str, Any] = {}

        def put(topic: str, msg: Any, ns: int, latched: bool = False) -> None:
            if topic not in conns:
                extra: dict[str, Any] = {}
                if latched:
                    extra = (
                        {"latching": 1}
                        if target.format == "ros1"
                        else {"offered_qos_profiles": [_latched_qos()]}
                    )
                conns[topic] = writer.add_connection(
                    topic, msg.__msgtype__, typestore=build.ts, **extra
                )
            writer.write(conns[topic], ns, build.serialize(msg))

        with writer:
            put(TF_STATIC_TOPIC, build.transforms(START_NS, static_transforms(rig)), START_NS, True)
            for i, frame in enumerate(frames):
                ns = START_NS + i * PERIOD_NS
                travel = frame.p * rig.links.pin_pitch
                put(FIXTURE_TOPIC, build.joints(ns, travel, float(frame.theta)), ns)
                put(
                    TF_TOPIC, build.transforms(ns, moving_transforms(rig, frame.p, frame.theta)), ns
                )
                put(CAMERA_INFO_TOPIC, build.camera_info(ns, calibration), ns)
                topic = IMAGE_TOPIC if images == "raw" else COMPRESSED_TOPIC
                put(topic, build.image(ns, frame.image, images), ns)
                for kind, poses in (("expected", frame.expected), ("estimated", frame.estimated)):
                    for tag, pose in sorted(poses.items()):
                        if np.all(np.isfinite(pose)):
                            put(f"/simgap/tag{tag}/{kind}", build.pose(ns, np.asarray(pose)), ns)
        for mcap in folder.glob("*.mcap"):
            add_chunk_checksums(mcap)
        if target.single_file:
            suffix = ".mcap" if target.storage == "mcap" else ".db3"
            (folder / f"{folder.name}{suffix}").replace(tmp)
    return Path(path)


#: MCAP's magic bytes and the opcodes of a Chunk and of the Footer (mcap.dev specification).
MCAP_MAGIC = b"\x89MCAP0\r\n"
MCAP_CHUNK, MCAP_FOOTER = 0x06, 0x02


def add_chunk_checksums(path: Path) -> int:
    """Write each uncompressed chunk's CRC-32 into an MCAP file's chunk records; return how many.

    The MCAP writer of rosbags leaves ``uncompressed_crc`` 0 (no checksum), so a reader cannot
    tell damaged message data; rosbag2's own MCAP plugin writes it. With it, rosbags' reader
    refuses a chunk whose bytes changed ("Chunk checksum mismatch"). Compressed chunks keep 0.
    """
    data = bytearray(Path(path).read_bytes())
    if not data.startswith(MCAP_MAGIC):
        raise ValueError(f"{path}: not an MCAP file")
    pos, count = len(MCAP_MAGIC), 0
    while pos + 9 <= len(data):
        opcode, length = data[pos], int.from_bytes(data[pos + 1 : pos + 9], "little")
        body = pos + 9
        if opcode == MCAP_FOOTER:
            break
        if opcode == MCAP_CHUNK:
            name_len = int.from_bytes(data[body + 28 : body + 32], "little")
            compression = bytes(data[body + 32 : body + 32 + name_len])
            at = body + 32 + name_len
            size = int.from_bytes(data[at : at + 8], "little")
            if compression == b"":
                crc = zlib.crc32(data[at + 8 : at + 8 + size])
                data[body + 24 : body + 28] = crc.to_bytes(4, "little")
                count += 1
        pos = body + length
    Path(path).write_bytes(bytes(data))
    return count


def _expected(rig: Rig, p: int, theta: float) -> dict[int, np.ndarray]:
    return {t: rig.expected_pose(t, p, theta) for t in rig.tags.ids}


def capture_to_bag(
    folder: Path,
    bag: Path,
    fmt: BagFormat | None,
    rig: Rig | None = None,
    images: str = "raw",
    storage: BagStorage | None = None,
) -> Path:
    """Export a capture folder as a bag (frames in manifest order, ground truth from the rig).

    With ``images`` png or jpeg an image file of that format keeps its bytes, another is
    decoded and encoded so; raw frames are decoded to ``bgr8``. Every decoded frame's header
    size is checked against the calibration's first. Without JPEG re-encoding,
    :func:`ingest_bag` of the bag gives the same data as :func:`simgap.pipeline.capture.ingest`
    of the folder (repeats renumbered 0, 1, ... in manifest order).

    Raises
    ------
    simgap.core.config.ConfigError
        As :func:`simgap.pipeline.capture.read_capture`; also for a frame that must be decoded
        and cannot be, or whose size differs from the calibration's.
    """
    rig = rig or load_rig()
    cap = read_capture(Path(folder), rig)
    cal = cap.calibration

    def frames() -> Iterator[BagFrame]:
        for f in sorted(cap.frames, key=lambda f: f.repeat):
            yield BagFrame(f.p, f.theta, f.repeat, frame(f.image), _expected(rig, f.p, f.theta))

    def frame(path: Path) -> np.ndarray | tuple[bytes, str]:
        ext = path.suffix.lstrip(".").lower()
        if images != "raw" and ("jpeg" if ext in ("jpg", "jpeg") else ext) == images:
            return path.read_bytes(), ext
        bgr = read_image(path, cal.width, cal.height)
        if isinstance(bgr, str):
            raise ConfigError(
                f"{path}: frame {bgr}; a bag holds decoded frames of the calibration's size "
                "(--images with the files' own format keeps their bytes instead)"
            )
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)

    return write_bag(bag, fmt, cal, frames(), rig, images, storage)


def experiment_to_bag(
    exp: Any,
    cache_dir: Path,
    bag: Path,
    fmt: BagFormat | None,
    dataset: xr.Dataset | None = None,
    variant: str | None = None,
    images: str = "raw",
    storage: BagStorage | None = None,
    progress: ProgressCallback | None = None,
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
    fmt : {"ros1", "ros2"} or None
        Bag format (None: from the name, as :func:`write_bag`).
    dataset : xarray.Dataset, optional
        A result dataset of ``exp``: its configurations and its estimated poses are written too.
    variant : str, optional
        Variant to export (default: the first).
    images, storage
        As :func:`write_bag`.
    progress : ProgressCallback, optional
        Told of each configuration exported (step ``exporting frames``; rendering them where
        the cache has none is most of the work).

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

    steps = Steps(progress)
    steps.start("exporting frames", len(repeats) * len(ps) * len(thetas))

    def frames() -> Iterator[BagFrame]:
        for repeat in repeats:
            for p in ps:
                for theta in thetas:
                    steps.advance()
                    render_repeat = exp.render.render_repeat(repeat)
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

    cal = pipe.state.estimation.calibration
    return write_bag(bag, fmt, cal, frames(), rig, images, storage)
