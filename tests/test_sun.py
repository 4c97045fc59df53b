"""Lights of the operational environment: the sun and the Earth as distant discs, a black sky, a
regolith ground; rendered irradiance against the analytic one."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simgap.core.rig import load_rig
from simgap.effects import make_effect
from simgap.effects.scene import (
    LAB_LIGHTS,
    LAB_OBJECTS,
    SOLAR_CONSTANT_W_M2,
    SUN_ANGULAR_DIAMETER_DEG,
    sun_direction,
)
from simgap.effects.state import VariantState
from simgap.scene.lights import LightSpec, irradiance
from simgap.scene.spec import TABLE_TOP_Z_M, Ground, load_scene_spec


def _rotated(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``v`` turned by ``angle`` (rad) about ``axis`` (Rodrigues)."""
    axis = axis / np.linalg.norm(axis)
    return (
        v * np.cos(angle)
        + np.cross(axis, v) * np.sin(angle)
        + axis * np.dot(axis, v) * (1 - np.cos(angle))
    )


def test_the_sun_effect_places_a_distant_light_towards_its_direction():
    state = make_effect("sun", {"azimuth_deg": 90.0, "elevation_deg": 30.0}).apply(VariantState())
    sun = state.scene.spec.lights["sun"]
    assert sun.type == "directional" and sun.irradiance == SOLAR_CONSTANT_W_M2
    towards = np.asarray(sun.position) - np.asarray(sun.target)
    np.testing.assert_allclose(towards, [np.cos(np.radians(30)), 0.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(sun_direction(0.0, 90.0), [0.0, 0.0, 1.0], atol=1e-12)
    # the analytic irradiance: E cos(t) on the side facing it, nothing behind; edge-on, the
    # half of the 0.533 deg disc above the horizon: E 2 a / (3 pi) for the half-angle a
    normals = np.array([towards, -towards, [0.0, 1.0, 0.0]])
    e = irradiance(dataclasses.replace(sun, rgb=(1.0, 1.0, 1.0)), np.zeros((3, 3)), normals)
    np.testing.assert_allclose(e[:2], [SOLAR_CONSTANT_W_M2, 0.0], atol=1e-9)
    edge_on = SOLAR_CONSTANT_W_M2 * 2 * np.radians(SUN_ANGULAR_DIAMETER_DEG / 2) / (3 * np.pi)
    assert e[2] == pytest.approx(edge_on, rel=1e-3)  # 1.34 W m^-2


class _TagPaper:
    """Tag 0's paper at (p 0, theta 0) rendered (Mitsuba) with chosen lights and objects.

    ``mean`` is the mean radiance over the paper pixels of the sticker's inner part, chosen
    once from the first (noise-free) render.
    """

    side = 200

    def __init__(self) -> None:
        from simgap.render.scene import pose_transforms, projected_sticker_boxes

        self.rig, self.spec = load_rig(), load_scene_spec()
        tag = pose_transforms(self.rig, 0, 0.0)["tag_0"]
        self.normal, self.up = tag[:3, 2] / np.linalg.norm(tag[:3, 2]), tag[:3, 1]
        box = projected_sticker_boxes(self.rig, 0, 0.0)[0]
        self.u0, self.v0, self.u1, self.v1 = (int(round(x)) for x in box)
        self.offset = ((self.u0 + self.u1 - self.side) // 4 * 2,
                       (self.v0 + self.v1 - self.side) // 4 * 2)  # fmt: skip
        self.paper: np.ndarray | None = None

    def mean(self, lights: dict, objects=None, ground=None, spp: int = 16) -> float:
        from simgap.render.scene import FixtureScene

        spec = dataclasses.replace(self.spec, lights=lights, ground=ground)
        if objects is not None:
            spec = spec.without_objects(*(set(spec.objects) - set(objects)))
        scene = FixtureScene(self.rig, spec, (self.side, self.side), spp)
        scene.set_pose(0, 0.0)
        img = scene.render(self.offset, seed=1).mean(axis=2)
        (x0, y0) = self.offset
        inner = img[self.v0 - y0 + 3 : self.v1 - y0 - 3, self.u0 - x0 + 3 : self.u1 - x0 - 3]
        if self.paper is None:
            self.paper = inner > 0.5 * inner.max()
        return float(np.mean(inner[self.paper]))


def _distant(direction: np.ndarray, irradiance_w_m2: float, diameter_deg: float) -> LightSpec:
    return LightSpec("directional", position=tuple(direction), target=(0.0, 0.0, 0.0),
                     irradiance=irradiance_w_m2, angular_diameter_deg=diameter_deg)  # fmt: skip


@pytest.fixture(scope="module")
def tag_paper() -> _TagPaper:
    return _TagPaper()


@pytest.mark.parametrize("diameter_deg", [0.0, SUN_ANGULAR_DIAMETER_DEG])
@pytest.mark.parametrize("angle_deg", [30.0, 60.0])
def test_a_tags_paper_under_the_sun_follows_the_cosine_law(tag_paper, angle_deg, diameter_deg):
    """Rendered (16 spp): tag 0's paper with the sun alone, along its normal and ``angle_deg``
    off it (turned about the tag's vertical axis), as parallel rays and as the sun's 0.53 deg
    disc (a distant disk). Measured: 0.8660 and 0.5000 of the facing radiance either way (cos
    30 deg 0.8660, cos 60 deg 0.5), where the issue asks 1 %; the disc's facing paper is
    within 0.005 % of the parallel rays'."""
    facing = tag_paper.mean({"sun": _distant(tag_paper.normal, 10.0, diameter_deg)})
    turned_dir = _rotated(tag_paper.normal, tag_paper.up, np.radians(angle_deg))
    turned = tag_paper.mean({"sun": _distant(turned_dir, 10.0, diameter_deg)})
    assert turned / facing == pytest.approx(np.cos(np.radians(angle_deg)), rel=0.01)
    if diameter_deg:
        point = tag_paper.mean({"sun": _distant(tag_paper.normal, 10.0, 0.0)})
        assert facing / point == pytest.approx(1.0, abs=5e-4)


def test_the_earth_fills_its_cone_and_gives_its_irradiance(tag_paper):
    """The Earth from 400 km (140.4 deg wide, a distant sphere) facing the tag, with only the
    node left (the turntable would hide part of so wide a disc): the paper's radiance over the
    sun's at the same facing irradiance. Measured 1.0046 at 64 spp (1.0007 at 256; a flat
    disk sampled by area gave 0.948 at 16 spp); 1 % allowed."""
    earth = make_effect("earthshine", {}).apply(VariantState()).scene.spec.lights["earth"]
    sin_half = 6371.0 / (6371.0 + 400.0)
    assert earth.angular_diameter_deg == pytest.approx(2 * np.degrees(np.arcsin(sin_half)))
    assert earth.irradiance == pytest.approx(0.30 * SOLAR_CONSTANT_W_M2 * sin_half**2)  # 361
    node = ("node",)
    sun = tag_paper.mean({"sun": _distant(tag_paper.normal, 10.0, 0.0)}, node, spp=64)
    disc = _distant(tag_paper.normal, 10.0, earth.angular_diameter_deg)
    assert tag_paper.mean({"earth": disc}, node, spp=64) / sun == pytest.approx(1.0, abs=0.01)


def test_the_analytic_irradiance_of_a_wide_disc_cut_by_the_horizon():
    """A disc wholly above the horizon gives ``E cos(t)``; one the horizon cuts more than its
    cosine (the part below gave negative cosines) and something at 90 deg, continuously."""
    disc = _distant(np.array([0.0, 0.0, 1.0]), 100.0, 140.0)
    t = np.radians([0.0, 19.9, 20.1, 60.0, 90.0, 160.5])
    normals = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], axis=1)
    e = irradiance(disc, np.zeros((len(t), 3)), normals)
    np.testing.assert_allclose(e[:3], 100 * np.cos(t[:3]), rtol=1e-6)  # whole: the cosine law
    assert e[3] > 100 * np.cos(t[3]) and e[4] > 0  # cut by the horizon
    assert e[5] == pytest.approx(0.0, abs=1e-9)  # wholly below


def test_a_regolith_ground_adds_the_bounce_of_a_lambertian_plane(tag_paper):
    """The sun 30 deg above the tag's normal, the node alone on a regolith ground (albedo
    0.12): a vertical surface sees the lit ground fill its lower half, ``rho E sin(el) / 2``
    more than its direct ``E cos(el)``: 1.03464 of the ground-free paper. Measured 1.034641
    (16 spp; the bounce of a uniform plane is nearly noise-free); 0.1 % allowed."""
    el = np.radians(30.0)
    sun = {"sun": _distant(np.cos(el) * tag_paper.normal + np.sin(el) * np.array([0, 0, 1.0]),
                           10.0, 0.0)}  # fmt: skip
    state = make_effect("regolith", {}).apply(VariantState())
    ground = state.scene.spec.ground
    assert ground == Ground(TABLE_TOP_Z_M, 200.0, 0.12) and "table" not in state.scene.spec.objects
    bare = tag_paper.mean(sun, ("node",))
    lit = tag_paper.mean(sun, ("node",), ground=ground)
    assert lit / bare == pytest.approx(1 + 0.12 * np.sin(el) / (2 * np.cos(el)), rel=1e-3)


def test_a_black_sky_leaves_only_the_lights_other_effects_add():
    state = make_effect("sun", {}).apply(VariantState())
    dark = make_effect("black_sky", {}).apply(state).scene.spec
    assert set(dark.lights) == {"sun"} and not set(LAB_LIGHTS) & set(dark.lights)
    assert not set(LAB_OBJECTS) & set(dark.objects) and "node" in dark.objects
    kept = make_effect("black_sky", {"keep_table": True}).apply(state).scene.spec
    assert "table" in kept.objects and set(kept.lights) == {"sun"}
