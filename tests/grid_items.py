"""Items over a grid of the rig's visible configurations, for candidate fits on real renders."""

from __future__ import annotations

import numpy as np

from simgap.analysis.gap import Items
from simgap.core.rig import Rig


def grid_items(rig: Rig, pins: tuple[int, ...], thetas_deg: tuple[float, ...]) -> Items:
    """Every visible (tag, pin hole, stop) of the grid, with zero errors and corners.

    The caller fills in the image statistics (and detections) the fit reads.
    """
    rows = [
        (tag, p, np.deg2rad(t))
        for tag in rig.tags.ids
        for p in pins
        for t in thetas_deg
        if rig.is_visible(tag, p, np.deg2rad(t))
    ]
    tag, p, theta = (np.array(c) for c in zip(*rows, strict=True))
    n = len(tag)
    return Items(
        tag=tag, p=p, theta=theta, real_err=np.zeros((n, 6)), sim_err=np.zeros((n, 6)),
        real_corners=np.zeros((n, 4, 2)), sim_corners=np.zeros((n, 4, 2)), scale=np.ones(6),
    )  # fmt: skip
