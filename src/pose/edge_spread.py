"""The edge-spread function of a blurred edge seen through square pixels, and its 10-90 % width.

The slanted-edge idea of ISO 12233: pixels at many sub-pixel distances from a straight edge sample
the edge-spread function finely. :mod:`simgap.pose.image_stats` measures every tag's edge width
with :func:`fit_esf_width`.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq, least_squares
from scipy.special import ndtr

#: Smallest PSF sigma fitted to an edge (px): sharper edges are a 1 px pixel ramp anyway.
ESF_MIN_SIGMA_PX = 0.02


def pixel_esf(d: np.ndarray, sigma: float) -> np.ndarray:
    """Edge-spread function of a Gaussian PSF (``sigma`` px) seen through square pixels.

    The value of a pixel whose centre is at signed distance ``d`` (px) from a unit step along a
    pixel axis: ``Phi(u / sigma)`` averaged over ``u`` in ``[d - 1/2, d + 1/2]``, in closed form
    ``sigma [G((d + 1/2) / sigma) - G((d - 1/2) / sigma)]`` with ``G(t) = t Phi(t) + phi(t)``.
    Modelling the pixel aperture makes the fitted PSF independent of where the edge falls within
    a pixel (the tag edges here are nearly aligned with the pixel grid, so the sub-pixel phases
    that a slanted edge would spread out are few).
    """
    return pixel_esf_terms(d, sigma)[0]


def pixel_esf_terms(d: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`pixel_esf` and its derivatives, which share Phi and phi at the pixel's two ends.

    Returns
    -------
    tuple of ndarray
        ``E``; ``dE/dd = Phi(a) - Phi(b)``; ``dE/dsigma = phi(a) - phi(b)``, with
        ``a, b = (d +- 1/2) / sigma`` (``G(t) = t Phi(t) + phi(t)`` is the antiderivative of
        the standard normal CDF).
    """
    a, b = (d + 0.5) / sigma, (d - 0.5) / sigma
    cdf_a, cdf_b = ndtr(a), ndtr(b)
    # exp(-t^2 / 2), the standard normal density times sqrt(2 pi)
    gauss_a, gauss_b = np.exp(-0.5 * a * a), np.exp(-0.5 * b * b)
    g_a = a * cdf_a + gauss_a / np.sqrt(2 * np.pi)
    g_b = b * cdf_b + gauss_b / np.sqrt(2 * np.pi)
    return sigma * (g_a - g_b), cdf_a - cdf_b, (gauss_a - gauss_b) / np.sqrt(2 * np.pi)


def esf_width_10_90(sigma: float) -> float:
    """10-90 % rise (px) of :func:`pixel_esf` for a PSF of ``sigma`` px (0.8 px when sharp)."""
    lo = brentq(lambda d: pixel_esf(np.array([d]), sigma)[0] - 0.1, -sigma * 8 - 1, 0.0)
    return -2.0 * lo


def fit_esf_width(
    d: np.ndarray, v: np.ndarray, ink: float, paper: float, min_samples: int
) -> float:
    """10-90 % width (px) of ``ink + (paper - ink) pixel_esf(d - d0, s)`` fitted to (d, v).

    ``d``: signed distances of the samples to the edge (px); ``v``: their linear values; ``ink``
    and ``paper``: the starting levels. NaN with fewer than ``min_samples`` samples, when the
    paper is not brighter than the ink, or when the fit fails.
    """
    if d.size < min_samples or not paper > ink:
        return float("nan")

    # the solver asks for the Jacobian where it last evaluated the model: compute both once
    last: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def terms(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in last:
            last.clear()
            last[key] = pixel_esf_terms(d - x[2], x[3])
        return last[key]

    def residual(x: np.ndarray) -> np.ndarray:
        lo, hi = x[0], x[1]
        return lo + (hi - lo) * terms(x)[0] - v

    def jacobian(x: np.ndarray) -> np.ndarray:
        # analytic (a third of the fit's time went to finite differences)
        lo, hi = x[0], x[1]
        esf, slope, spread = terms(x)
        return np.stack([1.0 - esf, esf, -(hi - lo) * slope, (hi - lo) * spread], axis=1)

    try:
        sol = least_squares(
            residual,
            np.array([ink, paper, 0.0, 0.5]),
            jac=jacobian,
            bounds=([-1.0, -1.0, -2.0, ESF_MIN_SIGMA_PX], [2.0, 2.0, 2.0, 5.0]),
            loss="soft_l1",
            f_scale=max(0.05 * (paper - ink), 1e-4),
        )
    except ValueError:
        return float("nan")
    return esf_width_10_90(float(sol.x[3])) if sol.success else float("nan")
