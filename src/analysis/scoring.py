"""How well a model explains the held-out evidence, and when one model is better than another.

A :class:`Scored` model carries its held-out misfit per evidence channel: corners (in units of
the capture's corner noise), pose over all axes, detection, and each image statistic (in its
floor). The rules here decide when a model explains the evidence distinguishably better than
another (:func:`improves`), when two are equivalent, and which of several equivalent models is
the simplest (:func:`parsimonious`); :mod:`simgap.analysis.selection` searches with them.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simgap.analysis.evidence import compare_stat
from simgap.analysis.fitting import Fit, Items, corner_score, gap_score
from simgap.analysis.thresholds import (
    CORNER_UNIT_PX,
    DETECTION_UNIT,
    EQUIVALENT_PX,
    EQUIVALENT_REL,
    EQUIVALENT_UNITS,
    IMAGE_FLOORS,
    PAIRED_ALPHA,
    PAIRED_MIN_SHARE,
    RESIDUAL_CAP,
)
from simgap.core.axes import AXES
from simgap.core.robust import signed_rank_pvalue
from simgap.pose.image_stats import STAT_INDEX

#: Noise statistics: only stochastic effects change them (see :meth:`ModelSearch.evaluate`).
NOISE_STATS = [
    STAT_INDEX[s]
    for s in ("noise_ink_dn", "noise_paper_dn", "noise_ink_linear", "noise_paper_linear")
]
#: Image statistics with a floor, in the order of :attr:`Scored.image_after`.
SCORED_STATS = tuple(s for s, (_, floor) in IMAGE_FLOORS.items() if floor is not None)


@dataclass
class Scored:
    """A model (one or more fitted effects) and its held-out scores."""

    fits: list[tuple[Any, Fit]]
    before: float
    after: float
    before_axes: np.ndarray
    after_axes: np.ndarray
    before_all: float = float("nan")
    after_all: float = float("nan")
    corner_before: float = float("nan")
    corner_after: float = float("nan")
    prediction: np.ndarray | None = None
    #: the joint projection candidate, its fit and the held-out items it was applied to
    projection: tuple[Any, Fit, Items] | None = None
    #: held-out change of error (N, 6) of each simulation effect of the model (m, rad)
    simulation_deltas: dict[str, np.ndarray] = field(default_factory=dict)
    #: held-out image-evidence misfit per statistic before / after (floors, :func:`image_misfits`)
    image_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    image_after: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: held-out detection mismatch before / after (in units of DETECTION_UNIT)
    detection_before: float = 0.0
    detection_after: float = 0.0
    #: the scored items and the model's predictions for them: corners (N, 4, 2) px, image
    #: statistics (N, S), detection rate (N,)
    items: Items | None = None
    corner_unit_px: float = CORNER_UNIT_PX
    corners_pred: np.ndarray | None = None
    stats_pred: np.ndarray | None = None
    detected_pred: np.ndarray | None = None

    @property
    def channels_after(self) -> np.ndarray:
        """Held-out misfit per evidence channel, in its units.

        Corners (:attr:`corner_unit_px`), pose over all axes (:func:`gap_score`, noise or
        practical floor), detection (:data:`DETECTION_UNIT`), then each image statistic (floors).
        """
        return self._channels(self.corner_after, self.after_all, self.detection_after, True)

    @property
    def channels_before(self) -> np.ndarray:
        """Held-out misfit per evidence channel without the model's effects."""
        return self._channels(self.corner_before, self.before_all, self.detection_before, False)

    def _channels(self, corner_px: float, pose: float, detection: float, after: bool) -> np.ndarray:
        head = [finite_or_zero(corner_px) / self.corner_unit_px, finite_or_zero(pose), detection]
        return np.concatenate([head, self.image_after if after else self.image_before])

    @property
    def evidence_after(self) -> float:
        """Combined held-out misfit of all evidence (root sum of squared channels)."""
        return float(np.sqrt(np.sum(self.channels_after**2)))

    @property
    def evidence_before(self) -> float:
        """Combined held-out misfit without the model's effects."""
        return float(np.sqrt(np.sum(self.channels_before**2)))

    @property
    def evidence_reduction(self) -> float:
        """Relative fall of the combined held-out misfit."""
        b = self.evidence_before
        return 1.0 - self.evidence_after / b if b > 0 else 0.0

    @property
    def effects(self) -> list[str]:
        """Names of the model's effects."""
        return [fit.effect for _, fit in self.fits]

    @property
    def n_params(self) -> int:
        """Number of fitted parameters of the model."""
        return sum(cand.n_params for cand, _ in self.fits)

    @property
    def reduction(self) -> float:
        """Relative fall of the held-out gap."""
        return 1.0 - self.after / self.before if self.before > 0 else 0.0

    def record(self) -> dict[str, Any]:
        """JSON record of a single-effect model (ranking entry)."""
        cand, fit = self.fits[0]
        return {
            "effect": fit.effect,
            "params": fit.params,
            "heldout_gap_before": self.before,
            "heldout_gap_after": self.after,
            "reduction": self.reduction,
            "heldout_gap_all_axes_before": self.before_all,
            "heldout_gap_all_axes_after": self.after_all,
            "heldout_corner_gap_before_px": self.corner_before,
            "heldout_corner_gap_after_px": self.corner_after,
            "heldout_gap_before_per_axis": dict(
                zip(AXES, map(float, self.before_axes), strict=True)
            ),
            "heldout_gap_after_per_axis": dict(zip(AXES, map(float, self.after_axes), strict=True)),
            "heldout_image_misfit_before": root_sum_square(self.image_before),
            "heldout_image_misfit_after": root_sum_square(self.image_after),
            "heldout_detection_mismatch_before": self.detection_before,
            "heldout_detection_mismatch_after": self.detection_after,
            "heldout_evidence_before": self.evidence_before,
            "heldout_evidence_after": self.evidence_after,
            "n_params": cand.n_params,
            "fit_seconds": fit.seconds,
            "stage": cand.kind,
        }


