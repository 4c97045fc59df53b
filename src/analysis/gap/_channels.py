"""The evidence channels: how far a prediction is from the real evidence, each in its unit.

A model's predictions for a set of items (:class:`Prediction`: pose errors, detected corners,
image statistics, detection rates) are compared with the real evidence channel by channel
(:func:`channel_misfits`): detected corners (px, in units of the capture's corner noise,
:func:`corner_unit`), the pose over all axes (:func:`simgap.analysis.gap.gap_score`: in units
of each item's noise or the practical floor), detection (:func:`detection_score`, in units of
:func:`detection_unit`) and each image statistic with a floor
(:func:`image_misfits`, in floors, and the paper level's spread over the tags,
:func:`level_spread`). :func:`evidence_channels` puts them in one vector; its root
sum of squares is the combined misfit a model is ranked on. Every function here also takes a
leading batch of item sets (bootstrap resamples), which gives one value per set.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from simgap.analysis.gap._evidence import compare_stat
from simgap.analysis.gap._gap_size import corner_score, gap_score
from simgap.analysis.gap._items import Items
from simgap.analysis.thresholds import CORNER_UNIT_PX, DETECTION_UNIT, IMAGE_FLOORS, RESIDUAL_CAP
from simgap.pose.image_stats import STAT_INDEX

#: Noise statistics: on a path-traced simulation only stochastic effects change them (see
#: :meth:`simgap.analysis.candidates.SimulationChain.changes`).
NOISE_STATS = [
    STAT_INDEX[s]
    for s in ("noise_ink_dn", "noise_paper_dn", "noise_ink_linear", "noise_paper_linear")
]
#: Image statistics with a floor: the image channels, in this order.
SCORED_STATS = tuple(s for s, (_, floor) in IMAGE_FLOORS.items() if floor is not None)
#: The statistic whose spread over the tags is the last image channel (:func:`level_spread`).
SPREAD_STAT = "paper_linear"
#: Every image channel by name, in the order of :func:`image_misfits`: the statistics with a
#: floor, then the paper level's spread over the tags.
IMAGE_CHANNELS = (*SCORED_STATS, "paper_spread")


@dataclass(frozen=True)
class Prediction:
    """What a model predicts for a set of N items (the simulation with its effects).

    Attributes
    ----------
    error : ndarray (N, 6)
        Pose errors (m, rad).
    corners : ndarray (N, 4, 2)
        Detected corners (px).
    stats : ndarray (N, S) or None
        Image statistics (:data:`simgap.pose.image_stats.STATS`); None where the items carry no
        image evidence.
    detected : ndarray (N,) or None
        Detection rate (0-1); None with ``stats``.
    """

    error: np.ndarray
    corners: np.ndarray
    stats: np.ndarray | None = None
    detected: np.ndarray | None = None

    @classmethod
    def simulated(cls, items: Items) -> Prediction:
        """The simulation without any effect: the items' own simulated evidence."""
        return cls(items.sim_err, items.sim_corners, items.sim_stats, items.sim_detected)


def corner_unit(reproj_px: np.ndarray) -> float:
    """Unit of the corner channel (px) for a capture with these PnP reprojection errors.

    The RMS reprojection error of four corners fitted by a 6-parameter pose keeps 2 of 8 degrees
    of freedom, so a corner's noise is about twice the median reprojection error
    (:func:`frame_corner_noise`); a residual of
    real against simulated corners carries it from both sides (sqrt 2). The unit is that, or
    :data:`~simgap.analysis.thresholds.CORNER_UNIT_PX` (the detector's own bias on ideal
    renders) when larger: on a blurred or noisy capture corner residuals of a pixel are noise,
    not evidence.
    """
    return max(CORNER_UNIT_PX, np.sqrt(2.0) * frame_corner_noise(reproj_px))


def frame_corner_noise(reproj_px: np.ndarray) -> float:
    """A frame's corner noise from its PnP reprojection errors.

    The RMS reprojection error of four corners fitted by a 6-parameter pose keeps 2 of 8 degrees
    of freedom: its square is a quarter of the corner noise's variance, so the noise is twice the
    median reprojection error.

    Parameters
    ----------
    reproj_px : ndarray
        RMS reprojection errors of the detections, any shape (px); NaN where none.

    Returns
    -------
    float
        Standard deviation of one corner coordinate (px); 0 where no error is finite.
    """
    r = np.asarray(reproj_px, float)
    r = r[np.isfinite(r)]
    return 2.0 * float(np.median(r)) if r.size else 0.0


