"""A smooth 2-D polynomial field fitted to one channel of a sticker's noisy pixels, and its tests.

The numerical core of :mod:`simgap.render.demodulate` (numpy and scipy; no renderer import):
:func:`fit_channel` fits the irradiance (a matte print: the ratio radiance / albedo) or the
diffuse and specular fields together (a coated print: the radiance, ``albedo x D + S``) by
weighted least squares, chooses the polynomial order and tests the smooth model.

The statistics, each stated once:

- **Noise model of the ratio** ``r = radiance / albedo``: one sample is ``a(x) E X``, the albedo
  where it lands times the irradiance times a light-sampling factor ``X`` of mean 1 and variance
  ``rho**2``, so the ratio's sample variance is ``E**2 (rho**2 (1 + g) + g)`` with
  ``g = var(a) / a**2`` over the footprint (given by the albedo pass,
  :class:`simgap.render.demodulate.StickerSamples`);
  ``rho**2`` is pooled over the sticker from the samples' own variances. Without the albedo
  variance, the variance of a pixel's mean ratio is pooled over pixels of similar albedo
  (:data:`ALBEDO_BINS` equal-width bins) as a relative variance per squared irradiance,
  ``var(r_i) = phi_bin * E_i**2``. Path-traced noise on a diffuse print scales with the
  radiance (the albedo multiplies every sample's incoming light), so
  ``phi`` is constant on pure ink or pure paper; pixels that straddle an ink/paper edge, whose
  samples land on both, get their own bins. Pooling keeps the weights independent of each pixel's
  own noisy (4-sample) variance, which would otherwise favour the pixels whose samples came out
  low and bias the fit down.
- **Order** (0 to :data:`MAX_ORDER`): the one of least AIC, ``chi2 + 2 k`` for ``k``
  coefficients (Akaike 1974, IEEE Trans. Automat. Contr. 19:716; with known variances
  ``-2 ln L = chi2 + const``).
- **Smooth model rejected** when either of two tests fails at the family-wise false-alarm
  probability per sticker (:data:`simgap.render.demodulate.FALSE_ALARM_PROBABILITY`; Bonferroni over
  channels and the two tests):
  the global lack-of-fit F test, the fit's reduced chi-square (residual mean square) against the
  pure-error mean square from the samples' own variance, ``F(n - k, sum(spp - 1))``
  (NIST/SEMATECH e-Handbook of Statistical Methods, section 4.4.4.3, "lack-of-fit test" with
  replicates: a pixel's samples are its replicates); and a local test for an edge or lobe that
  covers too few pixels to move the global chi-square: the mean normalized residual of square
  blocks of :data:`BLOCK_SIZES_PX` px, ``z = sum(r_i / sigma_i) / sqrt(m)`` (standard normal
  under the model; each term clipped to :data:`BLOCK_Z_CLIP`), against the two-sided normal
  quantile Bonferroni-corrected over all blocks (Dunn 1961, J. Am. Stat. Assoc. 56:52). A
  correlated sampler (stratified, as Mitsuba's ``multijitter``) makes the sample variance
  overstate the error of the mean, so both tests are conservative there: they flag less often,
  never more.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

__all__ = [
    "ALBEDO_BINS",
    "BLOCK_SIZES_PX",
    "BLOCK_Z_CLIP",
    "MAX_ORDER",
    "ChannelFit",
    "SmoothFit",
    "fit_channel",
    "n_coefficients",
]

#: Highest total degree of the irradiance polynomial (10 coefficients at degree 3).
MAX_ORDER = 3
#: Equal-width albedo bins over which the ratio's relative variance is pooled.
ALBEDO_BINS = 8
#: A bin with fewer fitted pixels than this takes the sticker's pooled value instead.
MIN_BIN_PIXELS = 20
#: Edge lengths of the square blocks of the local residual test (px).
BLOCK_SIZES_PX = (4, 8, 16)
#: The local test's normalized residuals are clipped to +-this (standard normal units) before
#: they are summed: under the model |z| > 4 has probability 6e-5, so the test's null
#: distribution is unchanged, but one firefly (a rare bright sample of a laminate's specular
#: lobe, tens of sigma) no longer fails a block alone. Measured on the baseline's tag under a
#: rough laminate at p 2, theta 0 (27 k px): unclipped, one such block (z 11.4 > 5.4) sent the
#: sticker to the path tracer (4.3 DN RMS from 256 spp); clipped, it was demodulated (1.2 DN).
#: An edge or lobe moves many pixels' residuals at once and is still found (tests); a glint
#: of a few pixels is left to the global test, whose chi-square it raises by their squares.
BLOCK_Z_CLIP = 4.0
#: Pixels whose fitted irradiance is below this share of the sticker's brightest carry no
#: measure of the relative noise and are left out of its pool: in a black shadow (a black sky)
#: the few samples of its penumbra over a fit near zero gave relative variances 1e4-1e9 times
#: the lit paper's, and the smooth model was accepted across the shadow in 6 of 24 renders
#: (docs/results/shadow_edge.md). Under any light with an ambient part the fit never drops so
#: low, and nothing is left out.
POOL_MIN_LEVEL = 0.01
#: Floor of the ratio's standard deviation relative to the irradiance: 10x the float32 machine
#: epsilon (1.19e-7) of a rendered radiance, so a noise-free render is not given infinite weight.
RELATIVE_NOISE_FLOOR = 1e-6


@dataclass(frozen=True)
class ChannelFit:
    """Diagnostics of one channel's irradiance fit (the chosen order).

    Attributes
    ----------
    order : int
        Total degree of the fitted polynomial (0 to :data:`MAX_ORDER`).
    reduced_chi2 : float
        Residual mean square over the pure-error mean square (the lack-of-fit F statistic).
    p_value : float
        Probability of an F at least this large under the smooth model.
    max_block_z : float
        Largest |mean normalized residual| of any block (standard normal units).
    block_threshold : float
        The Bonferroni-corrected limit ``max_block_z`` was tested against.
    n_pixels : int
        Pixels fitted (fully covered; of a matte print, albedo above
        :data:`simgap.render.demodulate.MIN_ALBEDO`).
    """

    order: int
    reduced_chi2: float
    p_value: float
    max_block_z: float
    block_threshold: float
    n_pixels: int


def _design(uv: NDArray[np.float64], centre: NDArray[np.float64], scale: float, order: int):
    """Monomials ``x**i y**j`` (i + j <= order) of coordinates normalised to about [-1, 1].

    Columns run by total degree, so the design of a lower order is the first
    ``(order + 1) (order + 2) / 2`` columns of a higher one's.
    """
    x, y = ((uv - centre) / scale).T
    return np.stack([x**i * y ** (d - i) for d in range(order + 1) for i in range(d + 1)], axis=1)


def n_coefficients(order: int) -> int:
    """Coefficients of a 2-D polynomial of total degree ``order``."""
    return (order + 1) * (order + 2) // 2


def _solve(normal: NDArray[np.float64], rhs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least-squares solution of normal equations (minimum-norm where they are singular).

    Singular: a sticker seen nearly edge-on, whose pixels on a line leave a coordinate
    undetermined.
    """
    coef, *_ = np.linalg.lstsq(normal, rhs, rcond=None)
    return coef


