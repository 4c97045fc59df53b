"""A hard shadow edge across a sticker, in a converged render, lies where the geometry puts it.

The geometric boundary is ray cast in the loaded Mitsuba scene (the sticker's surface towards the
sun, :func:`shadow_edge.shadow_boundary`) and projected with the rig's camera; the rendered edge is
where the paper's luminance crosses half-way between the lit and the shadowed paper, along image
columns through the sticker's white quiet zone (benchmarks/shadow_edge.py, whose helpers are
imported here; docs/results/shadow_edge.md).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from simgap.pipeline.experiment import VariantSpec
from simgap.pipeline.variant import clear_scenes
from simgap.render import sun_direct as sun_direct_module
from simgap.render.sun_direct import (
    SUN_COARSE_POINTS,
    SUN_DIRECT_POINTS,
    settled,
    split_sun,
    sun_direct,
    sun_direct_pattern,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from shadow_edge import (  # noqa: E402  (the benchmark's cases and ray casting)
    SunCase,
    case_pipelines,
    luminance,
    paper_levels,
    shadow_boundary,
    sticker_to_image,
    sun_experiment,
)

#: The camera body's top edge across tag 0 (45 % shadowed), the turntable turned 20 deg so that
#: the edge runs 1.4 deg off the pixel rows.
CASE = SunCase("slanted_edge", 0, 20.0, 195.0, 8.0)
#: Sky radiance (W m^-2 sr^-1): the shadowed paper at 0.27 of the lit.
SKY = 200.0
#: Rows searched on either side of the geometric edge (px).
HALF_WINDOW_PX = 6
#: Share of the quiet zone's width left out at either side (the print's and the sticker's edges).
QUIET_ZONE_MARGIN = 0.1


@pytest.fixture
def no_scenes_left():
    """Drop the Mitsuba scenes this test built (each one alive slows every later launch)."""
    yield
    clear_scenes()


def edge_offsets(
    scene, hdr: np.ndarray, offset: tuple[int, int], case: SunCase
) -> tuple[np.ndarray, float]:
    """Per image column through the quiet zone: rendered edge - geometric edge (px).

    Along each column the rendered edge is the half-way crossing between the lit and the
    shadowed paper's luminance (:func:`shadow_edge.paper_levels`) nearest the geometric edge,
    linearly interpolated between pixel centres; the distance is taken perpendicular to the edge.

    Returns
    -------
    offsets : ndarray (M,)
        Signed distances (px; positive: the rendered edge lies further down the image).
    slope : float
        The geometric edge's slope in the image (rows per column).
    """
    rig = scene.rig
    cells = rig.marker_cells() + 2 * rig.tags.quiet_zone_cells
    inner = 1.0 - 2.0 * rig.tags.quiet_zone_cells / cells  # where the marker's border begins
    keep = QUIET_ZONE_MARGIN * (1.0 - inner)
    lit, shade = paper_levels(scene, case, hdr, offset)
    boundary = shadow_boundary(scene, case)
    y = luminance(hdr)
    offsets, slopes = [], []
    for side in (-1.0, 1.0):
        x = side * boundary[:, 0]
        uv = sticker_to_image(scene, case.tag, boundary[(x > inner + keep) & (x < 1.0 - keep)])
        uv = uv[np.argsort(uv[:, 0])]
        slope = float(np.polyfit(uv[:, 0], uv[:, 1], 1)[0])
        slopes.append(slope)
        for u in range(int(np.ceil(uv[0, 0])), int(np.floor(uv[-1, 0])) + 1):
            geometric = float(np.interp(u, uv[:, 0], uv[:, 1]))
            rows = np.arange(-HALF_WINDOW_PX, HALF_WINDOW_PX + 1) + int(round(geometric))
            level = (y[rows - offset[1], u - offset[0]] - shade) / (lit - shade) - 0.5
            k = np.flatnonzero(np.sign(level[:-1]) != np.sign(level[1:]))
            crossings = rows[k] + level[k] / (level[k] - level[k + 1])
            if len(crossings):
                nearest = crossings[np.argmin(np.abs(crossings - geometric))]
                offsets.append((nearest - geometric) * np.cos(np.arctan(slope)))
    return np.asarray(offsets), float(np.mean(slopes))


def test_a_shadow_edge_on_a_sticker_lies_where_the_geometry_puts_it(tmp_path, no_scenes_left):
    """One converged render (4 spp, the baseline's) under parallel rays: the sticker's light
    less the sun's direct part demodulated as smooth, the sun's direct light added from the
    footprint pass with its shadow rays (the sun's disc would soften the edge into a penumbra
    about 13 px wide whose half-way point is the same geometric edge). Measured at render seeds
    0-2: the rendered edge 0.085-0.091 px above the geometric one (median over the 43 columns),
    every column within 0.2 px; the 1024-spp reference 0.08 px. The issue asks 1 px; moving the
    geometry's sun by 0.05 deg in elevation moves the median by 1.2-1.4 px
    (docs/results/shadow_edge.md).
    """
    exp = sun_experiment((CASE,), SKY).with_render(mode="converged", spp=4)
    pipe = case_pipelines(exp, tmp_path)[CASE.name]
    hdr, offset = pipe.hdr(CASE.p, CASE.theta, 0)
    (treatment,) = pipe.sticker_treatments  # the one sticker facing the camera
    assert treatment == "smooth + sun direct"  # the rest demodulated, the sun's direct light added
    offsets, slope = edge_offsets(pipe.scene(), hdr, offset, CASE)
    assert len(offsets) >= 40 and 0.01 < abs(slope) < 0.1  # both strips; not along a pixel row
    assert abs(np.median(offsets)) <= 1.0
    assert np.mean(np.abs(offsets) <= 1.0) >= 0.9


@pytest.mark.parametrize("diameter_deg", [0.0, 0.533])
def test_the_sun_pass_keeps_its_coarse_value_only_where_the_full_pattern_agrees(
    tmp_path, no_scenes_left, monkeypatch, diameter_deg
):
    """The sun's direct pass over the slanted edge's whole region, under parallel rays and under
    the sun's disc (a penumbra about 13 px wide): evaluated first with 16 points a pixel and the
    full 256 only where a pixel is not settled, it equals the full pattern everywhere to within
    1e-3 of the lit paper (measured: 1.4e-9 under parallel rays, 1.2e-4 under the disc, at the
    penumbra's faint end; the full pattern's own error against 4096 points reaches 3 % there,
    docs/results/shadow_edge.md), while most pixels are settled (measured: 84 % and 82 %).
    """
    sun = {**CASE.sun(), "angular_diameter_deg": diameter_deg}
    exp = dataclasses.replace(
        sun_experiment((CASE,), SKY), variants=(VariantSpec(CASE.name, {"sun": sun}),)
    )
    pipe = case_pipelines(exp, tmp_path)[CASE.name]
    scene = pipe.scene()
    scene.set_pose(CASE.p, CASE.theta)
    pixels = pipe.region(CASE.p, CASE.theta).pixels()
    light, tags = split_sun(scene), np.full(len(pixels), CASE.tag)
    adaptive = sun_direct(scene, pixels, tags, light, SUN_DIRECT_POINTS)
    coarse, agreed = sun_direct_pattern(scene, pixels, tags, light, SUN_COARSE_POINTS)
    share = float(np.mean(settled(pixels, coarse, agreed)))
    monkeypatch.setattr(sun_direct_module, "SUN_COARSE_POINTS", SUN_DIRECT_POINTS)
    full = sun_direct(scene, pixels, tags, light, SUN_DIRECT_POINTS)
    lit = np.percentile(full.sum(axis=1), 99)
    assert np.abs(adaptive - full).sum(axis=1).max() <= 1e-3 * lit
    assert share >= 0.5
