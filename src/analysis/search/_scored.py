"""A scored model: its fitted effects and how well it explains the evidence of a set of items.

:class:`Scored` holds a model's misfit per evidence channel before (the simulation alone) and
after (with the model's effects) on the items it was scored on: the choose split while models are
searched, the measure split for the chosen one (:mod:`simgap.analysis.search._selection`). The
decision rules that compare scored models are :mod:`simgap.analysis.search._scoring`;
:func:`bootstrap_reductions` gives the intervals of a scored model's reductions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simgap.analysis.candidates import Candidate, Fit
from simgap.analysis.gap import (
    Items,
    Prediction,
    channel_misfits,
    detection_groups,
    evidence_channels,
    gap_score,
    median_abs_gap,
)
from simgap.analysis.thresholds import CORNER_UNIT_PX


@dataclass(kw_only=True)
class Scored:
    """A model (one or more fitted effects) and its misfit of the evidence of a set of items.

    Each misfit is given before (the simulation alone) and after (with the model's effects).

    Attributes
    ----------
    fits : list of (candidate, Fit)
        The model's candidates and their fits, in the model's order.
    pose_gap_before, pose_gap_after : float
        Pose gap on the axes with a significant gap (:func:`gap_score`, dimensionless).
    pose_gap_all_axes_before, pose_gap_all_axes_after : float
        Pose gap over all six axes (the pose channel).
    median_abs_gap_before, median_abs_gap_after : ndarray (6,)
        Median absolute pose gap per axis (m, rad; :func:`median_abs_gap`).
    corner_gap_before_px, corner_gap_after_px : float
        Robust RMS distance of the detected corners, real to predicted (px).
    image_misfit_before, image_misfit_after : ndarray (K,)
        Misfit per image statistic with a floor (floors, :func:`image_misfits`).
    detection_mismatch_before, detection_mismatch_after : float
        Mismatch of detection rates (in units of the detection channel).
    corner_unit_px : float
        Unit of the corner channel (px, :func:`simgap.analysis.gap.corner_unit`).
    items : Items or None
        The scored items.
    prediction : Prediction or None
        The model's predictions for them.
    projection : (candidate, Fit, Items) or None
        The joint projection candidate, its fit and the items it was applied to (with the
        simulation effects' corner changes).
    simulation_deltas : dict of str to ndarray (N, 6)
        Change of error (m, rad) of each simulation effect of the model.
    cross_fit_difference, cross_fit_difference_before : ndarray (M, 4, 2) or None
        Per item of the *other* split (the fit split while models are searched), the corners
        real - predicted (px) by the model with its projection effects refitted on the scored
        items (two-fold cross-fitting, :mod:`simgap.analysis.search._cross_fit`), and by the
        simulation alone; None where the model was not cross-fitted.
    """

    fits: list[tuple[Candidate, Fit]]
    pose_gap_before: float
    pose_gap_after: float
    median_abs_gap_before: np.ndarray
    median_abs_gap_after: np.ndarray
    pose_gap_all_axes_before: float = float("nan")
    pose_gap_all_axes_after: float = float("nan")
    corner_gap_before_px: float = float("nan")
    corner_gap_after_px: float = float("nan")
    image_misfit_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    image_misfit_after: np.ndarray = field(default_factory=lambda: np.zeros(0))
    detection_mismatch_before: float = 0.0
    detection_mismatch_after: float = 0.0
    corner_unit_px: float = CORNER_UNIT_PX
    items: Items | None = None
    prediction: Prediction | None = None
    projection: tuple[Any, Fit, Items] | None = None
    simulation_deltas: dict[str, np.ndarray] = field(default_factory=dict)
    cross_fit_difference: np.ndarray | None = None
    cross_fit_difference_before: np.ndarray | None = None

    @classmethod
    def measured(
        cls,
        fits: list[tuple[Candidate, Fit]],
        items: Items,
        prediction: Prediction,
        significant_axes: np.ndarray,
        corner_unit_px: float,
        **extra: Any,
    ) -> Scored:
        """Score ``prediction`` of the model ``fits`` on ``items`` against the simulation alone.

        ``significant_axes`` (bool (6,)) are the axes of the pose gap; ``extra`` fills
        :attr:`projection` and :attr:`simulation_deltas`.
        """
        groups = detection_groups(items)
        before = Prediction.simulated(items)
        b_corner, b_pose, b_detection, b_image = channel_misfits(items, before, groups)
        a_corner, a_pose, a_detection, a_image = channel_misfits(items, prediction, groups)
        real, scale = items.real_err, items.scale
        return cls(
            fits=fits,
            pose_gap_before=float(gap_score(real, before.error, scale, significant_axes)),
            pose_gap_after=float(gap_score(real, prediction.error, scale, significant_axes)),
            median_abs_gap_before=median_abs_gap(real, before.error),
            median_abs_gap_after=median_abs_gap(real, prediction.error),
            pose_gap_all_axes_before=float(b_pose),
            pose_gap_all_axes_after=float(a_pose),
            corner_gap_before_px=float(b_corner),
            corner_gap_after_px=float(a_corner),
            image_misfit_before=b_image,
            image_misfit_after=a_image,
            detection_mismatch_before=float(b_detection),
            detection_mismatch_after=float(a_detection),
            corner_unit_px=corner_unit_px,
            items=items,
            prediction=prediction,
            **extra,
        )

    def channels(self, after: bool = True) -> np.ndarray:
        """Misfit per evidence channel, in its unit (:func:`evidence_channels`).

        With the model's effects (``after``), or without them.
        """
        if after:
            corner, pose = self.corner_gap_after_px, self.pose_gap_all_axes_after
            detection, image = self.detection_mismatch_after, self.image_misfit_after
        else:
            corner, pose = self.corner_gap_before_px, self.pose_gap_all_axes_before
            detection, image = self.detection_mismatch_before, self.image_misfit_before
        return evidence_channels(corner, pose, detection, image, self.corner_unit_px)

    @property
    def channels_after(self) -> np.ndarray:
        """Misfit per evidence channel with the model's effects."""
        return self.channels(after=True)

    @property
    def channels_before(self) -> np.ndarray:
        """Misfit per evidence channel without the model's effects."""
        return self.channels(after=False)

    @property
    def evidence_after(self) -> float:
        """Combined misfit of all evidence (root sum of squared channels)."""
        return float(np.sqrt(np.sum(self.channels_after**2)))

    @property
    def evidence_before(self) -> float:
        """Combined misfit without the model's effects."""
        return float(np.sqrt(np.sum(self.channels_before**2)))

    @property
    def evidence_reduction(self) -> float:
        """Relative fall of the combined misfit."""
        b = self.evidence_before
        return 1.0 - self.evidence_after / b if b > 0 else 0.0

    @property
    def pose_gap_reduction(self) -> float:
        """Relative fall of the pose gap (significant axes)."""
        b = self.pose_gap_before
        return 1.0 - self.pose_gap_after / b if b > 0 else 0.0

    def items_and_prediction(self) -> tuple[Items, Prediction]:
        """The scored items and the model's predictions for them.

        Raises
        ------
        ValueError
            For a model scored without them (built by hand, not by :meth:`measured`).
        """
        if self.items is None or self.prediction is None:
            raise ValueError(f"model {self.effects} was scored without its items and predictions")
        return self.items, self.prediction

    @property
    def effects(self) -> list[str]:
        """Names of the model's effects."""
        return [fit.effect for _, fit in self.fits]

    @property
    def n_params(self) -> int:
        """Number of fitted parameters of the model."""
        return sum(cand.n_params for cand, _ in self.fits)


@dataclass(frozen=True)
class ReductionIntervals:
    """Bootstrap intervals of a scored model's reductions (relative falls, [low, high])."""

    pose_gap: tuple[float, float]
    evidence: tuple[float, float]


def bootstrap_reductions(
    scored: Scored,
    significant_axes: np.ndarray,
    resamples: int = 1000,
    seed: int = 0,
    level: float = 0.9,
) -> ReductionIntervals:
    """Bootstrap intervals of a scored model's pose-gap and evidence reductions.

    The scored items are resampled with replacement ``resamples`` times; each time the pose gap
    (:func:`gap_score` on ``significant_axes``) and the combined evidence misfit (the channels of
    :class:`Scored`, :func:`simgap.analysis.gap.channel_misfits`) are recomputed before and
    after. Returns the central ``level`` interval of each relative reduction.
    """
    h, after = scored.items_and_prediction()
    before = Prediction.simulated(h)
    groups = detection_groups(h)
    i = np.random.default_rng(seed).integers(0, len(h), (resamples, len(h)))  # one set per row
    pose_before = gap_score(h.real_err[i], before.error[i], h.scale[i], significant_axes)
    pose_after = gap_score(h.real_err[i], after.error[i], h.scale[i], significant_axes)
    with np.errstate(invalid="ignore", divide="ignore"):
        pose = np.where(pose_before > 0, 1.0 - pose_after / pose_before, 0.0)
    combined = [
        np.sqrt(np.sum(evidence_channels(*misfits, scored.corner_unit_px) ** 2, axis=-1))
        for misfits in (
            channel_misfits(h, before, groups, i),
            channel_misfits(h, after, groups, i),
        )
    ]
    with np.errstate(invalid="ignore", divide="ignore"):
        evidence = np.where(combined[0] > 0, 1.0 - combined[1] / combined[0], 0.0)
    q = [(1 - level) / 2 * 100, (1 + level) / 2 * 100]
    low_high = [
        (float(lo), float(hi)) for lo, hi in (np.nanpercentile(x, q) for x in (pose, evidence))
    ]
    return ReductionIntervals(pose_gap=low_high[0], evidence=low_high[1])
