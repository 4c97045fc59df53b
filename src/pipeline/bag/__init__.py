"""ROS bags in and out, without a ROS installation (the ``rosbags`` and ``rosbags-image`` packages).

In: a ROS 1 ``.bag`` file, a ROS 2 bag folder (``metadata.yaml`` + storage files) or one ROS 2
storage file (``.mcap`` or ``.db3``) is converted
into a capture folder (docs/conventions.md §3), the common interchange, which
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

Out: :func:`write_bag` writes (by the output's name: ``.bag`` ROS 1, ``.mcap`` / ``.db3`` one ROS 2
MCAP / SQLite 3 file, no extension a ROS 2 bag folder) frames as ``sensor_msgs/Image`` (``bgr8``) or
``sensor_msgs/CompressedImage`` with a ``sensor_msgs/CameraInfo`` per frame, the fixture
configuration as ``sensor_msgs/JointState``, the rig's transform tree on ``/tf_static`` and
``/tf`` (:mod:`.writer`), and poses as ``geometry_msgs/PoseStamped`` in the
camera's optical frame (x right, y down, z forward; what aruco_ros publishes):
``/simgap/tag<ID>/expected`` (ground truth of the rig's CAD) and, when known,
``/simgap/tag<ID>/estimated``. :func:`capture_to_bag` exports a capture folder,
:func:`experiment_to_bag` the cached renders of an experiment or a simulated result dataset.

Every problem with a bag or a CSV raises :class:`~simgap.core.config.ConfigError` naming the file,
the topic or row, and what was expected.

Modules, by job: :mod:`.formats` (bag kinds, message types, topics), :mod:`.ranges` (time-range
CSV), :mod:`.reader` (bag -> capture folder -> dataset) and :mod:`.writer` (capture, experiment or
frames -> bag).
"""

from __future__ import annotations

from simgap.pipeline.bag.formats import (
    BAG_FORMATS,
    BAG_STORAGES,
    CAMERA_INFO_TOPIC,
    CARRIAGE_JOINT,
    COMPRESSED_TOPIC,
    FIXTURE_TOPIC,
    IMAGE_TOPIC,
    RANGE_COLUMNS,
    TF_STATIC_TOPIC,
    TF_TOPIC,
    TURNTABLE_JOINT,
    BagFormat,
    BagStorage,
    BagTarget,
    bag_format,
    bag_target,
    is_bag,
    is_exported_bag,
)
from simgap.pipeline.bag.ranges import TimeRange, read_time_ranges
from simgap.pipeline.bag.reader import BagConversion, bag_to_capture, ingest_bag
from simgap.pipeline.bag.tf_tree import moving_transforms, static_transforms
from simgap.pipeline.bag.writer import (
    BagFrame,
    capture_to_bag,
    experiment_to_bag,
    write_bag,
)

__all__ = [
    "BAG_FORMATS",
    "BAG_STORAGES",
    "CAMERA_INFO_TOPIC",
    "CARRIAGE_JOINT",
    "COMPRESSED_TOPIC",
    "FIXTURE_TOPIC",
    "IMAGE_TOPIC",
    "RANGE_COLUMNS",
    "TF_STATIC_TOPIC",
    "TF_TOPIC",
    "TURNTABLE_JOINT",
    "BagConversion",
    "BagFormat",
    "BagFrame",
    "BagStorage",
    "BagTarget",
    "TimeRange",
    "bag_format",
    "bag_target",
    "bag_to_capture",
    "capture_to_bag",
    "experiment_to_bag",
    "ingest_bag",
    "is_bag",
    "is_exported_bag",
    "moving_transforms",
    "read_time_ranges",
    "static_transforms",
    "write_bag",
]
