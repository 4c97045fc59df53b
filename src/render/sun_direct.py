"""The sun's direct light on a matte sticker, apart from the rest of its light.

A directional light's direct radiance at a diffuse point is ``albedo E cos(t) V / pi`` (``E``
the irradiance on a surface facing it, W m^-2; ``t`` the angle between the surface's normal and
the light; ``V`` the visibility of the light from the point, 0 or 1). For a disc of uniform
radiance (the sun's 0.53 deg) it is the mean of that over the disc's directions. This needs no
Monte Carlo samples: :func:`sun_direct` evaluates it over each pixel's footprint with the fixed
point pattern of the footprint pass (:func:`simgap.render.pixel_samples.footprint_pattern`) and
one shadow ray per point, each towards one point of a fixed pattern over the disc:
the same for every render seed, and as sharp at a shadow edge as the geometry (a first pass
with fewer points settles the flat pixels, :func:`settled`).

The rest of a sticker's light (the sky, light reflected by other surfaces, the sun's included)
is what :func:`rest_trace` returns for a camera sample whose primary ray lands on a sticker: the
print's BSDF is sampled at the hit and the scene's integrator, one bounce shorter, continues
from there (the primary hit makes no emitter sample, so the sun's direct light, which only an
emitter sample reaches, is left out; a continuation that hits the sun's disc counts nothing).
Samples elsewhere are traced as usual. That rest is smooth across the sun's shadow edge and is
demodulated as any sticker's light (:mod:`simgap.render.converged`).

Used for a scene with a ``sun`` light (:data:`SUN_LIGHT`, a directional light), a matte print
(no coating) and a ``path`` integrator; every other scene is rendered without it
(:func:`split_sun`).
"""

from __future__ import annotations

import functools
import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

from simgap.core.transforms import perpendicular_axes
from simgap.render.mitsuba_scene import DISTANT_DISC_M
from simgap.render.pixel_samples import STICKER_PREFIX, footprint_pattern

if TYPE_CHECKING:
    from simgap.render.scene import FixtureScene
    from simgap.scene.lights import LightSpec

#: The name of the light whose direct part is split off (the ``sun`` effect's).
SUN_LIGHT = "sun"
#: Points per pixel of :func:`sun_direct` in the converged render: the footprint pattern's, each
#: with its own direction over the sun's disc. Against 4096 points, over the sticker of
#: corner_p6 (docs/results/shadow_edge.md), the direct term's error (share of the lit paper's)
#: with 64 / 256 / 1024 points: RMS 0.61 / 0.26 / 0.12 %, max 7.9 / 3.0 / 1.3 % under the
#: 0.533 deg disc (its penumbra), RMS 0.17 / 0.05 / 0.01 %, max 2.6 / 0.8 / 0.2 % under parallel
#: rays; on the 44 k pixels of top_edge it took 0.23 / 0.77 / 3.5 s.
SUN_DIRECT_POINTS = 256
#: Part of the render key of a converged render under a sun (:func:`simgap.render.converged.
#: render_version`): bump when what :func:`sun_direct` returns changes. adaptive-1: a coarse
#: first pass, the full pattern only where a pixel is not settled.
SUN_DIRECT_VERSION = "adaptive-1"
#: Points per pixel of :func:`sun_direct`'s first pass: a pixel it settles (:func:`settled`)
#: keeps that value, every other one takes :data:`SUN_DIRECT_POINTS`.
SUN_COARSE_POINTS = 16
#: Two values agree when they differ by at most this share of the largest (a pixel's and its
#: neighbours' over the region; the albedos of a pixel's points): on a flat matte print the
#: cosine changes far less over a pixel, and a print's albedo is one value per cell.
SUN_SETTLED_RTOL = 1e-4
#: A pixel within this many pixels (a square) of one whose points disagreed or whose value
#: differs from a neighbour's takes the full pattern too (px): a disc's penumbra fades over
#: several pixels, and its faint end escapes the coarse directions.
SUN_SETTLED_REACH_PX = 3
#: Scrambling seed of the fixed pattern of directions over the sun's disc (:func:`disc_pattern`).
DISC_PATTERN_SEED = 29
#: Shadow rays towards a distant disc stop this far short of it (m): the disc is a shape of the
#: scene and would occlude them.
DISC_SHADOW_MARGIN_M = 1.0

