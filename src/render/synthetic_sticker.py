"""A synthetic path-traced sticker with a known expectation, to check the demodulation.

A square sticker carries an ArUco-like print of 10 x 10 cells (a paper quiet zone, an ink border
and 6 x 6 random bits), axis-aligned at a sub-pixel offset so that cell edges and the sticker's
border cut through pixels. Each pixel gets ``spp`` stratified samples (an ``m x m`` jittered grid,
as Mitsuba's ``multijitter`` places them); a sample on the sticker returns

    (albedo(x) * E(pixel centre) * shadow(x) + highlight(pixel centre)) * X

and one off it ``background * shadow(x) * X``, where ``X`` is a gamma-distributed factor of mean 1
and standard deviation ``relative_noise`` drawn per sample: the light-sampling noise of a path
tracer, proportional to the radiance. The irradiance ``E`` is taken at the pixel centre, which is
the demodulation's own model (:mod:`simgap.render.demodulate`); the error of that footprint
approximation on a real render is not part of this check. The albedo pass (the print's albedo over
the sticker part of the footprint) and the coverage are exact (box filter, computed from the
overlap of pixels and cells). The expectation of each pixel's mean is exact too, except on pixels
crossed by the shadow line, where it is a 32 x 32-point midpoint rule (:attr:`SyntheticSticker.
straddles`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from simgap.render.demodulate import StickerSamples

__all__ = ["Shadow", "SyntheticSticker", "quadratic_irradiance", "synthetic_sticker"]

#: Print albedos (dimensionless): a matte black ink and a white paper.
INK_ALBEDO, PAPER_ALBEDO = 0.03, 0.8
#: Cells per side of the print (quiet zone + border + 6 x 6 bits).
CELLS = 10
#: Midpoints per side of the rule that integrates a pixel the shadow line crosses.
QUADRATURE = 32

Field = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


@dataclass(frozen=True)
class Shadow:
    """A hard shadow edge: irradiance times ``factor`` where ``(x, y) . normal > offset`` (px)."""

    normal: tuple[float, float]
    offset: float
    factor: float

    def __call__(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """The irradiance factor at image points ``x, y`` (px)."""
        side = x * self.normal[0] + y * self.normal[1] > self.offset
        return np.where(side, self.factor, 1.0)


@dataclass(frozen=True)
class SyntheticSticker:
    """A synthetic sticker render and its noise-free expectation.

    Attributes
    ----------
    samples : StickerSamples
        The demodulation's input (one channel).
    truth : ndarray of float (N, 1)
        Expected value of each pixel's rendered mean (linear).
    straddles : ndarray of bool (N,)
        The shadow line crosses the pixel (its truth is a quadrature there).
    """

    samples: StickerSamples
    truth: NDArray[np.float64]
    straddles: NDArray[np.bool_]


def quadratic_irradiance(centre: tuple[float, float], half: float, level: float = 0.5) -> Field:
    """A smooth quadratic irradiance over a sticker: ``level`` at ``centre``, +-~50 % at corners."""

    def field(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        xn, yn = (x - centre[0]) / half, (y - centre[1]) / half
        return level * (1 + 0.25 * xn - 0.15 * yn + 0.2 * xn**2 - 0.1 * xn * yn + 0.15 * yn**2)

    return field


def _overlap(lo: NDArray[np.float64], edges: NDArray[np.float64]) -> NDArray[np.float64]:
    """Length (px) of each pixel interval ``[lo, lo + 1]`` inside each cell ``edges[j:j+2]``."""
    a = np.maximum(lo[:, None], edges[None, :-1])
    b = np.minimum(lo[:, None] + 1.0, edges[None, 1:])
    return np.clip(b - a, 0.0, None)


def synthetic_sticker(
    rng: np.random.Generator,
    spp: int,
    *,
    size_px: float = 60.0,
    origin: tuple[float, float] = (100.37, 200.71),
    relative_noise: float = 1.0,
    background: float = 0.15,
    irradiance: Field | None = None,
    shadow: Shadow | None = None,
    highlight: Field | None = None,
) -> SyntheticSticker:
    """Render a synthetic sticker (module docstring) with ``spp`` samples a pixel.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the print's bits, the sample positions and the noise.
    spp : int
        Samples per pixel, a square (4, 16, ...).
    size_px : float
        Sticker side (px).
    origin : tuple of float
        Continuous image position of the sticker's top-left corner (px; pixel ``u`` spans
        ``[u - 0.5, u + 0.5]``).
    relative_noise : float
        Standard deviation of one sample relative to its expectation (0: noise-free).
    background : float
        Radiance of the background around the sticker (linear).
    irradiance : callable, optional
        ``E(x, y)`` at pixel centres (default :func:`quadratic_irradiance`).
    shadow : Shadow, optional
        A hard shadow edge, evaluated at each sample's position.
    highlight : callable, optional
        An additive radiance lobe on the sticker ``H(x, y)``, independent of the albedo.
    """
    m = int(round(np.sqrt(spp)))
    if m * m != spp:
        raise ValueError(f"spp: expected a square sample count, got {spp}")
    x0, y0 = origin
    half = size_px / 2
    irradiance = irradiance or quadratic_irradiance((x0 + half, y0 + half), half)
    print_ = np.full((CELLS, CELLS), INK_ALBEDO)
    print_[[0, -1], :] = print_[:, [0, -1]] = PAPER_ALBEDO
    print_[2:-2, 2:-2] = np.where(
        rng.random((CELLS - 4, CELLS - 4)) < 0.5, INK_ALBEDO, PAPER_ALBEDO
    )

    us = np.arange(int(np.floor(x0 + 0.5)), int(np.ceil(x0 + size_px + 0.5)))
    vs = np.arange(int(np.floor(y0 + 0.5)), int(np.ceil(y0 + size_px + 0.5)))
    cell_x = x0 + size_px * np.arange(CELLS + 1) / CELLS
    cell_y = y0 + size_px * np.arange(CELLS + 1) / CELLS
    ox, oy = _overlap(us - 0.5, cell_x), _overlap(vs - 0.5, cell_y)
    coverage = np.outer(oy.sum(axis=1), ox.sum(axis=1))
    albedo_sum = oy @ print_ @ ox.T
    keep = coverage > 0
    vv, uu = np.nonzero(keep)
    u, v = us[uu].astype(float), vs[vv].astype(float)
    cov = coverage[keep]
    albedo = albedo_sum[keep] / cov
    albedo_variance = (oy @ print_**2 @ ox.T)[keep] / cov - albedo**2

    def albedo_at(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """Print albedo at image points; NaN off the sticker."""
        i = np.floor((y - y0) / size_px * CELLS).astype(int)
        j = np.floor((x - x0) / size_px * CELLS).astype(int)
        on = (i >= 0) & (i < CELLS) & (j >= 0) & (j < CELLS)
        return np.where(on, print_[np.clip(i, 0, CELLS - 1), np.clip(j, 0, CELLS - 1)], np.nan)

    e = irradiance(u, v)
    h = highlight(u, v) if highlight is not None else np.zeros_like(u)

    def radiance_at(x, y, k):
        """Expected radiance of sample points ``x, y`` (..., S) of pixels ``k``."""
        a = albedo_at(x, y)
        s = shadow(x, y) if shadow is not None else 1.0
        on = a * e[k, None] * s + h[k, None]
        return np.where(np.isnan(a), background * s, on), ~np.isnan(a)

    # stratified jittered sample positions in each pixel
    grid = (np.arange(spp) % m, np.arange(spp) // m)
    jitter = rng.random((len(u), spp, 2))
    sx = u[:, None] - 0.5 + (grid[0][None, :] + jitter[..., 0]) / m
    sy = v[:, None] - 0.5 + (grid[1][None, :] + jitter[..., 1]) / m
    k = np.arange(len(u))
    expect, on = radiance_at(sx, sy, k)
    if relative_noise > 0:
        shape = 1.0 / relative_noise**2
        values = expect * rng.gamma(shape, 1.0 / shape, size=expect.shape)
    else:
        values = expect
    # the background part of a mixed pixel: the mean of its samples that left the sticker
    off = (~on).sum(axis=1)
    off_sum = np.where(on, 0.0, values).sum(axis=1)
    bg = np.where(off > 0, off_sum / np.maximum(off, 1), np.nan)

    shade = shadow if shadow is not None else (lambda x, y: np.ones_like(x))
    corners = [shade(u + dx, v + dy) for dx in (-0.5, 0.5) for dy in (-0.5, 0.5)]
    straddles = np.ptp(np.stack(corners), axis=0) > 0
    truth = cov * (albedo * e * shade(u, v) + h) + (1 - cov) * background * shade(u, v)
    if straddles.any():
        q = (np.arange(QUADRATURE) + 0.5) / QUADRATURE - 0.5
        qx, qy = (g.ravel() for g in np.meshgrid(q, q))
        ks = np.nonzero(straddles)[0]
        dense, _ = radiance_at(u[ks, None] + qx, v[ks, None] + qy, ks)
        truth[ks] = dense.mean(axis=1)

    samples = StickerSamples(
        uv=np.column_stack([u, v]),
        radiance=values.mean(axis=1)[:, None],
        sample_variance=values.var(axis=1, ddof=1)[:, None],
        spp=spp,
        albedo=albedo[:, None],
        coverage=cov,
        albedo_variance=np.maximum(albedo_variance, 0.0)[:, None],
        background=bg[:, None],
    )
    return SyntheticSticker(samples, truth[:, None], straddles)