def corner_unit(reproj_px: np.ndarray) -> float:
    """Unit of the corner channel (px) for a capture with these PnP reprojection errors.

    The RMS reprojection error of four corners fitted by a 6-parameter pose keeps 2 of 8 degrees
    of freedom, so a corner's noise is about twice the median reprojection error; a residual of
    real against simulated corners carries it from both sides (sqrt 2). The unit is that, or
    :data:`CORNER_UNIT_PX` (the detector's own bias on ideal renders) when larger: on a blurred
    or noisy capture corner residuals of a pixel are noise, not evidence.
    """
    r = np.asarray(reproj_px, float)
    r = r[np.isfinite(r)]
    noise = 2.0 * np.sqrt(2.0) * float(np.median(r)) if r.size else 0.0
    return max(CORNER_UNIT_PX, noise)


def finite_or_zero(v: float | np.ndarray) -> float | np.ndarray:
    """``v``, or 0 where it is not finite (a channel that measured nothing adds no misfit)."""
    out = np.where(np.isfinite(v), v, 0.0)
    return float(out) if out.ndim == 0 else out


def root_sum_square(v: np.ndarray) -> float:
    """Root sum of squares."""
    return float(np.sqrt(np.sum(np.square(v))))


def equivalent(a: float, b: float) -> bool:
    """Whether two held-out corner residuals (px) are too close to prefer one explanation."""
    return abs(a - b) <= max(EQUIVALENT_PX, EQUIVALENT_REL * min(a, b))


def equivalent_models(a: Scored, b: Scored) -> bool:
    """Whether two models explain every held-out evidence channel equally well.

    Per channel (corners, image statistics, detection) the misfits must be within
    :data:`EQUIVALENT_UNITS` channel units or :data:`EQUIVALENT_REL` of the smaller; for the
    corner channel this is :func:`equivalent` (0.05 px or 10 %).
    """
    return not (improves(a, b) or improves(b, a))


