"""Albedo demodulation of one flat printed sticker: a converged render from few samples (issue 28).

On a flat diffuse print the rendered radiance of a pixel is (the print's albedo averaged over the
pixel's footprint) x (the irradiance at the pixel), and the irradiance varies smoothly across a
2 cm sticker. Dividing the noisy radiance by a nearly free albedo pass (primary rays only),
fitting a smooth 2-D polynomial irradiance over the sticker and multiplying back removes most of
the Monte Carlo noise. Where the smooth model does not hold (a shadow or highlight edge crossing
the sticker, a specular lobe), the residual against the samples' own variance reveals it and the
path-traced pixels are kept instead (:attr:`Treatment.FALLBACK`: spend more samples there).

**Coated prints.** Under a dielectric laminate (Mitsuba's ``plastic`` and ``roughplastic``, whose
diffuse lobe is linear in the print's albedo: ``nonlinear`` false, the default) a pixel's radiance
is ``a D + S``: the albedo times a smooth diffuse field plus the coating's specular reflection,
which does not see the print. Both fields are fitted together on the radiance itself (the ink and
paper cells interleave across the sticker, so they are told apart) and the product is
``footprint albedo x D + S``. A glint of a smooth coating, or of a light small in the coating's
lobe, is not smooth: the tests below reject it and the sticker is path traced with more samples.

This module is the numerical core only (numpy and scipy; no renderer import). Its input per
sticker is :class:`StickerSamples`; :func:`demodulate` returns a :class:`DemodulationResult`
recording the treatment used and the fit's diagnostics.

The statistics, each stated once:

- **Noise model of the ratio** ``r = radiance / albedo``: one sample is ``a(x) E X``, the albedo
  where it lands times the irradiance times a light-sampling factor ``X`` of mean 1 and variance
  ``rho**2``, so the ratio's sample variance is ``E**2 (rho**2 (1 + g) + g)`` with
  ``g = var(a) / a**2`` over the footprint (given by the albedo pass, :class:`StickerSamples`);
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
  probability :data:`ALPHA` per sticker (Bonferroni over channels and the two tests):
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

import enum
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import stats

__all__ = [
    "ALPHA",
    "ALBEDO_BINS",
    "BLOCK_SIZES_PX",
    "BLOCK_Z_CLIP",
    "MAX_ORDER",
    "ChannelFit",
    "DemodulationResult",
    "StickerSamples",
    "Treatment",
    "demodulate",
]

#: Family-wise false-alarm probability per sticker of the smooth-model tests (dimensionless).
ALPHA = 1e-3
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
#: A pixel counts as fully on the sticker at this coverage or above (dimensionless).
FULL_COVERAGE = 1.0 - 1e-6
#: Pixels of lower albedo are left out of the fit (their ratio is undefined; dimensionless).
MIN_ALBEDO = 1e-3
#: Floor of the ratio's standard deviation relative to the irradiance: 10x the float32 machine
#: epsilon (1.19e-7) of a rendered radiance, so a noise-free render is not given infinite weight.
RELATIVE_NOISE_FLOOR = 1e-6
#: Fewest fully covered pixels a fit needs (dimensionless): 3x the most coefficients of a matte
#: fit (1.5x those of a coated one's two fields).
MIN_PIXELS = 3 * (MAX_ORDER + 1) * (MAX_ORDER + 2) // 2


class Treatment(str, enum.Enum):
    """How a sticker's converged radiance was made."""

    #: albedo x one smooth irradiance fitted over the sticker
    SMOOTH = "smooth"
    #: the smooth model failed; the path-traced pixels are kept (render more samples there)
    FALLBACK = "fallback"


