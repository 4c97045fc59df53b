"""Per-pixel sample statistics with the primary hit's sticker and print albedo.

The input that :func:`simgap.render.demodulate.demodulate` needs per sticker, from one pass:
every camera sample is traced by the integrator (its radiance) and its primary ray is
intersected once more for the sticker it lands on and the print's albedo there
(``BSDF.eval_diffuse_reflectance``: the texture lookup the integrator's first bounce makes).
The extra intersection is one ray per sample against a path of several (primary rays only,
nearly free). Statistics are reduced per pixel in numpy.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from simgap.render.scene import FixtureScene

#: Shape ids of the stickers in the Mitsuba scene: ``tag_<id>`` (:class:`FixtureScene`).
STICKER_PREFIX = "tag_"
#: Scrambling seed of :func:`footprint_pattern` (any fixed value: the pattern must not change
#: between renders, so that every render seed shares one footprint quadrature).
FOOTPRINT_PATTERN_SEED = 28


@dataclass(frozen=True)
class PixelSamples:
    """Per-pixel statistics of ``spp`` samples (N pixels, C = 3 channels, linear).

    Attributes
    ----------
    mean, variance : ndarray (N, C)
        Mean radiance and its unbiased sample variance (``ddof=1``).
    sticker : ndarray of int (N,)
        The tag id of the sticker most of the pixel's samples land on; -1 where none does.
    coverage : ndarray (N,)
        Share of the pixel's samples on that sticker (0-1).
    albedo, albedo_variance : ndarray (N, C)
        Mean and variance of the print's albedo over those samples (NaN where none).
    background : ndarray (N, C)
        Mean radiance of the pixel's other samples (NaN where every sample is on the sticker).
    spp : int
        Samples per pixel.
    """

    mean: np.ndarray
    variance: np.ndarray
    sticker: np.ndarray
    coverage: np.ndarray
    albedo: np.ndarray
    albedo_variance: np.ndarray
    background: np.ndarray
    spp: int


def _primary_hits(scene: FixtureScene, ray):
    """The sticker id (-1 off every sticker) and the print's albedo of primary rays (Dr.Jit)."""
    import drjit as dr

    mi = scene.mi
    hit = scene.scene.ray_intersect(mi.Ray3f(ray))
    sticker = mi.Int32(-1)
    for shape in scene.scene.shapes():
        if shape.id().startswith(STICKER_PREFIX):
            tag = int(shape.id()[len(STICKER_PREFIX) :])
            sticker = dr.select(hit.shape == mi.ShapePtr(shape), tag, sticker)
    return sticker, hit.bsdf().eval_diffuse_reflectance(hit, True)


def _to_numpy(value) -> np.ndarray:
    """A Dr.Jit colour or point as a float32 (L, 3) array."""
    return np.stack([np.asarray(c, np.float32) for c in (value.x, value.y, value.z)], -1)


def _launch(
    scene: FixtureScene, pixels: np.ndarray, seed: int, spp: int, pattern, rest: bool = False
):
    """One kernel launch: per sample radiance, sticker id and albedo ((L, 3), (L,), (L, 3)).

    With a ``pattern`` only the primary rays are traced and the radiance is None; with ``rest``
    the stickers' samples leave out the sun's direct light
    (:func:`simgap.render.sun_direct.rest_trace`).
    """
    import drjit as dr

    if rest:
        from simgap.render.sun_direct import rest_trace

        ray, value = rest_trace(scene, pixels, seed, spp)
    else:
        ray, value = scene.trace(pixels, seed, spp, pattern)
    sticker, albedo = _primary_hits(scene, ray)
    dr.eval(sticker, albedo) if value is None else dr.eval(value, sticker, albedo)
    rgb = None if value is None else _to_numpy(value)
    return rgb, np.asarray(sticker, np.int32), _to_numpy(albedo)


def _reduced(
    scene: FixtureScene,
    pixels: np.ndarray,
    seed: int,
    spp: int,
    pattern: np.ndarray | None,
    rest: bool = False,
) -> PixelSamples:
    """Trace ``spp`` samples per pixel (the sampler's, or ``pattern``) and reduce them."""
    from simgap.render.scene import launches

    pixels = np.asarray(pixels).reshape(-1, 2)
    n = len(pixels)
    rad = np.empty((n, spp, 3), np.float32) if pattern is None else None
    ids, alb = np.empty((n, spp), np.int32), np.empty((n, spp, 3), np.float32)
    for start, padded, launch_seed in launches(pixels, seed, spp, 1):
        r, i, a = _launch(scene, padded, launch_seed, spp, pattern, rest)
        m = min(len(padded), n - start)
        if rad is not None:
            rad[start : start + m] = r.reshape(-1, spp, 3)[:m]
        ids[start : start + m] = i.reshape(-1, spp)[:m]
        alb[start : start + m] = a.reshape(-1, spp, 3)[:m]
    return reduce_samples(rad, ids, alb)


