"""ROS bag kinds, message types, topics and joint names that simgap reads and writes."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from simgap.core.config import ConfigError

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
