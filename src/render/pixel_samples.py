"""Per-pixel sample statistics with the primary hit's sticker and print albedo (issue 28).

The input that :func:`simgap.render.demodulate.demodulate` needs per sticker, from one pass:
every camera sample is traced by the integrator (its radiance) and its primary ray is
intersected once more for the sticker it lands on and the print's albedo there
(``BSDF.eval_diffuse_reflectance``: the texture lookup the integrator's first bounce makes).
The extra intersection is one ray per sample against a path of several (primary rays only,
nearly free). Statistics are reduced per pixel in numpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from simgap.render.scene import FixtureScene

#: Shape ids of the stickers in the Mitsuba scene: ``tag_<id>`` (:class:`FixtureScene`).
STICKER_PREFIX = "tag_"


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


def _launch(scene: FixtureScene, pixels: np.ndarray, seed: int, spp: int, radiance: bool):
    """One kernel launch: per sample radiance, sticker id and albedo ((L, 3), (L,), (L, 3)).

    Without ``radiance`` only primary rays are traced and the radiance is NaN.
    """
    import drjit as dr

    mi = scene.mi
    ray, value = scene.trace(pixels, seed, spp, radiance)
    hit = scene.scene.ray_intersect(mi.Ray3f(ray))
    sticker = mi.Int32(-1)
    for shape in scene.scene.shapes():
        if shape.id().startswith(STICKER_PREFIX):
            tag = int(shape.id()[len(STICKER_PREFIX) :])
            sticker = dr.select(hit.shape == mi.ShapePtr(shape), tag, sticker)
    albedo = hit.bsdf().eval_diffuse_reflectance(hit, True)
    dr.eval(sticker, albedo) if value is None else dr.eval(value, sticker, albedo)
    alb = np.stack([np.asarray(c, np.float32) for c in (albedo.x, albedo.y, albedo.z)], -1)
    rgb = None
    if value is not None:
        rgb = np.stack([np.asarray(c, np.float32) for c in (value.x, value.y, value.z)], -1)
    return rgb, np.asarray(sticker, np.int32), alb


def sample_pixels(
    scene: FixtureScene,
    pixels: np.ndarray,
    seed: int,
    spp: int | None = None,
    radiance: bool = True,
) -> PixelSamples:
    """Trace ``spp`` samples (default: the scene's) per pixel; reduce them per pixel.

    Without ``radiance`` only the primary rays are traced (the sticker, coverage and albedo of
    the footprint; radiance NaN): a pass of many samples at the cost of one intersection each.

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
    radiance : bool
        Trace paths (default); else primary rays only.
    """
    from simgap.render.scene import launches

    spp = scene.spp if spp is None else int(spp)
    if spp < 2:
        raise ValueError(f"spp: expected at least 2 samples per pixel, got {spp}")
    pixels = np.asarray(pixels).reshape(-1, 2)
    n = len(pixels)
    rad = np.empty((n, spp, 3), np.float32) if radiance else None
    ids, alb = np.empty((n, spp), np.int32), np.empty((n, spp, 3), np.float32)
    for start, padded, launch_seed in launches(pixels, seed, spp, 1):
        r, i, a = _launch(scene, padded, launch_seed, spp, radiance)
        m = min(len(padded), n - start)
        if rad is not None:
            rad[start : start + m] = r.reshape(-1, spp, 3)[:m]
        ids[start : start + m] = i.reshape(-1, spp)[:m]
        alb[start : start + m] = a.reshape(-1, spp, 3)[:m]
    return reduce_samples(rad, ids, alb)


def reduce_samples(
    radiance: np.ndarray | None, sticker: np.ndarray, albedo: np.ndarray
) -> PixelSamples:
    """Per-pixel statistics of samples: radiance (N, S, C), sticker ids (N, S), albedo (N, S, C).

    ``radiance`` None: primary rays only (the radiance statistics are NaN).
    """
    n, spp = sticker.shape
    tags = np.flatnonzero(np.bincount(sticker[sticker >= 0].ravel()))
    own = np.full(n, -1)
    best = np.zeros(n, int)
    for tag in tags:
        count = np.count_nonzero(sticker == tag, axis=1)
        better = count > best
        own[better], best[better] = tag, count[better]
    on = sticker == own[:, None]
    on &= own[:, None] >= 0
    n_on = best.astype(np.float64)
    w = on[..., None]
    nan3 = np.full((n, 3), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        albedo_mean = np.where(w, albedo, 0.0).sum(axis=1, dtype=np.float64) / n_on[:, None]
        albedo_sq = np.where(w, albedo * albedo, 0.0).sum(axis=1, dtype=np.float64)
        albedo_var = albedo_sq / n_on[:, None] - albedo_mean**2
        if radiance is None:
            mean = variance = background = nan3
        else:
            total = radiance.sum(axis=1, dtype=np.float64)
            mean = total / spp
            variance = radiance.var(axis=1, ddof=1, dtype=np.float64)
            off = total - np.where(w, radiance, 0.0).sum(axis=1, dtype=np.float64)
            background = off / (spp - n_on)[:, None]
    return PixelSamples(
        mean=mean,
        variance=variance,
        sticker=own,
        coverage=n_on / spp,
        albedo=albedo_mean,
        albedo_variance=np.clip(albedo_var, 0.0, None),
        background=background,
        spp=spp,
    )