def distinguishably_lower(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether some channel misfit of ``a`` is lower than ``b``'s beyond the tolerance.

    Lower by more than :data:`EQUIVALENT_UNITS` channel units and :data:`EQUIVALENT_REL` of the
    smaller misfit (for the corner channel: 0.05 px and 10 %, the rule of issue 4).
    """
    return bool(np.any(b - a > np.maximum(EQUIVALENT_UNITS, EQUIVALENT_REL * np.minimum(a, b))))


def corner_residuals(scored: Scored, before: bool = False) -> np.ndarray | None:
    """Per held-out item, the mean squared corner distance real - predicted (px^2)."""
    h = scored.items
    if h is None or scored.corners_pred is None:
        return None
    pred = h.sim_corners if before else scored.corners_pred
    return np.sum((h.real_corners - pred) ** 2, axis=-1).mean(axis=-1)


def corners_clearly_lower(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Whether per-item corner residuals ``a`` are lower than ``b`` on the same items.

    A paired one-sided Wilcoxon signed-rank test at :data:`PAIRED_ALPHA`, with a median
    improvement of at least :data:`PAIRED_MIN_SHARE` of ``b``'s: a consistent improvement over
    the held-out items is evidence even when it is smaller than the fixed tolerance (a lens
    distortion moves the central tags' corners by tenths of a pixel).
    """
    if a is None or b is None or a.shape != b.shape:
        return False
    ok = np.isfinite(a) & np.isfinite(b)
    d = b[ok] - a[ok]
    if d.size < 6 or np.all(d == 0) or np.median(d) <= PAIRED_MIN_SHARE * np.median(b[ok]):
        return False
    return bool(signed_rank_pvalue(d, alternative="greater") < PAIRED_ALPHA)


def improves(a: Scored, b: Scored) -> bool:
    """Whether ``a`` explains some held-out evidence channel distinguishably better than ``b``.

    Beyond the tolerance on some channel (:func:`distinguishably_lower`), or consistently
    better corners item by item (:func:`corners_clearly_lower`).
    """
    return distinguishably_lower(a.channels_after, b.channels_after) or corners_clearly_lower(
        corner_residuals(a), corner_residuals(b)
    )


def as_good(a: Scored, b: Scored) -> bool:
    """``a`` explains the held-out evidence at least as well as ``b`` (or indistinguishably)."""
    return a.evidence_after <= b.evidence_after or equivalent_models(a, b)


def parsimonious(options: list[Scored]) -> Scored:
    """The model with the fewest parameters among those as good as the best.

    Ties within :func:`equivalent_models` are not evidence: a richer effect (a 6-DOF camera
    mount) reproduces a simpler one (a principal-point shift is a small camera rotation) and also
    soaks up unrelated nuisance, so it wins by a hair unless parsimony decides.
    """
    best = min(options, key=lambda s: s.evidence_after)
    tied = [s for s in options if as_good(s, best)]
    return min(tied, key=lambda s: (s.n_params, s.evidence_after))


def worsens_pose(
    scored: Scored, reference: Scored | None = None, tolerance: float = EQUIVALENT_REL
) -> bool:
    """Whether ``scored`` leaves a larger held-out pose gap than ``reference`` (or no effect).

    Larger by more than ``tolerance`` (relative; all axes, :attr:`Scored.after_all`). A geometric
    effect that does so is not an explanation of the gap, whatever it does to the corners: it is
    a look-alike absorbing an image effect outside the catalogue (motion blur shifts the corners
    the detector finds; a tag print scale follows them and moves every pose further away).
    """
    ref = scored.before_all if reference is None else reference.after_all
    return bool(scored.after_all > (1.0 + tolerance) * ref)


def improves_on_nothing(scored: Scored) -> bool:
    """Whether a model explains the held-out evidence distinguishably better than no effect."""
    return scored.evidence_after < scored.evidence_before and (
        distinguishably_lower(scored.channels_after, scored.channels_before)
        or corners_clearly_lower(corner_residuals(scored), corner_residuals(scored, before=True))
    )


def image_misfits(real: np.ndarray | None, pred: np.ndarray | None) -> np.ndarray:
    """Held-out image-evidence misfit per statistic (floors), capped at RESIDUAL_CAP.

    Per statistic of :data:`simgap.analysis.thresholds.IMAGE_FLOORS` that has a floor, the
    absolute median over tags of ``compare_stat(real, pred) / floor`` (a bias, robust to
    per-tag noise). Misfits beyond the cap mean "not modelled" and count as the cap, so that an
    effect is not credited or blamed for a difference nothing in the catalogue explains (a print
    whose ink is blacker than the simulation's, say). Zeros when nothing is measured.
    ``real`` and ``pred`` are (N, S), or (..., N, S) for a batch of item sets; the result is
    (K,) or (..., K) for the K scored statistics.
    """
    if real is None or pred is None:
        return np.zeros(len(SCORED_STATS))
    out = np.zeros(real.shape[:-2] + (len(SCORED_STATS),))
    for k, stat in enumerate(SCORED_STATS):
        floor = IMAGE_FLOORS[stat][1]
        i = STAT_INDEX[stat]
        d = compare_stat(stat, real[..., i], pred[..., i])
        with warnings.catch_warnings():  # a set without a measured tag scores 0
            warnings.simplefilter("ignore", RuntimeWarning)
            median = np.nanmedian(np.where(np.isfinite(d), d, np.nan), axis=-1)
        out[..., k] = np.where(
            np.isfinite(median), np.minimum(np.abs(median) / floor, RESIDUAL_CAP), 0.0
        )
    return out


def detection_groups(items: Items) -> list[np.ndarray]:
    """Group labels of items for comparing detection rates: by view and by distance.

    Views: the same tag at the same turntable angle (the carriage position varies). Distances:
    terciles of the carriage position ``p``. A tag near the detector's limit is lost or kept by
    a hair, so per-tag outcomes are compared as rates where the limit is crossed.
    """
    view = items.tag.astype(np.int64) * 100_000 + np.round(np.degrees(items.theta) * 10)
    cuts = np.quantile(items.p, [1 / 3, 2 / 3]) if len(items) else np.zeros(2)
    return [view.astype(np.int64), np.digitize(items.p, cuts)]


def detection_score(
    real: np.ndarray, pred: np.ndarray, groups: list[np.ndarray] | None = None
) -> float | np.ndarray:
    """Mismatch of detection rates, in units of :data:`DETECTION_UNIT`.

    Parameters
    ----------
    real, pred : ndarray (N,) or (..., N)
        Real and predicted detection rate of each item (share of repeats, 0-1); a leading batch
        of item sets (bootstrap resamples) gives one score per set.
    groups : list of ndarray (N,) or (..., N), optional
        Groupings of the items (:func:`detection_groups`). Per grouping, the item-weighted mean
        over groups of ``|real rate - predicted rate|``, then the mean over groupings: a model
        that loses as many tags as the capture where the capture loses them matches, even when
        threshold noise flips which ones. Without groupings, per item.
    """
    real, pred = np.asarray(real, float), np.asarray(pred, float)
    ok = np.isfinite(real) & np.isfinite(pred)
    diff = np.where(ok, real - pred, 0.0)
    if groups is None:
        with np.errstate(invalid="ignore"):
            score = np.abs(diff).sum(axis=-1) / ok.sum(axis=-1) / DETECTION_UNIT
    else:
        # per item set (row), the mean difference per group from bincounts over (row, group)
        rows = int(np.prod(real.shape[:-1], dtype=np.int64))
        row = np.repeat(np.arange(rows), real.shape[-1]).reshape(real.shape)
        mismatch = []
        for labels in groups:
            _, group = np.unique(labels, return_inverse=True)
            group = group.reshape(np.shape(labels))
            n_groups = int(group.max()) + 1 if group.size else 1
            cell = (row * n_groups + group)[ok]
            size = rows * n_groups
            total = np.bincount(cell, weights=diff[ok], minlength=size).reshape(rows, n_groups)
            count = np.bincount(cell, minlength=size).reshape(rows, n_groups)
            mean = total / np.maximum(count, 1)
            with np.errstate(invalid="ignore"):
                mismatch.append(np.sum(np.abs(mean) * count, axis=1) / count.sum(axis=1))
        score = np.mean(mismatch, axis=0).reshape(real.shape[:-1]) / DETECTION_UNIT
    score = np.where(np.isfinite(score), score, 0.0)  # nothing comparable: no mismatch
    return float(score) if score.ndim == 0 else score


def bootstrap_reductions(
    scored: Scored, axes: np.ndarray, resamples: int = 1000, seed: int = 0, level: float = 0.9
) -> dict[str, list[float]]:
    """Bootstrap intervals of a scored model's pose-gap and evidence reductions.

    The scored items are resampled with replacement ``resamples`` times; each time the pose gap
    (:func:`gap_score` on ``axes``) and the combined evidence misfit are recomputed before and
    after. Returns the central ``level`` interval of each relative reduction.
    """
    h = scored.items
    groups = detection_groups(h)
    i = np.random.default_rng(seed).integers(0, len(h), (resamples, len(h)))  # one set per row
    before = gap_score(h.real_err[i], h.sim_err[i], h.scale[i], axes)
    after = gap_score(h.real_err[i], scored.prediction[i], h.scale[i], axes)
    with np.errstate(invalid="ignore", divide="ignore"):
        pose = np.where(before > 0, 1.0 - after / before, 0.0)
    channels = []
    for pred_c, pred_e, pred_s, pred_d in (
        (h.sim_corners, h.sim_err, h.sim_stats, h.sim_detected),
        (scored.corners_pred, scored.prediction, scored.stats_pred, scored.detected_pred),
    ):
        corner = corner_score(h.real_corners[i], pred_c[i]) / scored.corner_unit_px
        pose_gap = gap_score(h.real_err[i], pred_e[i], h.scale[i])
        head = [finite_or_zero(corner), finite_or_zero(pose_gap)]
        if pred_s is not None and h.real_stats is not None:
            head.append(detection_score(h.real_detected[i], pred_d[i], [g[i] for g in groups]))
            head += list(np.moveaxis(image_misfits(h.real_stats[i], pred_s[i]), -1, 0))
        channels.append(np.sqrt(np.sum(np.square(head), axis=0)))
    with np.errstate(invalid="ignore", divide="ignore"):
        evidence = np.where(channels[0] > 0, 1.0 - channels[1] / channels[0], 0.0)
    q = [(1 - level) / 2 * 100, (1 + level) / 2 * 100]
    return {
        "pose_reduction": [float(v) for v in np.nanpercentile(pose, q)],
        "evidence_reduction": [float(v) for v in np.nanpercentile(evidence, q)],
    }
