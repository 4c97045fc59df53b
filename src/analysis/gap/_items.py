"""The comparable items of a diagnosis: the real and simulated evidence a fit and a score read."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np


@dataclass
class Items:
    """Comparable (tag, p, theta) items: index arrays and the data a fit needs.

    Attributes
    ----------
    tag, p : ndarray of int (N,)
    theta : ndarray of float (N,), rad
    real_err, sim_err : ndarray (N, 6)
        Repeat-mean errors (m, rad).
    real_corners, sim_corners : ndarray (N, 4, 2)
        Repeat-mean detected corners (px).
    real_stats, sim_stats : ndarray (N, S)
        Repeat-median image statistics (:data:`simgap.pose.image_stats.STATS`).
    real_detected, sim_detected : ndarray (N,)
        Detection rate over repeats.
    scale : ndarray (N, 6)
        Per-item, per-axis normalisation of residuals (m, rad): noise or practical floor, the
        larger. A per-axis (6,) scale is broadcast to every item.
    """

    tag: np.ndarray
    p: np.ndarray
    theta: np.ndarray
    real_err: np.ndarray
    sim_err: np.ndarray
    real_corners: np.ndarray
    sim_corners: np.ndarray
    scale: np.ndarray
    real_stats: np.ndarray | None = None
    sim_stats: np.ndarray | None = None
    real_detected: np.ndarray | None = None
    sim_detected: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.scale = np.broadcast_to(np.asarray(self.scale, float), (len(self.tag), 6))

    def __len__(self) -> int:
        return len(self.tag)

    def subset(self, index: np.ndarray) -> Items:
        """Items at ``index``."""
        fields: dict[str, Any] = {
            f.name: None if getattr(self, f.name) is None else getattr(self, f.name)[index]
            for f in dataclasses.fields(self)
        }
        return Items(**fields)

    def required(
        self, name: Literal["real_stats", "sim_stats", "real_detected", "sim_detected"]
    ) -> np.ndarray:
        """The image evidence ``name`` (statistics or detection rates), which a fit needs.

        Raises
        ------
        ValueError
            Where the items carry none (the capture or the simulation measured no images).
        """
        value: np.ndarray | None = getattr(self, name)
        if value is None:
            raise ValueError(f"the items carry no {name}: a fit on image evidence needs them")
        return value
