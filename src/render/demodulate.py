"""Albedo demodulation of one flat printed sticker: a converged render from few samples.

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
lobe, is not smooth: the fit's tests reject it and the sticker is path traced with more samples.

This module and :mod:`simgap.render.smooth_field` are the numerical core (numpy and scipy; no
renderer import). Its input per
sticker is :class:`StickerSamples`; :func:`demodulate` returns a :class:`DemodulationResult`
recording the treatment used and the fit's diagnostics.

The statistics of the fit (noise model, order, tests) are stated in
:mod:`simgap.render.smooth_field`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from simgap.render.smooth_field import MAX_ORDER, ChannelFit, fit_channel, n_coefficients

__all__ = [
    "FALSE_ALARM_PROBABILITY",
    "ChannelFit",
    "DemodulationResult",
    "StickerSamples",
    "Treatment",
    "demodulate",
]

#: Family-wise false-alarm probability per sticker of the smooth-model tests (dimensionless).
FALSE_ALARM_PROBABILITY = 1e-3
#: A pixel counts as fully on the sticker at this coverage or above (dimensionless).
FULL_COVERAGE = 1.0 - 1e-6
#: Pixels of lower albedo are left out of the fit (their ratio is undefined; dimensionless).
MIN_ALBEDO = 1e-3
#: Fewest fully covered pixels a fit needs (dimensionless): 3x the most coefficients of a matte
#: fit (1.5x those of a coated one's two fields).
MIN_PIXELS = 3 * n_coefficients(MAX_ORDER)


class Treatment(str, enum.Enum):
    """How a sticker's converged radiance was made."""

    #: albedo x one smooth irradiance fitted over the sticker
    SMOOTH = "smooth"
    #: the smooth model failed; the path-traced pixels are kept (render more samples there)
    FALLBACK = "fallback"
    #: no sample received light (a sticker in the shadow under a black sky): exactly black
    DARK = "dark"


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
        The background radiance at a mixed pixel: the mean of the samples whose primary ray left
        the sticker, the pixel's own or pooled with its neighbours' (linear; NaN where none did;
        :func:`simgap.render.converged.pooled_background`). Without it (or where NaN) a mixed
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


def demodulate(
    samples: StickerSamples, alpha: float = FALSE_ALARM_PROBABILITY
) -> DemodulationResult:
    """The converged radiance of one sticker from its few-sample render and its albedo pass.

    Parameters
    ----------
    samples : StickerSamples
        The sticker's pixels, their rendered mean and sample variance, albedo and coverage.
    alpha : float
        Family-wise false-alarm probability per sticker of the smooth-model tests
        (default :data:`FALSE_ALARM_PROBABILITY`).

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
    if not np.any(raw):
        return DemodulationResult(raw.copy(), Treatment.DARK, ())
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
        if not np.any(target):  # no light of this colour reaches it (a light without blue)
            irradiance[:, c] = 0.0
            continue
        fit = fit_channel(
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
        # no sample within the pooling square left the sticker: no background to blend with
        out[mixed] = np.where(np.isfinite(background), blended, raw[mixed])
    return DemodulationResult(out, Treatment.SMOOTH, tuple(fits))
