"""Which further poses would tell two look-alike models apart.

Two models the capture's poses cannot tell apart (a principal point and a camera mount, a focal
length and a print scale or a tag offset, seen from a handful of frontal poses) still predict
different corners elsewhere on the fixture's grid. Both fitted models are applied to every
visible tag at every pin hole and turntable stop with the exact projection
(:meth:`simgap.analysis.candidates.ProjectionCandidate.corner_shift`: no render needed), and the
poses where their predicted corners differ most are the ones to add to the capture. A model without
geometry moves no corner there.
"""

from __future__ import annotations

import numpy as np

from simgap.analysis.gap import Items
from simgap.analysis.search import Scored
from simgap.core.distance import camera_to_tag_distance
from simgap.core.rig import Rig
from simgap.diagnosis.result import TellingPose
from simgap.effects.state import VariantState

#: Poses the report names per look-alike.
TELLING_POSES = 3


def grid_items(rig: Rig) -> Items:
    """Every visible tag at every pin hole and turntable stop of the rig's grid, as items."""
    rows = [
        (tag, p, theta)
        for p in rig.grid.p
        for theta in rig.grid.theta
        for tag in rig.tags.ids
        if rig.is_visible(tag, p, float(theta))
    ]
    tag, p, theta = (np.array(c) for c in zip(*rows, strict=True))
    n = len(rows)
    return Items(
        tag=tag.astype(int),
        p=p.astype(int),
        theta=theta.astype(float),
        real_err=np.zeros((n, 6)),
        sim_err=np.zeros((n, 6)),
        real_corners=np.zeros((n, 4, 2)),
        sim_corners=np.zeros((n, 4, 2)),
        scale=np.ones(6),
    )


def predicted_shift(rig: Rig, base: VariantState, model: Scored, items: Items) -> np.ndarray:
    """The corners' change (N, 4, 2) that ``model``'s geometry predicts at ``items`` (px)."""
    if model.projection is None:
        return np.zeros((len(items), 4, 2))
    candidate, fit, _ = model.projection
    return candidate.corner_shift(rig, base, np.asarray(fit.extra["x"], float), items)


def corner_difference_px(
    rig: Rig, base: VariantState, a: Scored, b: Scored, items: Items
) -> np.ndarray:
    """Per item, the RMS distance (px) between the corners the two models predict."""
    diff = predicted_shift(rig, base, a, items) - predicted_shift(rig, base, b, items)
    return np.sqrt(np.mean(np.sum(diff**2, axis=2), axis=1))


def telling_poses(
    rig: Rig, base: VariantState, a: Scored, b: Scored, limit: int = TELLING_POSES
) -> list[TellingPose]:
    """The grid poses where the two models' predicted corners differ most, most first.

    One entry per pose (pin hole, stop): its tag that differs most. Empty where neither model
    has geometry.
    """
    if a.projection is None and b.projection is None:
        return []
    items = grid_items(rig)
    diff = corner_difference_px(rig, base, a, b, items)
    poses = rig.eyepoints_from_tags(items.tag, items.p, items.theta)
    distance = camera_to_tag_distance(poses[:, :3, 3])
    out: list[TellingPose] = []
    seen: set[tuple[int, float]] = set()
    for i in np.argsort(-diff, kind="stable"):
        key = (int(items.p[i]), float(items.theta[i]))
        if key in seen:
            continue
        seen.add(key)
        out.append(
            TellingPose(
                p=key[0],
                theta_deg=round(float(np.rad2deg(key[1])), 6),
                tag=int(items.tag[i]),
                distance_m=float(distance[i]),
                corner_difference_px=float(diff[i]),
            )
        )
        if len(out) == limit:
            break
    return out


__all__ = ["TELLING_POSES", "corner_difference_px", "grid_items", "telling_poses"]