_REST_INTEGRATORS: weakref.WeakKeyDictionary[Any, Any] = weakref.WeakKeyDictionary()


def split_sun(scene: FixtureScene) -> LightSpec | None:
    """The scene's sun if its direct light is split off, else None.

    Split off where the scene has a directional :data:`SUN_LIGHT` light, the print has no
    coating (its BSDF is diffuse) and the integrator is a ``path`` tracer of depth 2 or more
    (or unlimited).
    """
    light = scene.spec.lights.get(SUN_LIGHT)
    if light is None or light.type != "directional" or scene.spec.tag.coating is not None:
        return None
    integrator = scene.integrator_dict
    depth = int(integrator.get("max_depth", -1))
    if integrator.get("type") != "path" or depth in (0, 1):
        return None
    return light


def _rest_integrator(scene: FixtureScene):
    """The scene's integrator one bounce shorter (it continues paths from the primary hit)."""
    if scene not in _REST_INTEGRATORS:
        settings = dict(scene.integrator_dict)
        depth = int(settings.get("max_depth", -1))
        settings["max_depth"] = depth - 1 if depth > 0 else -1
        if "rr_depth" in settings:
            settings["rr_depth"] = max(int(settings["rr_depth"]) - 1, 1)
        _REST_INTEGRATORS[scene] = scene.mi.load_dict(settings)
    return _REST_INTEGRATORS[scene]


def _shape(scene: FixtureScene, name: str):
    """The loaded shape called ``name``, or None."""
    return next((s for s in scene.scene.shapes() if s.id() == name), None)


def _on_sticker(scene: FixtureScene, hit):
    """Dr.Jit mask: the hit is on a sticker."""
    on = scene.mi.Bool(False)
    for shape in scene.scene.shapes():
        if shape.id().startswith(STICKER_PREFIX):
            on |= hit.shape == scene.mi.ShapePtr(shape)
    return on


def rest_trace(scene: FixtureScene, pixels: np.ndarray, seed: int, spp: int):
    """Camera samples' radiance without the sun's direct light on the stickers (Dr.Jit values).

    As :meth:`simgap.render.scene.PixelTracer.trace` (primary rays, radiance per sample); a
    sample whose primary ray lands on a sticker carries the sticker's light less the sun's
    direct part (module docstring), any other sample the integrator's radiance.
    """
    import drjit as dr

    mi = scene.mi
    ray, sampler = scene.camera_rays(pixels, seed, spp)
    hit = scene.scene.ray_intersect(ray)
    on = _on_sticker(scene, hit)
    bs, weight = hit.bsdf().sample(
        mi.BSDFContext(), hit, sampler.next_1d(on), sampler.next_2d(on), on
    )
    onward = hit.spawn_ray(hit.to_world(bs.wo))
    full, _, _ = scene.scene.integrator().sample(
        scene.scene, sampler, mi.RayDifferential3f(ray), None, ~on
    )
    rest, _, _ = _rest_integrator(scene).sample(
        scene.scene, sampler, mi.RayDifferential3f(onward), None, on
    )
    disc = _shape(scene, f"light_{SUN_LIGHT}")
    if disc is not None:  # the disc's light is the direct term's
        reached = scene.scene.ray_intersect(onward, on)
        weight = dr.select(reached.shape == mi.ShapePtr(disc), 0.0, weight)
    return ray, dr.select(on, weight * rest, full)


@functools.lru_cache(maxsize=8)
def disc_pattern(points: int, half_angle_rad: float) -> np.ndarray:
    """Fixed offsets over a disc of ``half_angle_rad`` (rad) seen from its centre (points, 2).

    The tangents of the angles from the disc's centre along two perpendicular axes, uniform over
    the disc (an Owen-scrambled Sobol' set, seed :data:`DISC_PATTERN_SEED`, mapped by area, in
    an order shuffled with the same seed, independent of the footprint pattern's): directions
    uniform in solid angle to within ``half_angle^2`` (the sun's: 2e-5).
    """
    from scipy.stats import qmc

    if half_angle_rad == 0.0:
        return np.zeros((points, 2))
    sobol = qmc.Sobol(d=2, scramble=True, seed=DISC_PATTERN_SEED)
    u = sobol.random_base2(int(points).bit_length() - 1)
    # shuffled: the footprint pattern's points are the same Sobol' points under another
    # scrambling, so in the same order a point's place in the pixel would decide its place on
    # the disc (the penumbra came out too narrow: 1-2 % of the lit paper at its ends)
    u = u[np.random.default_rng(DISC_PATTERN_SEED).permutation(len(u))]
    r, phi = np.tan(half_angle_rad) * np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    offsets = np.stack([r * np.cos(phi), r * np.sin(phi)], -1)
    offsets.flags.writeable = False  # cached: shared by every call
    return offsets


