"""Whether one set of per-item residuals is consistently lower than another (paired test).

The one test the diagnosis uses wherever a model's corners must be *consistently* better item by
item, even by less than the fixed corner tolerance: the model search
(:func:`simgap.analysis.search._scoring.corners_clearly_lower`) and the order of a nested fit
(:meth:`simgap.analysis.candidates.ProjectionCandidate.fit`); and the per-item residuals they
compare (:func:`item_residuals_px2`, :func:`item_centre_residuals_px2`).
"""

from __future__ import annotations

import numpy as np

from simgap.analysis.thresholds import PAIRED_MIN_SHARE, PAIRED_SIGNIFICANCE_LEVEL
from simgap.core.robust import signed_rank_pvalue

#: Fewest paired items the test is run on (fewer: never "clearly lower").
MIN_PAIRED_ITEMS = 6


def item_residuals_px2(difference: np.ndarray) -> np.ndarray:
    """Per item, the mean squared corner distance (px^2) of corner differences (N, 4, 2) (px)."""
    return np.sum(np.reshape(difference, (-1, 4, 2)) ** 2, axis=-1).mean(axis=-1)


def item_centre_residuals_px2(difference: np.ndarray) -> np.ndarray:
    """Per item, the squared tag-centre distance (px^2) of corner differences (N, 4, 2) (px).

    The centre is the mean of the four corners: an edge bias that moves every side of the tag
    in or out by the same amount (exposure, softness, ink spread, a print scale) leaves it, up
    to the perspective of an oblique tag (its near side drawn larger).
    """
    return np.sum(np.mean(np.reshape(difference, (-1, 4, 2)), axis=-2) ** 2, axis=-1)


def clearly_lower(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether per-item residuals ``a`` are consistently lower than ``b`` on the same items.

    A paired one-sided Wilcoxon signed-rank test at
    :data:`~simgap.analysis.thresholds.PAIRED_SIGNIFICANCE_LEVEL`, with a median improvement of at
    least :data:`~simgap.analysis.thresholds.PAIRED_MIN_SHARE` of ``b``'s median, over the items
    where both are finite (at least :data:`MIN_PAIRED_ITEMS`).

    Parameters
    ----------
    a, b : ndarray (N,)
        Residuals of the same items (any unit, the same for both; e.g. px^2).
    """
    if a.shape != b.shape:
        return False
    ok = np.isfinite(a) & np.isfinite(b)
    d = b[ok] - a[ok]
    if d.size < MIN_PAIRED_ITEMS or np.all(d == 0):
        return False
    if np.median(d) <= PAIRED_MIN_SHARE * np.median(b[ok]):
        return False
    return bool(signed_rank_pvalue(d, alternative="greater") < PAIRED_SIGNIFICANCE_LEVEL)
