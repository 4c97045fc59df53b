"""Converged sticker renders: albedo demodulation per sticker, more samples where it fails.

``render.mode: converged`` (measured in docs/results/converged_render_step8.md). Every pixel of a
region is traced at the scene's samples per pixel with its primary hit's sticker and print
albedo (:func:`simgap.render.pixel_samples.sample_pixels`). On the pixels on a print edge or the
sticker's border, the print's albedo and coverage over the pixel's footprint are clipped exactly
from the print's cells
(:mod:`simgap.render.print_footprint`: box filter, nearest texture lookup, no occluder; a thin
lens's averaged over its aperture) or else integrated with :data:`FOOTPRINT_POINTS` primary
rays of one fixed pattern (:func:`simgap.render.pixel_samples.footprint_samples`); either is the
same for every render seed, and which one is used is decided by the first pass's samples
(:func:`edge_footprint`: near an occluder one seed may see it and another not; on the baseline
both seeds took the exact one at every configuration,
docs/results/converged_render_step8.md#step-4).
Per sticker, the radiance is divided by the albedo of its own samples, a smooth irradiance is
fitted and multiplied by the footprint's albedo (:func:`simgap.render.demodulate.demodulate`), which
removes most of the Monte Carlo noise of a flat diffuse print; a print under a laminate is
fitted as the albedo times a smooth diffuse field plus a smooth specular one. Where the smooth
model is rejected (a shadow or highlight edge across the sticker, a sharp glint), that
sticker's pixels are path traced again with :data:`FALLBACK_SPP_FACTOR` times the samples.
A border pixel mixes the sticker's converged radiance by its footprint coverage with the
background around it, pooled from its own and its neighbours' samples that left the sticker
(:func:`pooled_background`). Pixels off the stickers (node, table) keep their path-traced
mean: only the detector's thresholds see them. The treatment of every sticker is returned so
that the caller can record it.

Under a ``sun`` light on a matte print (:func:`simgap.render.sun_direct.split_sun`) the stickers'
samples carry their light less the sun's direct part (the sky, reflections: smooth across the
sun's shadow edges), which is treated as above; the sun's direct light, ``albedo E cos(t) V /
pi`` over each pixel's footprint with one shadow ray per point of a fixed pattern
(:func:`simgap.render.sun_direct.sun_direct`, :data:`~simgap.render.sun_direct.SUN_DIRECT_POINTS`
points), is added to every sticker pixel: noise-free, the same for every render seed, as sharp
as the geometry at a shadow edge. Every other scene is rendered as if the sun were not in the
code (the same samples, bit for bit).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from simgap.render.demodulate import StickerSamples, Treatment, demodulate
from simgap.render.pixel_samples import PixelSamples, footprint_samples, sample_pixels
from simgap.render.print_footprint import (
    agrees,
    defocus_reach_px,
    exact_footprint_applies,
    print_footprint,
)
from simgap.render.sun_direct import (
    SUN_DIRECT_POINTS,
    SUN_DIRECT_VERSION,
    SUN_LIGHT,
    split_sun,
    sun_direct,
)

if TYPE_CHECKING:
    from simgap.render.scene import FixtureScene
    from simgap.scene.spec import SceneSpec

#: Part of the render key of a converged render: bump when what it holds changes.
#: 9: a sun's direct light on matte stickers from the footprint pass (sun_direct);
#: 8: the relative noise pooled only where the fitted light is (a black shadow's penumbra left
#: out); 7: a border pixel's background pooled from its neighbours' samples; 6: thin-lens
#: footprints; 5: exact footprints; 4: coated fits keep the darkest pixels; 3: laminates
#: demodulated.
CONVERGED_VERSION = "exact-9"
#: Samples per pixel, relative to the scene's, of a sticker whose smooth model was rejected.
#: Four: the path-traced noise halves (a 16-spp sticker then carries the noise of 64 spp).
FALLBACK_SPP_FACTOR = 4
#: Primary rays per pixel of the footprint pass where the exact footprint does not apply (a tent
#: or Gaussian filter, bilinear texture lookup, a thin lens blurring more than
#: :data:`~simgap.render.print_footprint.LENS_REACH_MAX_PX`, an occluder) or disagrees,
#: a fixed Sobol' pattern (:func:`simgap.render.pixel_samples.footprint_pattern`): its points are
#: stratified in 1/64 px along each pixel axis, so under a box filter an edge along an axis is
#: placed to within 1/64 px (0.0064 px RMS over the edge's sub-pixel position). 256 points took
#: 2.3x the time of 64 on a baseline configuration (p 2, 4.7 k edge pixels: 0.16 s against
#: 0.07 s) and the whole render 1.5x (docs/results/converged_render_step8.md#step-3). Before the
#: pattern was fixed (random rays per render seed), 64 rays moved the detected corners by 0.12 px
#: RMS between two render seeds (docs/results/converged_render_step8.md#step-2).
FOOTPRINT_POINTS = 64
#: Treatment of a coated print's sticker whose diffuse and specular fields were both smooth.
COATED = "smooth (coated print)"
#: Appended to a sticker's treatment where the sun's direct light was added from the footprint
#: pass (:mod:`simgap.render.sun_direct`) to the treated rest of its light.
SUN_SUFFIX = " + sun direct"


def render_version(spec: SceneSpec) -> tuple[str, ...]:
    """What a converged render of a scene holds, as part of its render key.

    :data:`CONVERGED_VERSION`, and :data:`~simgap.render.sun_direct.SUN_DIRECT_VERSION` where the
    scene has a sun (so that a change to the sun's direct pass leaves every other render's key
    as it was).
    """
    sun = (SUN_DIRECT_VERSION,) if SUN_LIGHT in spec.lights else ()
    return (CONVERGED_VERSION, *sun)


@dataclass(frozen=True)
class ConvergedRender:
    """A region's radiance and how each sticker's was made.

    Attributes
    ----------
    values : ndarray (N, 3)
        Linear RGB radiance of the pixels, in the order asked for.
    treatments : dict of int to str
        Per tag id: ``"smooth"`` (demodulated), :data:`COATED` (a laminated print demodulated),
        ``"dark"`` (no sample received light: black) or ``"fallback (<why>): <spp> spp"`` (path
        traced with more samples).
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
    sun = split_sun(scene)
    # with a sun, the stickers' samples leave its direct light out: it is added from the
    # footprint pass (sun_direct), noise-free and sharp at its shadow edges
    samples = sample_pixels(scene, pixels, seed, rest=sun is not None)
    suffix = "" if sun is None else SUN_SUFFIX
    values = samples.mean.copy()
    tags = [int(t) for t in np.unique(samples.sticker[samples.sticker >= 0])]
    coated = scene.spec.tag.coating is not None
    # the footprint pass on the pixels whose footprint may hold a print edge or the sticker's
    # border: a pixel's own samples disagree, or its samples' albedo or sticker differs from a
    # neighbour's (an edge that cuts a corner of a pixel, or crosses it near its side, misses
    # all of its few samples, but then lies between it and a neighbour that does not look alike)
    near = edge_pixels(pixels, samples)
    reach = 0.0
    if scene.lens[0] > 0.0 and exact_footprint_applies(scene):
        # a thin lens spreads a print edge over a disc: every pixel within its radius of an
        # edge pixel may hold some of the edge, whether or not its few samples saw it
        reach = max((defocus_reach_px(scene, tag) for tag in tags), default=0.0)
        near = widened(pixels, near, reach)
    background = pooled_background(pixels, samples, reach)
    footprint = edge_footprint(scene, pixels[near], samples.sticker[near], samples.coverage[near])
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
                background=background[on],
                footprint_albedo=np.where(own[:, None], footprint_albedo[on], samples.albedo[on]),
                footprint_coverage=np.where(own, footprint_coverage[on], samples.coverage[on]),
                coated=coated,
            )
        )
        direct = 0.0
        if sun is not None:
            direct = sun_direct(scene, pixels[on], np.full(len(on), tag), sun, SUN_DIRECT_POINTS)
        if result.treatment is Treatment.DARK:
            values[on] += direct
            treatments[tag] = Treatment.DARK.value + suffix
            continue
        if result.treatment is Treatment.SMOOTH:
            values[on] = result.radiance + direct
            treatments[tag] = (COATED if coated else Treatment.SMOOTH.value) + suffix
            continue
        spp = samples.spp * FALLBACK_SPP_FACTOR
        more = sample_pixels(scene, pixels[on], seed + 1 + tag, spp, rest=sun is not None)
        values[on] = more.mean + direct
        treatments[tag] = f"fallback ({result.reason}): {spp} spp{suffix}"
    return ConvergedRender(values.astype(np.float32), treatments)