def _wls_orders(
    design: NDArray[np.float64],
    ratio: NDArray[np.float64],
    var: NDArray[np.float64],
    fields: int = 1,
) -> list[tuple[NDArray[np.float64], float]]:
    """Weighted least squares of every order at once: per order, coefficients and chi-square.

    Normal equations of the highest order's design (columns by degree, ``fields`` columns per
    monomial, coordinates in about [-1, 1], so at most 20 x 20); a lower order solves the
    leading block.
    """
    w = 1.0 / var
    weighted = design * w[:, None]
    normal = weighted.T @ design
    rhs = weighted.T @ ratio
    fits = []
    for order in range(MAX_ORDER + 1):
        k = fields * n_coefficients(order)
        coef = _solve(normal[:k, :k], rhs[:k])
        residual = design[:, :k] @ coef - ratio
        fits.append((coef, float(np.sum(w * residual * residual))))
    return fits


def _ratio_variance(
    rel_var: NDArray[np.float64],
    albedo: NDArray[np.float64],
    spread: NDArray[np.float64] | None,
    irradiance: NDArray[np.float64],
    spp: int,
) -> NDArray[np.float64]:
    """Variance of each pixel's mean ratio (module docstring: noise model).

    ``rel_var`` is each pixel's own estimate (its sample variance over ``spp a**2``), ``spread``
    the footprint's relative albedo variance ``g = var(a) / a**2`` (or None).
    """
    level = np.maximum(np.abs(irradiance), RELATIVE_NOISE_FLOOR * np.max(np.abs(irradiance)))
    q = rel_var / level**2
    # a relative noise is read only where the light is (a black shadow's few penumbral samples
    # over a near-zero fit would swamp the pool, and every test would then pass)
    lit = level >= POOL_MIN_LEVEL * np.max(level)
    if lit.sum() < MIN_BIN_PIXELS:
        lit = np.ones_like(lit)
    if spread is not None:
        # one sample is a(x) E X with X of mean 1, variance rho^2: the ratio's sample variance is
        # E^2 (rho^2 (1 + g) + g); rho^2 is pooled over the sticker
        # (from the pixels on one albedo when there are enough: a stratified sampler spreads
        # the samples of an edge pixel over ink and paper evenly, below this model's g)
        pure = (spread <= RELATIVE_NOISE_FLOOR) & lit
        pool = pure if pure.sum() >= MIN_BIN_PIXELS else lit
        rho2 = max(float(np.mean(spp * q[pool] - spread[pool]) / np.mean(1 + spread[pool])), 0.0)
        phi = (rho2 * (1.0 + spread) + spread) / spp
    else:
        edges = np.linspace(albedo.min(), albedo.max(), ALBEDO_BINS + 1)
        bins = np.clip(np.searchsorted(edges, albedo, side="right") - 1, 0, ALBEDO_BINS - 1)
        counts = np.bincount(bins[lit], minlength=ALBEDO_BINS)
        sums = np.bincount(bins[lit], weights=q[lit], minlength=ALBEDO_BINS)
        pooled = np.where(counts >= MIN_BIN_PIXELS, sums / np.maximum(counts, 1), np.mean(q[lit]))
        phi = pooled[bins]
    return np.maximum(phi, RELATIVE_NOISE_FLOOR**2) * level**2


