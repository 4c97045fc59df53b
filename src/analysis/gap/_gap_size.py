"""Robust sizes of a sim-to-real gap: the pose gap, the corner residual, the gap per axis."""

from __future__ import annotations

import warnings

import numpy as np


def gap_score(
    real: np.ndarray, pred: np.ndarray, scale: np.ndarray, axes: np.ndarray | None = None
) -> float | np.ndarray:
    """Robust size of the normalised gap ``(real - pred) / scale`` (dimensionless).

    Per axis the median of the squared normalised residuals (rotation estimates of a square marker
    have heavy tails, from the planar pose ambiguity, that no effect explains), averaged over
    ``axes`` (a boolean mask of the six axes; default all) and square-rooted. Pure noise scores
    about 0.67 (the median of |N(0, 1)|). ``real`` and ``pred`` are (N, 6), or (..., N, 6) for
    a batch of item sets (bootstrap resamples), which gives one score per set; NaN where
    nothing is measured.
    """
    r2 = ((real - pred) / scale) ** 2
    with warnings.catch_warnings():  # an axis or a set without a measured item is NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        per_axis = np.nanmedian(r2, axis=-2)
        if axes is not None and np.any(axes):
            per_axis = per_axis[..., np.asarray(axes, bool)]
        score = np.sqrt(np.nanmean(per_axis, axis=-1))
    return float(score) if np.ndim(score) == 0 else score


def corner_score(real: np.ndarray, pred: np.ndarray) -> float | np.ndarray:
    """Robust RMS distance between real and predicted corners (px).

    The square root of the median over items of the mean squared corner distance. ``real`` and
    ``pred`` are (N, 4, 2), or (..., N, 4, 2) for a batch of item sets (one score per set).
    """
    d2 = np.sum((real - pred) ** 2, axis=-1).mean(axis=-1)
    with warnings.catch_warnings():  # a set without a detected item is NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        score = np.sqrt(np.nanmedian(d2, axis=-1))
    return float(score) if np.ndim(score) == 0 else score


def median_abs_gap(real: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Robust gap size per axis: the median over items of ``|real - pred|``.

    Parameters
    ----------
    real, pred : ndarray (N, 6)
        Real and predicted errors (m, rad); NaN items are ignored.

    Returns
    -------
    ndarray (6,)
        Median absolute gap per axis (m for tx, ty, tz; rad for rx, ry, rz). Not an RMS.
    """
    return np.nanmedian(np.abs(real - pred), axis=0)