@dataclass(frozen=True)
class StickerSamples:
    """One sticker's rendered pixels, the input of :func:`demodulate`.

    Parameters
    ----------
    uv : ndarray of float (N, 2)
        Full-image pixel columns and rows (px) of the sticker's pixels (those with coverage > 0).
    radiance : ndarray of float (N, C)
        Mean of the pixel's ``spp`` radiance samples, per channel (linear, scene units).
    sample_variance : ndarray of float (N, C)
        Unbiased variance (``ddof=1``) of the pixel's radiance samples, per channel.
    spp : int
        Samples per pixel (>= 2: the variance needs two).
    albedo : ndarray of float (N, C)
        The print's albedo averaged over the sticker part of the pixel's footprint (primary
        rays; dimensionless, 0-1).
    coverage : ndarray of float (N,)
        Share of the pixel's footprint on the sticker (0-1); below 1 at the border.
    albedo_variance : ndarray of float (N, C), optional
        Variance of the print's albedo over the sticker part of the footprint (from the same
        primary rays: mean of the squares minus the squared mean). Its samples land on ink and
        paper at random, which dominates the noise of pixels that straddle a print edge; with it
        the noise model is per pixel (module docstring), without it pooled in albedo bins.
    background : ndarray of float (N, C), optional
        The background part of a mixed pixel: the mean of the pixel's own samples whose primary
        ray left the sticker (linear; NaN where none did). Without it (or where NaN) a mixed
        pixel keeps its rendered value: unbiased, but not denoised.
    footprint_albedo : ndarray of float (N, C), optional
        The albedo over the sticker part of the footprint from many more primary rays than the
        radiance's (a pass of intersections only). The irradiance is fitted on the ratio of the
        radiance to ``albedo`` (the same rays, so their sampling of a print edge cancels) and
        multiplied by this: a pixel that straddles an ink/paper edge would otherwise keep the
        noise of a few samples' share of ink. Default: ``albedo``.
    footprint_coverage : ndarray of float (N,), optional
        The coverage from the same primary rays (the border blend uses it). Default:
        ``coverage``.
    coated : bool
        The print is under a dielectric laminate (module docstring: coated prints).
    """

    uv: NDArray[np.float64]
    radiance: NDArray[np.float64]
    sample_variance: NDArray[np.float64]
    spp: int
    albedo: NDArray[np.float64]
    coverage: NDArray[np.float64]
    albedo_variance: NDArray[np.float64] | None = None
    background: NDArray[np.float64] | None = None
    footprint_albedo: NDArray[np.float64] | None = None
    footprint_coverage: NDArray[np.float64] | None = None
    coated: bool = False

    def __post_init__(self) -> None:
        n = len(self.uv)
        if np.shape(self.uv) != (n, 2):
            raise ValueError(f"uv: expected shape (N, 2), got {np.shape(self.uv)}")
        shape = np.shape(self.radiance)
        if len(shape) != 2 or shape[0] != n:
            raise ValueError(f"radiance: expected shape ({n}, C), got {shape}")
        for name in (
            "sample_variance", "albedo", "albedo_variance", "background", "footprint_albedo"
        ):  # fmt: skip
            value = getattr(self, name)
            if value is not None and np.shape(value) != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {np.shape(value)}")
        for name in ("coverage", "footprint_coverage"):
            value = getattr(self, name)
            if value is not None and np.shape(value) != (n,):
                raise ValueError(f"{name}: expected shape ({n},), got {np.shape(value)}")
        if int(self.spp) < 2:
            raise ValueError(f"spp: expected at least 2 samples per pixel, got {self.spp}")


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
        Pixels fitted (fully covered, albedo above :data:`MIN_ALBEDO`).
    """

    order: int
    reduced_chi2: float
    p_value: float
    max_block_z: float
    block_threshold: float
    n_pixels: int


@dataclass(frozen=True)
class DemodulationResult:
    """The converged radiance of one sticker and how it was made.

    Attributes
    ----------
    radiance : ndarray of float (N, C)
        Converged radiance (linear): albedo x fitted irradiance on covered pixels, coverage-mixed
        with the background at the border; the rendered mean where the treatment is fallback.
    treatment : Treatment
        What was used.
    fits : tuple of ChannelFit
        Per channel, the diagnostics of the best smooth fit (empty when too few pixels).
    reason : str
        Why the smooth model was rejected ("" when it was not).
    """

    radiance: NDArray[np.float64]
    treatment: Treatment
    fits: tuple[ChannelFit, ...] = field(default=())
    reason: str = ""

    @property
    def needs_more_samples(self) -> bool:
        """The path-traced pixels were kept: the caller should render this sticker with more."""
        return self.treatment is Treatment.FALLBACK


def _design(uv: NDArray[np.float64], centre: NDArray[np.float64], scale: float, order: int):
    """Monomials ``x**i y**j`` (i + j <= order) of coordinates normalised to about [-1, 1].

    Columns run by total degree, so the design of a lower order is the first
    ``(order + 1) (order + 2) / 2`` columns of a higher one's.
    """
    x, y = ((uv - centre) / scale).T
    return np.stack([x**i * y ** (d - i) for d in range(order + 1) for i in range(d + 1)], axis=1)


def _n_coefficients(order: int) -> int:
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
        k = fields * _n_coefficients(order)
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
    if spread is not None:
        # one sample is a(x) E X with X of mean 1, variance rho^2: the ratio's sample variance is
        # E^2 (rho^2 (1 + g) + g); rho^2 is pooled over the sticker
        # (from the pixels on one albedo when there are enough: a stratified sampler spreads
        # the samples of an edge pixel over ink and paper evenly, below this model's g)
        pure = spread <= RELATIVE_NOISE_FLOOR
        pool = pure if pure.sum() >= MIN_BIN_PIXELS else np.ones_like(pure)
        rho2 = max(float(np.mean(spp * q[pool] - spread[pool]) / np.mean(1 + spread[pool])), 0.0)
        phi = (rho2 * (1.0 + spread) + spread) / spp
    else:
        edges = np.linspace(albedo.min(), albedo.max(), ALBEDO_BINS + 1)
        bins = np.clip(np.searchsorted(edges, albedo, side="right") - 1, 0, ALBEDO_BINS - 1)
        counts = np.bincount(bins, minlength=ALBEDO_BINS)
        sums = np.bincount(bins, weights=q, minlength=ALBEDO_BINS)
        pooled = np.where(counts >= MIN_BIN_PIXELS, sums / np.maximum(counts, 1), np.mean(q))
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
class _Fit:
    irradiance_all: NDArray[np.float64]
    specular_all: NDArray[np.float64]
    diagnostics: ChannelFit
    failed: str


def _fit_channel(
    uv: NDArray[np.float64],
    target: NDArray[np.float64],
    rel_var: NDArray[np.float64],
    albedo: NDArray[np.float64],
    spread: NDArray[np.float64] | None,
    uv_all: NDArray[np.float64],
    spp: int,
    alpha: float,
    coated: bool = False,
) -> _Fit:
    """Fit one channel's smooth fields over the fitted pixels ``uv``; evaluate at ``uv_all``.

    Matte: ``target`` is the ratio radiance / albedo, one field (the irradiance). Coated:
    ``target`` is the radiance, two fields: ``albedo x D + S`` (module docstring).
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
    quadratic = design[:, : fields * _n_coefficients(2)]
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
    return _Fit(at_all @ coef[::fields], specular, diagnostics, failed)