def sample_pixels(
    scene: FixtureScene,
    pixels: np.ndarray,
    seed: int,
    spp: int | None = None,
    rest: bool = False,
) -> PixelSamples:
    """Trace ``spp`` samples (default: the scene's) per pixel; reduce them per pixel.

    Parameters
    ----------
    scene : FixtureScene
        A posed scene (:meth:`FixtureScene.set_pose`).
    pixels : ndarray of int (N, 2)
        Full-image pixel columns and rows (px).
    seed : int
        Sampler seed (same seed, same statistics).
    spp : int, optional
        Samples per pixel (at least 2: the variance needs two).
    rest : bool
        The samples that land on a sticker leave out the sun's direct light
        (:func:`simgap.render.sun_direct.rest_trace`; the scene must have a sun:
        :func:`simgap.render.sun_direct.split_sun`).
    """
    spp = scene.spp if spp is None else int(spp)
    if spp < 2:
        raise ValueError(f"spp: expected at least 2 samples per pixel, got {spp}")
    return _reduced(scene, pixels, seed, spp, None, rest)


@functools.lru_cache(maxsize=4)
def footprint_pattern(points: int) -> np.ndarray:
    """The fixed footprint pattern: ``points`` (a power of two) points in [0, 1)^4, float32.

    The first ``points`` of an Owen-scrambled Sobol' sequence (``scipy.stats.qmc.Sobol``, seed
    :data:`FOOTPRINT_PATTERN_SEED`): every dimension has one point in each ``1 / points``
    interval, and dimensions 0-1 (the pixel filter's sample) form a (0, m, 2)-net, so under a
    box filter an edge along a pixel axis is placed to within ``1 / points`` px; dimensions 2-3
    are the aperture's sample.
    """
    from scipy.stats import qmc

    if points < 2 or points & (points - 1):
        raise ValueError(f"points: expected a power of two >= 2, got {points}")
    sobol = qmc.Sobol(d=4, scramble=True, seed=FOOTPRINT_PATTERN_SEED)
    pattern = sobol.random_base2(int(points).bit_length() - 1).astype(np.float32)
    pattern.flags.writeable = False  # cached: shared by every call
    return pattern


def footprint_samples(scene: FixtureScene, pixels: np.ndarray, points: int) -> PixelSamples:
    """Sticker, coverage and albedo over each pixel's footprint, from a fixed point pattern.

    Primary rays only (radiance NaN): every pixel is integrated with the same
    :func:`footprint_pattern`, warped by the reconstruction filter (and the thin lens'
    aperture) as the camera samples are, so a pixel's footprint is a deterministic quadrature
    of the geometry: the same for every render seed, whichever other pixels are asked for.

    Parameters
    ----------
    scene : FixtureScene
        A posed scene.
    pixels : ndarray of int (N, 2)
        Full-image pixel columns and rows (px).
    points : int
        Points per pixel (a power of two).
    """
    return _reduced(scene, pixels, 0, points, footprint_pattern(points))


def reduce_samples(
    radiance: np.ndarray | None, sticker: np.ndarray, albedo: np.ndarray
) -> PixelSamples:
    """Per-pixel statistics of samples: radiance (N, S, C), sticker ids (N, S), albedo (N, S, C).

    ``radiance`` None: primary rays only (the radiance statistics are NaN).
    """
    n, spp = sticker.shape
    # the sticker most samples land on (ties: the lower id)
    own, best = np.full(n, -1), np.zeros(n, int)
    for tag in np.flatnonzero(np.bincount(sticker[sticker >= 0].ravel())):
        count = np.count_nonzero(sticker == tag, axis=1)
        better = count > best
        own[better], best[better] = tag, count[better]
    off = ((sticker != own[:, None]) | (own[:, None] < 0))[..., None]
    n_on = best.astype(np.float64)[:, None]
    nan3 = np.full((n, 3), np.nan)
    # in float64: a float32 albedo times a sample count is exact, so a pixel whose samples saw
    # one albedo has exactly that mean and a variance of exactly zero (callers tell edge pixels
    # by a non-zero variance)
    with np.errstate(invalid="ignore", divide="ignore"):
        albedo_on = albedo.astype(np.float64)
        np.copyto(albedo_on, 0.0, where=off)
        albedo_mean = _sum_over_samples(albedo_on) / n_on
        deviation = albedo_on - albedo_mean[:, None]
        np.copyto(deviation, 0.0, where=off)
        albedo_var = _sum_over_samples(np.square(deviation)) / n_on
        if radiance is None:
            mean = variance = background = nan3
        else:
            values = radiance.astype(np.float64)
            total = _sum_over_samples(values)
            mean = total / spp
            variance = _sum_over_samples(np.square(values - mean[:, None])) / (spp - 1)
            np.copyto(values, 0.0, where=~off)
            background = _sum_over_samples(values) / (spp - n_on)
    return PixelSamples(
        mean=mean,
        variance=variance,
        sticker=own,
        coverage=n_on[:, 0] / spp,
        albedo=albedo_mean,
        albedo_variance=albedo_var,
        background=background,
        spp=spp,
    )


def _sum_over_samples(values: np.ndarray) -> np.ndarray:
    """Sum (N, S, C) over the samples S.

    ``einsum`` of one operand: about 5x faster than ``sum(axis=1)`` over a short middle axis, and
    single-threaded (a BLAS product is faster alone, but its threads fight a busy machine's).
    """
    return np.einsum("nsc->nc", values)
