"""ROS bag kinds, message types, topics and joint names that simgap reads and writes."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from simgap.core.config import ConfigError

BagFormat = Literal["ros1", "ros2"]
BAG_FORMATS: tuple[str, ...] = ("ros1", "ros2")
#: Storage of a ROS 2 bag: SQLite 3 (``.db3``) or MCAP (``.mcap``).
BagStorage = Literal["sqlite3", "mcap"]
BAG_STORAGES: tuple[str, ...] = ("sqlite3", "mcap")
#: A ROS 2 bag written or read as one storage file (no ``metadata.yaml``), by its extension.
ROS2_FILE_SUFFIXES: dict[str, BagStorage] = {".mcap": "mcap", ".db3": "sqlite3"}
#: What an output bag's name may look like, for messages.
BAG_NAMES = (
    "NAME.bag (ROS 1), NAME.mcap (ROS 2, one MCAP file), NAME.db3 (ROS 2, one SQLite 3 file) "
    "or NAME without extension (ROS 2 bag folder; --storage sqlite3 or mcap)"
)
IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO_TYPE = "sensor_msgs/msg/CameraInfo"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
TF_TYPE = "tf2_msgs/msg/TFMessage"
#: How an exported bag holds its frames: raw ``bgr8`` ``Image`` messages, or ``CompressedImage``
#: messages in PNG (lossless) or JPEG.
IMAGE_ENCODINGS = ("raw", "png", "jpeg")
#: JPEG quality of exported frames: ROS compressed_image_transport's default ``jpeg_quality``.
JPEG_QUALITY = 80
#: Default topics of an exported bag (RealSense driver naming).
IMAGE_TOPIC = "/camera/color/image_raw"
COMPRESSED_TOPIC = "/camera/color/image_raw/compressed"
CAMERA_INFO_TOPIC = "/camera/color/camera_info"
FIXTURE_TOPIC = "/simgap/fixture"
#: The fixture's transform tree: static links once, moving links at every frame's stamp.
TF_STATIC_TOPIC = "/tf_static"
TF_TOPIC = "/tf"
CARRIAGE_JOINT = "carriage"
TURNTABLE_JOINT = "turntable"
OPTICAL_FRAME = "camera_color_optical_frame"
RANGE_COLUMNS = ("start_ns", "end_ns", "p", "theta_rad")
#: How far a carriage joint position may be from a pin hole, in pin pitches.
PIN_TOLERANCE = 0.02
#: Time stamp of the first exported frame and the period between frames (ns).
START_NS = 1_700_000_000 * 10**9
PERIOD_NS = 100_000_000


@dataclass(frozen=True)
class BagTarget:
    """How an output bag is written, from its name and the options.

    Attributes
    ----------
    format : {"ros1", "ros2"}
        ROS 1 (noetic messages) or ROS 2 (humble messages).
    storage : {"sqlite3", "mcap"} or None
        ROS 2 storage (None for ROS 1).
    single_file : bool
        ROS 2 written as its one storage file (``.mcap`` or ``.db3``, no ``metadata.yaml``)
        instead of a bag folder.
    """

    format: BagFormat
    storage: BagStorage | None = None
    single_file: bool = False


def bag_target(path: Path, fmt: str | None = None, storage: str | None = None) -> BagTarget:
    """The bag to write at ``path``: its extension decides, ``fmt`` and ``storage`` must agree.

    ``NAME.bag``: ROS 1; ``NAME.mcap``: one ROS 2 MCAP file; ``NAME.db3``: one ROS 2 SQLite 3
    file; ``NAME`` without extension: a ROS 2 bag folder in ``storage`` (default SQLite 3).

    Raises
    ------
    simgap.core.config.ConfigError
        For another extension, or a ``fmt`` / ``storage`` the name contradicts (naming the
        allowed forms).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if fmt is not None and fmt not in BAG_FORMATS:
        raise ConfigError(f"--format: expected one of {', '.join(BAG_FORMATS)}, got {fmt!r}")
    if storage is not None and storage not in BAG_STORAGES:
        raise ConfigError(f"--storage: expected one of {', '.join(BAG_STORAGES)}, got {storage!r}")
    if suffix == ".bag":
        target = BagTarget("ros1")
    elif suffix in ROS2_FILE_SUFFIXES:
        target = BagTarget("ros2", ROS2_FILE_SUFFIXES[suffix], single_file=True)
    elif suffix == "":
        target = BagTarget("ros2", storage or "sqlite3")  # type: ignore[arg-type]
    else:
        raise ConfigError(f"-o/--output {path}: extension {path.suffix!r}: expected {BAG_NAMES}")
    if fmt is not None and fmt != target.format:
        raise ConfigError(
            f"--format {fmt}: -o/--output {path} names a {target.format} bag; expected {BAG_NAMES}"
        )
    if storage is not None and storage != target.storage:
        raise ConfigError(
            f"--storage {storage}: -o/--output {path} names a "
            f"{target.storage or 'ROS 1'} bag; expected {BAG_NAMES}"
        )
    return target


def bag_format(path: Path) -> BagFormat:
    """``"ros1"`` for a ``.bag`` file, ``"ros2"`` for a bag folder or a ``.mcap``/``.db3`` file.

    Raises
    ------
    simgap.core.config.ConfigError
        If ``path`` is none of them.
    """
    path = Path(path)
    if path.is_file() and path.suffix == ".bag":
        return "ros1"
    if path.is_file() and path.suffix in ROS2_FILE_SUFFIXES:
        return "ros2"
    if path.is_dir() and (path / "metadata.yaml").is_file():
        return "ros2"
    raise ConfigError(
        f"{path}: not a ROS bag: expected a ROS 1 .bag file, a ROS 2 .mcap or .db3 file or a "
        "ROS 2 bag folder (with metadata.yaml)"
    )


def is_bag(path: Path) -> bool:
    """Whether ``path`` looks like a ROS 1 or ROS 2 bag (see :func:`bag_format`)."""
    try:
        bag_format(path)
    except ConfigError:
        return False
    return True


def is_exported_bag(path: Path) -> bool:
    """Whether ``path`` is a bag simgap wrote: a ROS 1 or ROS 2 bag with :data:`FIXTURE_TOPIC`.

    Reads the bag's index (connections) only. False for anything else, readable or not.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if not is_bag(path):
        return False
    try:
        with AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as bag:
            return any(c.topic == FIXTURE_TOPIC for c in bag.connections)
    except Exception:  # rosbags raises its own error types for damaged or foreign bags
        return False