def finite_or_zero(v: float | np.ndarray) -> float | np.ndarray:
    """``v``, or 0 where it is not finite (a channel that measured nothing adds no misfit)."""
    out = np.where(np.isfinite(v), v, 0.0)
    return float(out) if out.ndim == 0 else out


def root_sum_square(v: np.ndarray) -> float:
    """Root sum of squares."""
    return float(np.sqrt(np.sum(np.square(v))))


def evidence_channels(
    corner_px: float | np.ndarray,
    pose_all_axes: float | np.ndarray,
    detection: float | np.ndarray,
    image: np.ndarray,
    corner_unit_px: float,
) -> np.ndarray:
    """The misfit per evidence channel, each in its unit: ``(..., 3 + K)``.

    Corners over ``corner_unit_px``, the pose over all axes, detection, then the ``K`` image
    statistics (:data:`SCORED_STATS`); a channel that measured nothing (NaN) counts 0. The
    detection channel is capped at :data:`~simgap.analysis.thresholds.RESIDUAL_CAP` units, as
    each image statistic is: on a choose split of 8-12 tags one tag is 2-2.5 units, and a fitted
    blur or defocus that lost one or two tags the other camera's detector kept (its own tone
    curve and pixel filter) scored 5 units and was outweighed by a print scale that explained
    no image evidence (measured on blind captures: docs/results/design_evidence.md#channels).
    """
    detection = np.minimum(detection, RESIDUAL_CAP)
    parts = [finite_or_zero(corner_px) / corner_unit_px, finite_or_zero(pose_all_axes), detection]
    head = np.stack(np.broadcast_arrays(*parts), axis=-1)
    return np.concatenate([head, np.broadcast_to(image, head.shape[:-1] + image.shape[-1:])], -1)


def channel_misfits(
    items: Items, pred: Prediction, groups: list[np.ndarray], index: np.ndarray | None = None
) -> tuple[float | np.ndarray, float | np.ndarray, float | np.ndarray, np.ndarray]:
    """Misfit of ``pred`` to the real evidence of ``items``, per channel (raw units).

    Parameters
    ----------
    items : Items
        The items, with their real evidence.
    pred : Prediction
        Predictions for the same items.
    groups : list of ndarray (N,)
        The items' detection groups (:func:`detection_groups`).
    index : ndarray of int (R, N), optional
        Item sets to score (bootstrap resamples), one per row; default: the items once.

    Returns
    -------
    tuple
        Corner residual (px, :func:`simgap.analysis.gap._gap_size.corner_score`), pose gap over all
        axes (:func:`simgap.analysis.gap.gap_score`), detection mismatch
        (:func:`detection_score`) and image misfits (:func:`image_misfits`, (K,) or (R, K)).
        Without image evidence (``pred.stats`` or the items' real statistics None) detection
        and image misfits are 0.
    """

    def at(a: np.ndarray) -> np.ndarray:
        return a if index is None else a[index]

    corner = corner_score(at(items.real_corners), at(pred.corners))
    pose = gap_score(at(items.real_err), at(pred.error), at(items.scale))
    if pred.stats is None or items.real_stats is None:
        shape = np.shape(pose)
        return corner, pose, np.zeros(shape)[()], np.zeros(shape + (len(SCORED_STATS),))
    if items.real_detected is None or pred.detected is None:
        raise ValueError("image statistics without detection rates: both are given or neither")
    detection = detection_score(at(items.real_detected), at(pred.detected), [at(g) for g in groups])
    return corner, pose, detection, image_misfits(at(items.real_stats), at(pred.stats))




def image_misfits(real: np.ndarray | None, pred: np.ndarray | None) -> np.ndarray:
    """Image-evidence misfit per image channel of the scored items (floors), capped.

    Per statistic of :data:`simgap.analysis.thresholds.IMAGE_FLOORS` that has a floor, the
    absolute median over tags of ``compare_stat(real, pred) / floor`` (a bias, robust to
    per-tag noise); then the paper level's spread over the tags (:func:`level_spread`). Misfits
    beyond the cap mean "not modelled" and count as the cap, so that an effect is not credited
    or blamed for a difference nothing in the catalogue explains (a print whose ink is blacker
    than the simulation's, say). Zeros when nothing is measured. ``real`` and ``pred`` are
    (N, S), or (..., N, S) for a batch of item sets; the result is (K,) or (..., K) for the K
    channels of :data:`IMAGE_CHANNELS`.
    """
    if real is None or pred is None:
        return np.zeros(len(IMAGE_CHANNELS))
    out = np.zeros(real.shape[:-2] + (len(IMAGE_CHANNELS),))
    for k, stat in enumerate(SCORED_STATS):
        median = _tag_median(_tag_misfit(stat, real, pred))
        out[..., k] = np.where(
            np.isfinite(median), np.minimum(np.abs(median), RESIDUAL_CAP), 0.0
        )
    out[..., -1] = level_spread(real, pred)
    return out