def _block_z(uv: NDArray[np.float64], z: NDArray[np.float64]) -> tuple[float, int]:
    """Largest |mean normalized residual| over square blocks, and how many blocks were tested."""
    worst, tested = 0.0, 0
    origin = uv.min(axis=0)
    for size in BLOCK_SIZES_PX:
        cell = np.floor((uv - origin) / size).astype(np.int64)
        index = cell[:, 0] + cell[:, 1] * (int(cell[:, 0].max()) + 1)
        counts = np.bincount(index)
        sums = np.bincount(index, weights=z)
        full = counts >= max(size * size // 2, 4)
        if full.any():
            worst = max(worst, float(np.max(np.abs(sums[full]) / np.sqrt(counts[full]))))
            tested += int(full.sum())
    return worst, max(tested, 1)


@dataclass(frozen=True)
class SmoothFit:
    """One channel's fit: its fields at every pixel asked for, diagnostics, why it was rejected.

    ``specular_all`` is zero for a matte print; ``failed`` is "" when the smooth model holds.
    """

    irradiance_all: NDArray[np.float64]
    specular_all: NDArray[np.float64]
    diagnostics: ChannelFit
    failed: str


def fit_channel(
    uv: NDArray[np.float64],
    target: NDArray[np.float64],
    rel_var: NDArray[np.float64],
    albedo: NDArray[np.float64],
    spread: NDArray[np.float64] | None,
    uv_all: NDArray[np.float64],
    spp: int,
    alpha: float,
    coated: bool = False,
) -> SmoothFit:
    """Fit one channel's smooth fields over the fitted pixels ``uv``; evaluate at ``uv_all``.

    Matte: ``target`` is the ratio radiance / albedo, one field (the irradiance). Coated:
    ``target`` is the radiance, two fields: ``albedo x D + S`` (:mod:`simgap.render.demodulate`:
    coated prints).
    """
    centre = uv.mean(axis=0)
    scale = max(float(np.max(np.abs(uv - centre))), 1.0)
    monomials = _design(uv, centre, scale, MAX_ORDER)
    fields = 2 if coated else 1
    if coated:
        # per monomial: its diffuse column (x albedo) and its specular column
        design = np.stack([albedo[:, None] * monomials, monomials], axis=2).reshape(len(uv), -1)
    else:
        design = monomials
    # first pass: unweighted quadratic fields, only to scale the pooled variance
    quadratic = design[:, : fields * n_coefficients(2)]
    start = _solve(quadratic.T @ quadratic, quadratic.T @ target)
    fitted = quadratic @ start
    for _ in range(2):
        var = _ratio_variance(rel_var, albedo, spread, fitted, spp)
        fits = _wls_orders(design, target, var, fields)
        aic = [chi2 + 2 * len(coef) for coef, chi2 in fits]
        order = int(np.argmin(aic))
        coef, chi2 = fits[order]
        fitted = design[:, : len(coef)] @ coef
    n, k = len(target), len(coef)
    f_stat = chi2 / (n - k)
    p_value = float(stats.f.sf(f_stat, n - k, n * (spp - 1)))
    z = (target - fitted) / np.sqrt(var)
    worst, blocks = _block_z(uv, np.clip(z, -BLOCK_Z_CLIP, BLOCK_Z_CLIP))
    limit = float(stats.norm.isf(alpha / (2 * blocks)))
    failed = ""
    if p_value < alpha:
        failed = f"lack of fit: reduced chi-square {f_stat:.2f} (p = {p_value:.1e})"
    elif worst > limit:
        failed = f"local residual: block z {worst:.1f} > {limit:.1f}"
    diagnostics = ChannelFit(order, float(f_stat), p_value, worst, limit, n)
    at_all = _design(uv_all, centre, scale, order)
    specular = at_all @ coef[1::2] if coated else np.zeros(len(uv_all))
    return SmoothFit(at_all @ coef[::fields], specular, diagnostics, failed)