@dataclass(frozen=True)
class Footprint:
    """The print over each pixel's footprint: what the demodulated radiance is made with.

    Attributes
    ----------
    sticker : ndarray of int (N,)
        The tag id of the sticker that covers most of the footprint; -1 where none does.
    coverage : ndarray (N,)
        Share of the footprint on that sticker (0-1).
    albedo : ndarray (N, 3)
        The print's mean albedo over that share (NaN where it is 0).
    exact : bool
        Clipped from the print's cells (:mod:`simgap.render.print_footprint`), not integrated
        with :data:`FOOTPRINT_POINTS` rays.
    """

    sticker: np.ndarray
    coverage: np.ndarray
    albedo: np.ndarray
    exact: bool


def edge_footprint(
    scene: FixtureScene, pixels: np.ndarray, sample_sticker: np.ndarray, sample_coverage: np.ndarray
) -> Footprint:
    """The footprint of edge pixels: exact where the scene allows it and its samples agree.

    Exact (:func:`simgap.render.print_footprint.print_footprint`) under a box filter and
    nearest texture lookup (a thin lens: averaged over points of its aperture), for every
    sticker the first pass saw, if each agrees with the first pass's samples
    (:func:`simgap.render.print_footprint.agrees`: no occluder); otherwise from
    :data:`FOOTPRINT_POINTS` primary rays of a fixed pattern
    (:func:`simgap.render.pixel_samples.footprint_samples`).

    Parameters
    ----------
    scene : FixtureScene
        A posed scene.
    pixels : ndarray of int (N, 2)
        Full-image pixel columns and rows (px).
    sample_sticker, sample_coverage : ndarray (N,)
        The first pass's sticker and coverage of these pixels (:class:`PixelSamples`).
    """
    n = len(pixels)
    if n and exact_footprint_applies(scene):
        sticker, coverage = np.full(n, -1), np.zeros(n)
        albedo = np.full((n, 3), np.nan)
        for tag in (int(t) for t in np.unique(sample_sticker[sample_sticker >= 0])):
            try:
                clipped = print_footprint(scene, pixels, tag)
            except ValueError:  # a degenerate projection (not a convex cell): the rays decide
                break
            if not agrees(clipped, sample_sticker, sample_coverage, tag):
                break
            share, mean = clipped.coverage, clipped.albedo
            more = share > coverage
            sticker[more], coverage[more], albedo[more] = tag, share[more], mean[more, None]
        else:
            return Footprint(sticker, coverage, albedo, exact=True)
    rays = footprint_samples(scene, pixels, FOOTPRINT_POINTS)
    return Footprint(rays.sticker, rays.coverage, rays.albedo, exact=False)