def _tag_misfit(stat: str, real: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Per tag, ``compare_stat(real, pred)`` of ``stat`` in its floors; NaN where unmeasured."""
    i = STAT_INDEX[stat]
    d = compare_stat(stat, real[..., i], pred[..., i]) / IMAGE_FLOORS[stat][1]
    return np.where(np.isfinite(d), d, np.nan)


def _tag_median(d: np.ndarray) -> np.ndarray:
    """Median over the tags (last axis) of finite values; NaN for a set with none."""
    with warnings.catch_warnings():  # a set without a measured tag
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(d, axis=-1)


def level_spread(real: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Spread over the tags of the paper level's misfit (floors), capped; 0 where unmeasured.

    The RMS over tags of each tag's paper misfit (:data:`SPREAD_STAT`, ``compare_stat / floor``)
    less the median one, each capped at :data:`~simgap.analysis.thresholds.RESIDUAL_CAP`. The
    median channel reads what moves every tag's paper alike (an exposure); this one what moves
    tags differently by the way they face: a light the simulation lacks (a sun on some faces),
    whose median change over the tags can stay under its floor. One gain leaves it as it is,
    and every effect that does not light tags unevenly changes it little. ``real`` and ``pred``
    are (..., N, S); the result has their leading shape.
    """
    d = _tag_misfit(SPREAD_STAT, real, pred)
    deviation = np.minimum(np.abs(d - _tag_median(d)[..., None]), RESIDUAL_CAP)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rms = np.sqrt(np.nanmean(deviation**2, axis=-1))
    return np.where(np.isfinite(rms), rms, 0.0)


def detection_groups(items: Items) -> list[np.ndarray]:
    """Group labels of items for comparing detection rates: by view and by distance.

    Views: the same tag at the same turntable angle (the carriage position varies). Distances:
    terciles of the carriage position ``p``. A tag near the detector's limit is lost or kept by
    a hair, so per-tag outcomes are compared as rates where the limit is crossed.
    """
    view = items.tag.astype(np.int64) * 100_000 + np.round(np.degrees(items.theta) * 10)
    cuts = np.quantile(items.p, [1 / 3, 2 / 3]) if len(items) else np.zeros(2)
    return [view.astype(np.int64), np.digitize(items.p, cuts)]


def detection_unit(n_items: int | np.ndarray) -> float | np.ndarray:
    """Unit of the detection channel for ``n_items`` compared items (share of tags).

    :data:`~simgap.analysis.thresholds.DETECTION_UNIT` (5 %), or one item's share where the
    items are fewer than twenty: the smallest rate difference the items can show. A tag near the
    detector's limit is kept or lost by a hair (one render of it, one frame), and on a choose
    split of 7 items one such tag lost by a correct JPEG model was 2.9 units, more than
    its blockiness explained, and the JPEG went unnamed. The unit follows the items compared:
    two splits of 7 and 8 items, or bootstrap resamples with missing detections, are each in
    their own; so is the laminate's choice of intensity
    (:meth:`simgap.analysis.candidates.GlossCandidate.intensity`), where detections weigh up to 3x
    less on fewer than twenty items (no fitted magnitude of the development captures changed;
    docs/results/design_evidence.md#channels).
    """
    return np.maximum(DETECTION_UNIT, 1.0 / np.maximum(n_items, 1))


def detection_score(
    real: np.ndarray, pred: np.ndarray, groups: list[np.ndarray] | None = None
) -> float | np.ndarray:
    """Mismatch of detection rates, in units of the detection channel (:func:`detection_unit`).

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
    unit = detection_unit(ok.sum(axis=-1))
    if groups is None:
        with np.errstate(invalid="ignore"):
            score = np.abs(diff).sum(axis=-1) / ok.sum(axis=-1) / unit
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
        score = np.mean(mismatch, axis=0).reshape(real.shape[:-1]) / unit
    score = np.where(np.isfinite(score), score, 0.0)  # nothing comparable: no mismatch
    return float(score) if score.ndim == 0 else score
