"""The sun (issue 54, first step): a distant light whose irradiance follows the cosine law."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simgap.core.rig import load_rig
from simgap.effects import make_effect
from simgap.effects.scene import SOLAR_CONSTANT_W_M2, sun_direction
from simgap.effects.state import VariantState
from simgap.scene.lights import LightSpec, irradiance
from simgap.scene.spec import load_scene_spec


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
    # the analytic irradiance: E cos(t) on the side facing it, nothing behind
    normals = np.array([towards, -towards, [0.0, 1.0, 0.0]])
    e = irradiance(dataclasses.replace(sun, rgb=(1.0, 1.0, 1.0)), np.zeros((3, 3)), normals)
    np.testing.assert_allclose(e, [SOLAR_CONSTANT_W_M2, 0.0, 0.0], atol=1e-9)


@pytest.mark.parametrize("angle_deg", [30.0, 60.0])
def test_a_tags_paper_under_the_sun_follows_the_cosine_law(angle_deg):
    """Rendered (Mitsuba, 16 spp): tag 0's paper with the sun alone, along its normal and
    ``angle_deg`` off it (turned about the tag's vertical axis). Measured: 0.8660 and 0.5000 of
    the facing radiance (cos 30 deg 0.8660, cos 60 deg 0.5), where the issue asks 1 %."""
    from simgap.render.scene import FixtureScene, pose_transforms, projected_sticker_boxes

    rig, spec = load_rig(), load_scene_spec()
    world = pose_transforms(rig, 0, 0.0)
    tag = world["tag_0"]
    normal, up = tag[:3, 2] / np.linalg.norm(tag[:3, 2]), tag[:3, 1]
    side = 200
    u0, v0, u1, v1 = (int(round(x)) for x in projected_sticker_boxes(rig, 0, 0.0)[0])
    offset = ((u0 + u1 - side) // 4 * 2, (v0 + v1 - side) // 4 * 2)

    def paper(direction: np.ndarray) -> float:
        sun = LightSpec("directional", position=tuple(direction), target=(0.0, 0.0, 0.0),
                        irradiance=10.0)  # fmt: skip
        scene = FixtureScene(rig, dataclasses.replace(spec, lights={"sun": sun}), (side, side), 16)
        scene.set_pose(0, 0.0)
        img = scene.render(offset, seed=1).mean(axis=2)
        rows = slice(v0 - offset[1] + 3, v1 - offset[1] - 3)
        inner = img[rows, u0 - offset[0] + 3 : u1 - offset[0] - 3]
        return float(np.median(inner[inner > 0.5 * inner.max()]))

    facing = paper(normal)
    turned = paper(_rotated(normal, up, np.radians(angle_deg)))
    assert turned / facing == pytest.approx(np.cos(np.radians(angle_deg)), rel=0.01)