def _grid_coordinates(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Columns and rows of ``pixels`` (N, 2) on their bounding grid, and its shape (rows, cols)."""
    u, v = (pixels - pixels.min(axis=0)).T
    return u, v, (int(v.max()) + 1, int(u.max()) + 1)


def widened(pixels: np.ndarray, mask: np.ndarray, radius_px: float) -> np.ndarray:
    """``mask`` over ``pixels`` (N, 2) grown by a disc of ``radius_px`` plus one pixel."""
    r = int(np.ceil(radius_px)) + 1
    u, v, shape = _grid_coordinates(pixels)
    grid = np.zeros(shape, np.uint8)
    grid[v[mask], u[mask]] = 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(grid, kernel)[v, u].astype(bool)


def pooled_background(pixels: np.ndarray, samples: PixelSamples, reach_px: float) -> np.ndarray:
    """The background radiance near each pixel from its own and its neighbours' samples (N, 3).

    A pixel on a sticker's border mixes the sticker with what lies around it. Its own samples
    that left the sticker are few (one of four, or none: a pixel whose exact coverage is 0.9 has
    all four samples on the sticker about two times in three, and under a thin lens a band of
    pixels several wide), so their mean alone keeps the noise of one sample, or is missing and the
    pixel kept its raw value (the defocused sticker's render noise: 0.93 DN, three times the
    others', docs/results/converged_render_step8.md#step-5). The background around a sticker is the
    face it is stuck on, smooth over a few pixels: every background sample within
    ``ceil(reach_px) + 1`` px along each axis (a square of side twice that plus one: the pixel's
    8-neighbours; under a thin lens, the spread of its aperture's disc and one more) is pooled,
    weighted by how many of a pixel's samples it holds (linear; NaN where no sample in the
    square left a sticker). The caller passes the largest reach of the region's stickers (one or
    two tags at similar depths); a wider square only assumes the face smooth over more pixels.
    """
    r = int(np.ceil(reach_px)) + 1
    u, v, shape = _grid_coordinates(pixels)
    count = np.round((1.0 - samples.coverage) * samples.spp)
    count = np.where(np.isfinite(samples.background).all(axis=1), count, 0.0)
    # the sample-weighted radiance (3 channels) and the sample count, summed over the square at
    # once (OpenCV filters up to 4 channels in one pass)
    grid = np.zeros((*shape, 4), np.float64)
    grid[v, u, :3] = np.nan_to_num(samples.background) * count[:, None]
    grid[v, u, 3] = count
    size = (2 * r + 1, 2 * r + 1)
    summed = cv2.boxFilter(grid, -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)[v, u]
    n = summed[:, 3:]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, summed[:, :3] / n, np.nan)


def edge_pixels(pixels: np.ndarray, samples: PixelSamples) -> np.ndarray:
    """Pixels that may hold a print edge or a sticker's border, as a mask over ``pixels``.

    Marked: a pixel whose samples land on two albedos or partly off its sticker, and both of any
    two 8-neighbours that differ in their samples' albedo or sticker (one of them is then on a
    sticker).
    """
    u, v, shape = _grid_coordinates(pixels)
    kernel = np.ones((3, 3), np.uint8)
    differs = np.zeros(len(pixels), bool)
    albedo = np.where(samples.sticker[:, None] >= 0, samples.albedo, -1.0)
    for layer in (*albedo.T, samples.sticker.astype(np.float64)):
        grid = np.full(shape, np.nan, np.float32)
        grid[v, u] = layer
        # outside the region: the pixel's own value (no difference from what was not rendered)
        high = cv2.dilate(np.nan_to_num(grid, nan=-np.inf), kernel)
        low = cv2.erode(np.nan_to_num(grid, nan=np.inf), kernel)
        differs |= (high[v, u] != grid[v, u]) | (low[v, u] != grid[v, u])
    mixed = (samples.albedo_variance.max(axis=1) > 0) | (
        (samples.coverage > 0) & (samples.coverage < 1)
    )
    # every pixel off the stickers reads -1 in every layer, so two that differ include one on
    return mixed | differs