def sun_points(light: LightSpec, points: int) -> tuple[np.ndarray, bool]:
    """Where each pattern point's shadow ray aims (points, 3), and whether at a distant disc.

    Parallel rays (``angular_diameter_deg`` 0): the unit vector towards the light (rail frame),
    the same for every point. A disc: points of the emitting disk that renders it
    (:func:`simgap.render.mitsuba_scene.distant_disc`, :data:`DISTANT_DISC_M` away; m, rail
    frame) at the offsets of :func:`disc_pattern`, so that each shading point sees the disc
    where the path tracer's emitter is.
    """
    target, towards = np.asarray(light.target, float), light.towards()
    if light.angular_diameter_deg == 0:
        return np.tile(towards, (points, 1)), False
    e1, e2 = perpendicular_axes(towards)
    offsets = disc_pattern(points, float(np.radians(light.angular_diameter_deg) / 2))
    centre = target + DISTANT_DISC_M * towards
    return centre + DISTANT_DISC_M * (offsets[:, :1] * e1 + offsets[:, 1:] * e2), True


def sun_direct(
    scene: FixtureScene, pixels: np.ndarray, tags: np.ndarray, light: LightSpec, points: int
) -> np.ndarray:
    """The sun's direct radiance from each pixel's sticker, over its footprint (N, 3).

    The mean over ``points`` fixed primary rays per pixel (the footprint pattern) of
    ``albedo E rgb cos(t) V / pi`` where the ray lands on the sticker ``tags[i]`` (0 elsewhere:
    the pixel's coverage is in the mean), each with one shadow ray towards one direction over
    the sun's disc (:func:`sun_points`). Linear RGB radiance (W m^-2 sr^-1 x the light's
    tint), the same for every render seed.

    Evaluated first with :data:`SUN_COARSE_POINTS` points per pixel; a pixel keeps that value
    only where it is settled (:func:`settled`: its points are all lit on one albedo or all
    unlit, and its neighbours' values agree with its own), which on a flat print in full sun or
    full shadow is the value the full pattern gives to within the cosine's change over the
    pixel and the disc. Every other pixel (a print edge, a shadow edge or penumbra, the
    sticker's border) takes the full ``points``.

    Parameters
    ----------
    scene : FixtureScene
        A posed scene.
    pixels : ndarray of int (N, 2)
        Full-image pixel columns and rows (px).
    tags : ndarray of int (N,)
        The tag id of each pixel's sticker.
    light : LightSpec
        The sun (:func:`split_sun`).
    points : int
        Points per pixel (a power of two).
    """
    pixels = np.asarray(pixels).reshape(-1, 2)
    tags = np.asarray(tags).reshape(-1)
    coarse = min(SUN_COARSE_POINTS, points)
    total, agreed = sun_direct_pattern(scene, pixels, tags, light, coarse)
    refine = ~settled(pixels, total, agreed) if coarse < points else np.zeros(len(pixels), bool)
    if refine.any():
        total[refine] = sun_direct_pattern(scene, pixels[refine], tags[refine], light, points)[0]
    return total