def demodulate(samples: StickerSamples, alpha: float = ALPHA) -> DemodulationResult:
    """The converged radiance of one sticker from its few-sample render and its albedo pass.

    Parameters
    ----------
    samples : StickerSamples
        The sticker's pixels, their rendered mean and sample variance, albedo and coverage.
    alpha : float
        Family-wise false-alarm probability per sticker of the smooth-model tests
        (default :data:`ALPHA`).

    Returns
    -------
    DemodulationResult
        Converged radiance (N, C), the treatment used and the fit's diagnostics.
    """
    uv = np.asarray(samples.uv, np.float64)
    raw = np.asarray(samples.radiance, np.float64)
    albedo = np.asarray(samples.albedo, np.float64)
    s2 = np.asarray(samples.sample_variance, np.float64)
    coverage = np.asarray(samples.coverage, np.float64)
    spread_all = (
        None if samples.albedo_variance is None else np.asarray(samples.albedo_variance, float)
    )
    n_channels = raw.shape[1]
    full = coverage >= FULL_COVERAGE
    per_test = alpha / (2 * n_channels)
    fits: list[ChannelFit] = []
    irradiance = np.empty_like(raw)
    specular = np.zeros_like(raw)
    coated = bool(samples.coated)
    for c in range(n_channels):
        # a coated print's radiance needs no division: its darkest pixels fit the specular best
        used = full if coated else full & (albedo[:, c] > MIN_ALBEDO)
        if used.sum() < MIN_PIXELS:
            return DemodulationResult(
                raw.copy(), Treatment.FALLBACK, tuple(fits),
                f"too few covered pixels: {int(used.sum())} < {MIN_PIXELS}",
            )  # fmt: skip
        a = albedo[used, c]
        if coated:  # the radiance itself; its noise pooled in albedo bins
            target, rel_var, spread = raw[used, c], s2[used, c] / samples.spp, None
        else:
            target, rel_var = raw[used, c] / a, s2[used, c] / (samples.spp * a * a)
            spread = None if spread_all is None else spread_all[used, c] / (a * a)
        fit = _fit_channel(
            uv[used], target, rel_var, a, spread, uv, int(samples.spp), per_test, coated
        )
        fits.append(fit.diagnostics)
        if fit.failed:
            return DemodulationResult(
                raw.copy(), Treatment.FALLBACK, tuple(fits), f"channel {c}: {fit.failed}"
            )
        irradiance[:, c] = fit.irradiance_all
        specular[:, c] = fit.specular_all
    if samples.footprint_albedo is not None:
        albedo = np.asarray(samples.footprint_albedo, np.float64)
    if samples.footprint_coverage is not None:
        coverage = np.asarray(samples.footprint_coverage, np.float64)
        full = coverage >= FULL_COVERAGE
    sticker = albedo * irradiance + specular
    out = np.where(full[:, None] & np.isfinite(sticker), sticker, raw)
    if samples.background is not None:
        mixed = ~full & np.isfinite(sticker).all(axis=1)
        cov = coverage[mixed, None]
        background = np.asarray(samples.background, np.float64)[mixed]
        blended = cov * sticker[mixed] + (1.0 - cov) * background
        # no sample of the pixel left the sticker: nothing to estimate the background from
        out[mixed] = np.where(np.isfinite(background), blended, raw[mixed])
    return DemodulationResult(out, Treatment.SMOOTH, tuple(fits))
