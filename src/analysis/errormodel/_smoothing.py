"""The error model's smoother: Gaussian-kernel robust local-linear regression (LOESS).

Covariates are (distance m, obliquity rad) pairs; bandwidths ``h`` are in the same units.
"""

from __future__ import annotations

import numpy as np
from scipy import stats


def kernel(xq: np.ndarray, x: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian kernel weights (Q, N) and scaled offsets (Q, N, 2) of data ``x`` from ``xq``."""
    u = (x[None, :, :] - xq[:, None, :]) / h
    return np.exp(-0.5 * np.sum(u**2, axis=-1)), u


def local_linear_weights(xq: np.ndarray, x: np.ndarray, w: np.ndarray, h: np.ndarray):
    """Rows ``l`` (Q, N) of the local-linear smoother: the fit at ``xq`` is ``l @ y``."""
    k, u = kernel(xq, x, h)
    kw = k * w[None, :]
    design = np.concatenate([np.ones(u.shape[:2] + (1,)), u], axis=-1)  # Q, N, 3
    a = np.einsum("qn,qni,qnj->qij", kw, design, design)
    a += np.diag([0.0, 1e-3, 1e-3]) * np.maximum(kw.sum(axis=1), 1e-12)[:, None, None]
    b = np.transpose(design * kw[..., None], (0, 2, 1))  # Q, 3, N
    return np.linalg.solve(a, b)[:, 0, :]


def weighted_median(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted median of ``values`` (N,) under each row of ``weights`` (Q, N)."""
    order = np.argsort(values)
    cum = np.cumsum(weights[:, order], axis=1)
    idx = np.argmax(cum >= 0.5 * cum[:, -1:], axis=1)
    return values[order][idx]


def robust_local_linear(x: np.ndarray, y: np.ndarray, h: np.ndarray, iterations: int):
    """Robustness weights (N,) and leave-one-out residuals (N,) of a robust LOESS fit."""
    w = np.ones(len(y))
    for _ in range(iterations + 1):
        l_data = local_linear_weights(x, x, w, h)
        resid = y - l_data @ y
        scale = np.median(np.abs(resid)) or 1e-12
        u = resid / (6.0 * scale)
        w_new = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
        if np.array_equal(w_new, w):
            break
        w = w_new
    leverage = np.clip(np.diag(l_data), 0.0, 0.95)
    return w, resid / (1.0 - leverage)


def rank_correlation(z: np.ndarray) -> np.ndarray:
    """Pearson-equivalent correlation (6, 6) from Spearman's rho, positive semi-definite."""
    rho = stats.spearmanr(z).statistic
    r = 2 * np.sin(np.pi * np.atleast_2d(rho) / 6)
    vals, vecs = np.linalg.eigh(r)
    r = vecs @ np.diag(np.clip(vals, 1e-6, None)) @ vecs.T
    d = np.sqrt(np.diag(r))
    return r / np.outer(d, d)