def settled(pixels: np.ndarray, values: np.ndarray, agreed: np.ndarray) -> np.ndarray:
    """Pixels whose coarse value stands for their footprint (N,) bool.

    A pixel is settled where its own points agreed (``agreed``) and no pixel of the set within
    :data:`SUN_SETTLED_REACH_PX` (px, a square) is unsettled in that way or holds another value
    (beyond :data:`SUN_SETTLED_RTOL` of the largest value): an edge that cuts off less of a
    pixel than the coarse points resolve, or a penumbra's faint end, still differs from a
    neighbour's value.

    Parameters
    ----------
    pixels : ndarray of int (N, 2)
        Pixel columns and rows (px).
    values : ndarray (N, 3)
        The coarse values.
    agreed : ndarray of bool (N,)
        Whether every coarse point of each pixel was lit on one albedo, or none was
        (:func:`sun_direct_pattern`).
    """
    from scipy.ndimage import binary_dilation, maximum_filter, minimum_filter

    if len(pixels) == 0:
        return np.zeros(0, bool)
    lum = values.sum(axis=1)
    tol = SUN_SETTLED_RTOL * max(float(lum.max()), 1e-30)
    lo = pixels.min(axis=0)
    cols, rows = (pixels - lo).T
    shape = (int(rows.max()) + 1, int(cols.max()) + 1)
    grid = np.full(shape, np.nan)
    grid[rows, cols] = lum
    present = ~np.isnan(grid)
    high = maximum_filter(np.where(present, grid, -np.inf), size=3)
    low = minimum_filter(np.where(present, grid, np.inf), size=3)
    differs = (high - grid > tol) | (grid - low > tol)  # False where absent (NaN)
    unsettled = np.zeros(shape, bool)
    unsettled[rows, cols] = ~agreed
    unsettled |= differs & present
    reach = SUN_SETTLED_REACH_PX - 1
    if reach > 0:
        unsettled = binary_dilation(unsettled, np.ones((2 * reach + 1,) * 2, bool))
    return ~unsettled[rows, cols]


def sun_direct_pattern(
    scene: FixtureScene, pixels: np.ndarray, tags: np.ndarray, light: LightSpec, points: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sun_direct` with ``points`` per pixel everywhere, and whether each pixel's agreed.

    Returns
    -------
    radiance : ndarray (N, 3)
        The mean over the pixel's points (as :func:`sun_direct`).
    agreed : ndarray of bool (N,)
        Whether every point of the pixel was lit on one albedo, or none was.
    """
    import drjit as dr

    from simgap.render.scene import launches

    mi = scene.mi
    n = len(pixels)
    pattern = footprint_pattern(points)
    aims, disc = sun_points(light, points)
    ids = {
        shape.id(): shape for shape in scene.scene.shapes() if shape.id().startswith(STICKER_PREFIX)
    }
    total = np.zeros((n, 3))
    agreed = np.ones(n, bool)
    for start, padded, _ in launches(pixels, 0, points, 2):
        m = min(len(padded), n - start)
        ray, _ = scene.camera_rays(padded, 0, None, pattern)
        hit = scene.scene.ray_intersect(ray)
        tiled = np.tile(aims, (len(padded), 1))
        aim = mi.Vector3f(tiled[:, 0], tiled[:, 1], tiled[:, 2])
        if disc:
            distance = dr.norm(aim - hit.p)
            towards = (aim - hit.p) / distance
        else:
            towards = aim
        # the tag each lane must land on: its pixel's
        wanted = np.resize(tags[start : start + m], len(padded)).astype(np.int32)
        want = dr.gather(
            mi.Int32, mi.Int32(wanted), dr.arange(mi.UInt32, len(padded) * points) // points
        )
        on = mi.Bool(False)
        for name, shape in ids.items():
            tag = int(name[len(STICKER_PREFIX) :])
            on |= (hit.shape == mi.ShapePtr(shape)) & (want == tag)
        cos = dr.dot(hit.sh_frame.n, towards)
        lit = on & (cos > 0)
        shadow = hit.spawn_ray(towards)
        if disc:
            shadow.maxt = distance - DISC_SHADOW_MARGIN_M
        lit &= ~scene.scene.ray_test(shadow, lit)
        albedo = hit.bsdf().eval_diffuse_reflectance(hit, lit)
        value = dr.select(lit, albedo * cos, 0.0)
        dr.eval(value)
        rgb = np.stack([np.asarray(c, np.float64) for c in (value.x, value.y, value.z)], -1)
        total[start : start + m] = rgb.reshape(-1, points, 3)[:m].mean(axis=1)
        # agreed: every point lit with one albedo, or none lit (the cosine differs between the
        # directions over the disc, by up to its half-angle)
        shade = np.asarray(dr.select(lit, albedo.x + albedo.y + albedo.z, -1.0), np.float64)
        shade = shade.reshape(-1, points)[:m]
        spread = shade.max(axis=1) - shade.min(axis=1)
        agreed[start : start + m] = spread <= SUN_SETTLED_RTOL * max(float(shade.max()), 1e-30)
    return total * np.asarray(light.rgb, float) * light.irradiance / np.pi, agreed
