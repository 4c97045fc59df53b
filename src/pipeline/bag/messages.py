"""ROS message builders for the exported bags (ROS 1 and ROS 2 field names), one per typestore."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from simgap.core import transforms as tf
from simgap.core.rig import CameraModel
from simgap.pipeline.bag.formats import (
    CAMERA_INFO_TYPE,
    CARRIAGE_JOINT,
    COMPRESSED_TYPE,
    IMAGE_TYPE,
    JOINT_STATE_TYPE,
    JPEG_QUALITY,
    OPTICAL_FRAME,
    POSE_TYPE,
    TF_TYPE,
    TURNTABLE_JOINT,
    BagFormat,
)
from simgap.render import imaging


def typestore(fmt: BagFormat):
    """The typestore of ``fmt`` (ROS 1 Noetic or ROS 2 Humble) with ``tf2_msgs/TFMessage``."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.ROS2_HUMBLE)
    if TF_TYPE not in store.types:  # rosbags' noetic store lacks tf2_msgs: its one-line definition
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF_TYPE))
    return store


class Messages:
    """Message builders for one typestore (ROS 1 and ROS 2 differ in field names)."""

    def __init__(self, fmt: BagFormat) -> None:
        self.fmt, self.ts = fmt, typestore(fmt)
        self.types = self.ts.types

    def header(self, ns: int, frame_id: str = OPTICAL_FRAME):
        """A ``std_msgs/Header`` at ``ns`` (ns since the epoch) in ``frame_id``."""
        stamp = self.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        extra = {"seq": 0} if self.fmt == "ros1" else {}
        return self.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id, **extra)

    def serialize(self, msg: Any) -> bytes:
        """``msg`` serialised for the bag (ROS 1 or CDR)."""
        if self.fmt == "ros1":
            return bytes(self.ts.serialize_ros1(msg, msg.__msgtype__))
        return bytes(self.ts.serialize_cdr(msg, msg.__msgtype__))

    def image(self, ns: int, image: np.ndarray | tuple[bytes, str], images: str):
        """A raw ``Image`` (bgr8 or mono8) or a ``CompressedImage`` (``images`` png or jpeg).

        ``image`` is an 8-bit RGB or grey array, or a file's bytes and its format (kept as they
        are in a ``CompressedImage``; decoded for a raw one). Arrays are encoded as PNG or as
        JPEG at :data:`~simgap.pipeline.bag.formats.JPEG_QUALITY`.
        """
        if isinstance(image, tuple):
            data, ext = image
            if images == "raw":
                bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
                return self.image(ns, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), "raw")
            fmt = "jpeg" if ext in ("jpg", "jpeg") else "png"
            return self.types[COMPRESSED_TYPE](
                header=self.header(ns), format=fmt, data=np.frombuffer(data, np.uint8)
            )
        img = np.asarray(image)
        if img.dtype != np.uint8 or img.ndim not in (2, 3):
            raise ValueError(f"image: expected 8-bit RGB or grey, got {img.dtype} {img.shape}")
        bgr = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
        if images == "png":
            return self.image(ns, (imaging.encode_png(bgr), "png"), images)
        if images == "jpeg":
            ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if not ok:
                raise RuntimeError("JPEG encoding failed")
            return self.image(ns, (buf.tobytes(), "jpeg"), images)
        h, w = bgr.shape[:2]
        enc, step = ("mono8", w) if bgr.ndim == 2 else ("bgr8", 3 * w)
        return self.types[IMAGE_TYPE](
            header=self.header(ns), height=h, width=w, encoding=enc, is_bigendian=0,
            step=step, data=np.ascontiguousarray(bgr).reshape(-1),
        )  # fmt: skip

    def camera_info(self, ns: int, cal: CameraModel):
        """A ``CameraInfo`` of the calibration ``cal`` (its distortion model and coefficients)."""
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
            distortion_model=cal.distortion_model, binning_x=0, binning_y=0, roi=roi, **mats,
        )  # fmt: skip

    def joints(self, ns: int, travel_m: float, theta: float):
        """The fixture's ``JointState``: carriage travel (m) and turntable angle (rad)."""
        return self.types[JOINT_STATE_TYPE](
            header=self.header(ns, "rail"), name=[CARRIAGE_JOINT, TURNTABLE_JOINT],
            position=np.array([travel_m, theta]), velocity=np.zeros(0), effort=np.zeros(0),
        )  # fmt: skip

    def _pose_parts(self, m: np.ndarray):
        """``geometry_msgs`` position values and Quaternion of a 4x4 transform."""
        x, y, z, w = Rotation.from_matrix(m[:3, :3]).as_quat()
        quat = self.types["geometry_msgs/msg/Quaternion"](
            x=float(x), y=float(y), z=float(z), w=float(w)
        )
        return [float(v) for v in m[:3, 3]], quat

    def transforms(self, ns: int, links: list[tuple[str, str, np.ndarray]]):
        """A ``tf2_msgs/TFMessage`` of ``(parent, child, parent_from_child)`` links."""
        t = self.types
        out = []
        for parent, child, m in links:
            xyz, quat = self._pose_parts(m)
            out.append(
                t["geometry_msgs/msg/TransformStamped"](
                    header=self.header(ns, parent),
                    child_frame_id=child,
                    transform=t["geometry_msgs/msg/Transform"](
                        translation=t["geometry_msgs/msg/Vector3"](*xyz), rotation=quat
                    ),
                )
            )
        return t[TF_TYPE](transforms=out)

    def pose(self, ns: int, pose6: np.ndarray):
        """A PoseStamped in the optical frame from a global-frame pose (m, rotation vector)."""
        eye_from_tag = tf.make(tf.rotvec_to_matrix(pose6[3:]), pose6[:3])
        cv_from_tag = tf.make(tf.GLOBAL_FROM_CV.T) @ eye_from_tag
        xyz, quat = self._pose_parts(cv_from_tag)
        t = self.types
        point = t["geometry_msgs/msg/Point"](*xyz)
        return t[POSE_TYPE](
            header=self.header(ns),
            pose=t["geometry_msgs/msg/Pose"](position=point, orientation=quat),
        )
