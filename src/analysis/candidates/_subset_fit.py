"""A bounded robust least-squares fit of some entries of a parameter vector.

The glint's two models (:mod:`simgap.analysis.candidates._gloss`,
:mod:`simgap.analysis.candidates._glint_ratio`) fit nested subsets of one parameter vector from
several starts: exposure alone, then a light, then the laminate; the entries not fitted keep their
start values.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares


def fit_subset(
    residual: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    free: np.ndarray,
    lower: Sequence[float],
    upper: Sequence[float],
) -> np.ndarray:
    """Robust (soft L1) bounded least squares of ``residual`` over the ``free`` entries of ``x0``.

    Returns the whole parameter vector: ``x0`` with its free entries fitted.
    """

    def partial(v: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[free] = v
        return residual(x)

    solution = least_squares(partial, x0[free], bounds=(lower, upper), loss="soft_l1")
    x = x0.copy()
    x[free] = solution.x
    return x
