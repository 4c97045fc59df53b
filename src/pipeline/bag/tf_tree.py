"""The fixture's transform tree in bags: frame names, the links of /tf_static and /tf."""

from __future__ import annotations

import numpy as np

from simgap.core import transforms as tf
from simgap.core.rig import Rig
from simgap.pipeline.bag.formats import OPTICAL_FRAME

#: Frame names of the rig's transform tree in exported bags (:mod:`simgap.core.rig`).
RAIL_FRAME, CARRIAGE_FRAME, EYEPOINT_FRAME, TURNTABLE_FRAME = (
    "rail", "carriage", "eyepoint", "turntable",
)  # fmt: skip


def tag_frame(tag: int) -> str:
    """The frame name of tag ``tag``'s marker frame (z out of the marker, y up, x right)."""
    return f"tag{tag}"


def static_transforms(rig: Rig) -> list[tuple[str, str, np.ndarray]]:
    """The links that never move, as ``(parent, child, parent_from_child)`` (4x4, m)."""
    links = [
        (CARRIAGE_FRAME, EYEPOINT_FRAME, rig.carriage_from_eyepoint()),
        (EYEPOINT_FRAME, OPTICAL_FRAME, tf.make(tf.GLOBAL_FROM_CV)),
    ]
    return links + [
        (TURNTABLE_FRAME, tag_frame(t), rig.turntable_from_tag(t)) for t in rig.tags.ids
    ]


def moving_transforms(rig: Rig, p: int, theta: float) -> list[tuple[str, str, np.ndarray]]:
    """The links set by the fixture configuration (pin hole ``p``, ``theta`` rad), as above."""
    return [
        (RAIL_FRAME, CARRIAGE_FRAME, rig.rail_from_carriage(p)),
        (RAIL_FRAME, TURNTABLE_FRAME, rig.rail_from_turntable(theta)),
    ]
