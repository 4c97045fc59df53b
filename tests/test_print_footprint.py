"""Exact print footprints (issue 28): clipped areas, and the footprint against Mitsuba's rays."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.region import sticker_region
from simgap.render.clipping import _holds_unit_square, clipped_area
from simgap.render.converged import edge_footprint, edge_pixels, widened
from simgap.render.pixel_samples import footprint_samples, sample_pixels
from simgap.render.print_footprint import (
    LENS_REACH_MAX_PX,
    agrees,
    defocus_reach_px,
    exact_footprint_applies,
    print_footprint,
)
from simgap.render.scene import FixtureScene, projected_sticker_outlines


def _shoelace(quad: np.ndarray) -> float:
    x, y = quad[:, 0], quad[:, 1]
    return 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def _holds_by_every_corner(quads: np.ndarray) -> np.ndarray:
    """The definition: every corner of [0, 1]^2 on the inner side of every edge (M, 4, 2)."""
    edge = np.roll(quads, -1, axis=1) - quads
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    to_corner = corners[None, None] - quads[:, :, None]  # (M, 4 edges, 4 corners, 2)
    cross = edge[:, :, None, 0] * to_corner[..., 1] - edge[:, :, None, 1] * to_corner[..., 0]
    turning = np.roll(edge, -1, axis=1)
    turn = np.sign(
        np.sum(edge[..., 0] * turning[..., 1], axis=1)
        - np.sum(edge[..., 1] * turning[..., 0], axis=1)
    )
    return np.all(cross * turn[:, None, None] >= 0.0, axis=(1, 2)) & (turn != 0)


def test_holding_the_square_is_decided_as_by_every_corner_bit_for_bit():
    """The fast test takes each edge's least and greatest cross product over the corners from
    its per-axis terms: the same decision as the four corners', also where a corner lies exactly
    on an edge (vertices on a 1/8 grid) and either way round."""
    rng = np.random.default_rng(28)
    centre = rng.uniform(-1.0, 2.0, (20_000, 1, 2))
    radius = rng.uniform(0.05, 3.0, (20_000, 1, 1))
    angle = np.sort(rng.uniform(0.0, 2.0 * np.pi, (20_000, 4)), axis=1)
    quads = centre + radius * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    for q in (quads, quads[:, ::-1], np.round(quads * 8.0) / 8.0):
        expected = _holds_by_every_corner(q)
        assert 0 < expected.sum() < len(q)  # both answers occur
        np.testing.assert_array_equal(_holds_unit_square(q), expected)


def test_clipped_area_of_known_shapes():
    """Inside, outside, straddling a corner and a side, covering the square, a triangle cut."""
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    quads = np.stack(
        [
            0.25 + 0.5 * square,  # inside: 0.25
            square + [2.0, 0.0],  # outside: 0
            square + [0.3, 0.2],  # over a corner: 0.7 x 0.8
            square * [3.0, 0.5] - [1.0, 0.0],  # across, half as high: 0.5
            square * 3.0 - 1.0,  # covers the square: 1
            np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [0.0, 2.0]]),  # triangle: 1 - 0
            square,  # the square itself: 1
            np.array([[0.5, 0.0], [1.0, 0.5], [0.5, 1.0], [0.0, 0.5]]),  # touching: 0.5
            square + [1.0, 0.0],  # sharing a side: 0
        ]
    )
    expected = [0.25, 0.0, 0.56, 0.5, 1.0, 1.0, 1.0, 0.5, 0.0]
    np.testing.assert_allclose(clipped_area(quads), expected, atol=1e-12)
    # the same quadrilateral the other way round
    np.testing.assert_allclose(clipped_area(quads[:, ::-1]), clipped_area(quads), atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.floats(-0.4, 0.4), min_size=8, max_size=8),
    st.floats(0.3, 6.0) | st.integers(1, 5).map(float),
    st.floats(-3.0, 3.0) | st.integers(-3, 3).map(float),
    st.floats(-3.0, 3.0) | st.integers(-3, 3).map(float),
)
def test_clipped_areas_of_the_unit_squares_add_up_to_the_quadrilateral(jitter, size, x0, y0):
    """A convex quadrilateral (a homography of a square; corners on the grid's lines too) tiled
    by unit squares: the clipped areas over every square its box touches sum to its own area
    (float64 round-off)."""
    h = np.eye(3) + np.array([jitter[:3], jitter[3:6], [*jitter[6:8], 0.0]])
    h[2, :2] *= 0.2  # keep w > 0 over the square: the image stays convex
    corners = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]])
    image = corners @ h.T
    quad = image[:, :2] / image[:, 2:] * size + [x0, y0]
    lo, hi = np.floor(quad.min(axis=0)).astype(int), np.ceil(quad.max(axis=0)).astype(int)
    cells = np.array([(i, j) for i in range(lo[0], hi[0]) for j in range(lo[1], hi[1])], float)
    areas = clipped_area(quad[None] - cells[:, None, :])
    assert np.all(areas >= -1e-12) and np.all(areas <= 1.0 + 1e-12)
    assert areas.sum() == pytest.approx(_shoelace(quad), abs=1e-9)


def _posed(p: int, theta_deg: float, **scene_options) -> tuple[FixtureScene, np.ndarray]:
    """The baseline scene at 4 spp posed at (p, theta) and the pixels of its sticker region."""
    exp = load_experiment("experiments/baseline.yaml")
    s = exp.base_state().scene
    size = (s.camera.width, s.camera.height)
    scene = FixtureScene(
        exp.rig_model, s.spec, size, 4, errors=s.errors, camera=s.camera, **scene_options
    )
    theta = np.deg2rad(theta_deg)
    scene.set_pose(p, theta)
    outlines = projected_sticker_outlines(exp.rig_model, p, theta, s.errors, s.camera, 1.0, 8)
    return scene, sticker_region(outlines, 4, size).pixels()


def test_the_exact_footprint_is_the_rendered_print():
    """p 12, theta 40 deg and p 2, theta 0: the exact coverage and albedo of the edge pixels
    against 256 of Mitsuba's own primary rays per pixel (a Sobol' pattern, quadrature error
    about 1/256 per axis-aligned edge). Measured at four poses: coverage 0.0007-0.0013 RMS,
    0.004-0.011 at most; albedo 0.0007-0.0013 RMS, 0.005-0.013 at most. Bounds: 3x the RMS,
    2x the largest."""
    for p, theta in ((12, 40.0), (2, 0.0)):
        scene, pixels = _posed(p, theta)
        assert exact_footprint_applies(scene)
        samples = sample_pixels(scene, pixels, seed=3)
        near = edge_pixels(pixels, samples)
        rays = footprint_samples(scene, pixels[near], 256)
        clipped = print_footprint(scene, pixels[near], 0)
        coverage, albedo = clipped.coverage, clipped.albedo
        assert agrees(clipped, samples.sticker[near], samples.coverage[near], 0)
        # a pinhole sees every pixel through one point: its coverage is its extremes
        assert np.array_equal(clipped.least, coverage) and np.array_equal(clipped.most, coverage)
        on = rays.sticker == 0
        assert on.sum() > 1000
        dc = coverage[on] - rays.coverage[on]
        da = albedo[on] - rays.albedo[on, 0]
        assert np.sqrt(np.mean(dc**2)) < 0.004 and np.abs(dc).max() < 0.022
        assert np.sqrt(np.mean(da**2)) < 0.004 and np.abs(da).max() < 0.027
        # no ray found the sticker where the geometry puts none of it
        assert not np.any(rays.sticker[coverage == 0] == 0)
        footprint = edge_footprint(
            scene, pixels[near], samples.sticker[near], samples.coverage[near]
        )
        assert footprint.exact
        np.testing.assert_array_equal(footprint.coverage[on], coverage[on])


def test_a_geometry_the_render_does_not_share_falls_back_to_rays():
    """The footprint computed for a camera 2 % longer than the one that rendered: pixels the
    geometry puts wholly on the sticker have samples off it, so the edge footprint is taken
    from rays (as it is for an occluder)."""
    scene, pixels = _posed(12, 40.0)
    samples = sample_pixels(scene, pixels, seed=3)
    near = edge_pixels(pixels, samples)
    camera = scene.camera_model
    scene.camera_model = dataclasses.replace(camera, fx=camera.fx * 1.02, fy=camera.fy * 1.02)
    clipped = print_footprint(scene, pixels[near], 0)
    assert not agrees(clipped, samples.sticker[near], samples.coverage[near], 0)
    footprint = edge_footprint(scene, pixels[near], samples.sticker[near], samples.coverage[near])
    assert not footprint.exact


def test_a_thin_lens_footprint_is_the_rendered_print():
    """p 12, theta 40 deg through a thin lens (aperture radius 2 mm, focused at 0.6 m; blur
    radius 0.75 px): the footprint averaged over 64 aperture points against 1024 of Mitsuba's
    own primary rays per pixel (pixel and aperture sampled) on the pixels within the blur of an
    edge. Measured: coverage 0.0007 RMS, albedo 0.0009 RMS (the 64-ray pattern and the samples'
    own albedo, before: 0.0088 and 0.0072). Bounds: 3x the RMS; 0.01 on the largest (measured
    0.008 for both)."""
    scene, pixels = _posed(12, 40.0, lens=(0.002, 0.6))
    assert exact_footprint_applies(scene)
    assert defocus_reach_px(scene, 0) == pytest.approx(0.75, abs=0.05)
    samples = sample_pixels(scene, pixels, seed=3)
    band = widened(pixels, edge_pixels(pixels, samples), defocus_reach_px(scene, 0))
    rays = footprint_samples(scene, pixels[band], 1024)
    clipped = print_footprint(scene, pixels[band], 0)
    coverage, albedo = clipped.coverage, clipped.albedo
    assert np.all(clipped.least <= coverage + 1e-12) and np.all(clipped.most >= coverage - 1e-12)
    for seed in (3, 4, 5):  # whole and empty pixels told by the rim: no seed sees otherwise
        other = sample_pixels(scene, pixels[band], seed=seed)
        assert agrees(clipped, other.sticker, other.coverage, 0)
    on = rays.sticker == 0
    dc, da = coverage[on] - rays.coverage[on], albedo[on] - rays.albedo[on, 0]
    assert np.sqrt(np.mean(dc**2)) < 0.0021 and np.abs(dc).max() < 0.016
    assert np.sqrt(np.mean(da**2)) < 0.0027 and np.abs(da).max() < 0.016


def test_a_wide_blur_takes_the_footprint_from_rays():
    """A 5 mm aperture focused at 5 m blurs the near tag over tens of pixels: its band would be
    the whole sticker at 64 clippings a pixel, so the 64 rays decide."""
    scene, _ = _posed(0, 0.0, lens=(0.005, 5.0))
    assert defocus_reach_px(scene, 0) > LENS_REACH_MAX_PX
    assert not exact_footprint_applies(scene)
