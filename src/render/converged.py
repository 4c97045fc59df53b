"""Converged sticker renders: albedo demodulation per sticker, more samples where it fails.

``render.mode: converged`` (issue 28). Every pixel of a region is traced at the scene's samples
per pixel with its primary hit's sticker and print albedo (:func:`simgap.render.pixel_samples.
sample_pixels`), and once more with :data:`FOOTPRINT_SPP` primary rays only (the footprint's
albedo and coverage). Per sticker, the radiance is divided by the albedo of its own samples, a
smooth irradiance is fitted and multiplied by the footprint's albedo
(:func:`simgap.render.demodulate.demodulate`), which removes most of
the Monte Carlo noise of a flat diffuse print. Where the smooth model is rejected (a shadow or
highlight edge across the sticker), that sticker's pixels are path traced again with
:data:`FALLBACK_SPP_FACTOR` times the samples; a print under a coating (a glossy laminate, whose
diffuse lobe is no linear function of the albedo and whose specular lobe is not smooth across
the texture) is path traced as in ``path`` mode. Pixels off the stickers (node, table) keep their
path-traced mean: only the detector's thresholds see them. The treatment of every sticker is
returned so that the caller can record it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from simgap.render.demodulate import StickerSamples, Treatment, demodulate
from simgap.render.pixel_samples import sample_pixels

if TYPE_CHECKING:
    from simgap.render.scene import FixtureScene

#: Samples per pixel, relative to the scene's, of a sticker whose smooth model was rejected.
#: Four: the path-traced noise halves (a 16-spp sticker then carries the noise of 64 spp).
FALLBACK_SPP_FACTOR = 4
#: Primary rays per pixel of the footprint pass (albedo and coverage the product is made with):
#: intersections only, stratified by the scene's sampler. Measured on a baseline configuration
#: (p 2, 4 spp, against 1024 spp that carry 0.42 DN of their own): 16 rays 0.93 DN RMS, 64 rays
#: 0.58 DN, 256 rays 0.55 DN at four times the cost of 64.
FOOTPRINT_SPP = 64
#: Treatment of a coated print's stickers (no demodulation; path traced).
COATED = "path (coated print)"


@dataclass(frozen=True)
class ConvergedRender:
    """A region's radiance and how each sticker's was made.

    Attributes
    ----------
    values : ndarray (N, 3)
        Linear RGB radiance of the pixels, in the order asked for.
    treatments : dict of int to str
        Per tag id: ``"smooth"`` (demodulated), ``"fallback (<why>): <spp> spp"`` (path traced
        with more samples) or :data:`COATED`.
    """

    values: np.ndarray
    treatments: dict[int, str]


def converged_pixels(scene: FixtureScene, pixels: np.ndarray, seed: int) -> ConvergedRender:
    """Render ``pixels`` of a posed scene with every sticker demodulated (module docstring).

    Parameters
    ----------
    scene : FixtureScene
        A posed scene; its ``spp`` (at least 2) is the samples of the first pass.
    pixels : ndarray of int (N, 2)
        Full-image pixel columns and rows (px).
    seed : int
        Sampler seed (same seed, same render).
    """
    pixels = np.asarray(pixels).reshape(-1, 2)
    samples = sample_pixels(scene, pixels, seed)
    values = samples.mean.copy()
    tags = [int(t) for t in np.unique(samples.sticker[samples.sticker >= 0])]
    if scene.spec.tag.coating is not None:
        return ConvergedRender(values.astype(np.float32), dict.fromkeys(tags, COATED))
    # the footprint pass where a pixel's samples disagree (a print edge or the sticker's border
    # in its footprint) and next to such pixels (an edge that cuts a corner of a pixel may miss
    # all of its few samples); elsewhere every sample saw one cell, whose albedo is exact
    mixed = (samples.albedo_variance.max(axis=1) > 0) | (
        (samples.coverage > 0) & (samples.coverage < 1)
    )
    near = near_pixels(pixels, mixed)
    footprint = sample_pixels(scene, pixels[near], seed + 1, FOOTPRINT_SPP, radiance=False)
    footprint_albedo, footprint_coverage = samples.albedo.copy(), samples.coverage.copy()
    footprint_sticker = samples.sticker.copy()
    footprint_albedo[near], footprint_coverage[near] = footprint.albedo, footprint.coverage
    footprint_sticker[near] = footprint.sticker
    treatments: dict[int, str] = {}
    for tag in tags:
        on = np.flatnonzero(samples.sticker == tag)
        own = footprint_sticker[on] == tag
        result = demodulate(
            StickerSamples(
                uv=pixels[on].astype(np.float64),
                radiance=samples.mean[on],
                sample_variance=samples.variance[on],
                spp=samples.spp,
                albedo=samples.albedo[on],
                coverage=samples.coverage[on],
                albedo_variance=samples.albedo_variance[on],
                background=samples.background[on],
                footprint_albedo=np.where(own[:, None], footprint_albedo[on], samples.albedo[on]),
                footprint_coverage=np.where(own, footprint_coverage[on], samples.coverage[on]),
            )
        )
        if result.treatment is Treatment.SMOOTH:
            values[on] = result.radiance
            treatments[tag] = Treatment.SMOOTH.value
            continue
        spp = samples.spp * FALLBACK_SPP_FACTOR
        more = sample_pixels(scene, pixels[on], seed + 1 + tag, spp)
        values[on] = more.mean
        treatments[tag] = f"fallback ({result.reason}): {spp} spp"
    return ConvergedRender(values.astype(np.float32), treatments)


def near_pixels(pixels: np.ndarray, marked: np.ndarray) -> np.ndarray:
    """Pixels that are marked or touch a marked one (8-neighbourhood), as a mask over ``pixels``."""
    lo = pixels.min(axis=0) - 1
    u, v = (pixels - lo).T
    grid = np.zeros((v.max() + 2, u.max() + 2), np.uint8)
    grid[v[marked], u[marked]] = 1
    grid = cv2.dilate(grid, np.ones((3, 3), np.uint8))
    return grid[v, u].astype(bool)
