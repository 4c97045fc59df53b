"""Each item's own noise: measured by repeats, carried into the diagnosis' items.

A far, oblique tag's depth and rotation move millimetres with a tenth of a pixel of corner
noise; on a small capture one such item decided between a focal length and a camera mount by the
realisation of the simulation's render noise (docs/results/sample_focal_render_seeds.md).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simgap.analysis import gap as gapmod
from simgap.analysis.gap import Items
from simgap.analysis.thresholds import PRACTICAL_FLOOR
from simgap.diagnosis.items import build_items, with_render_seeds
from simgap.diagnosis.settings import DiagnoseSettings
from simgap.pipeline.experiment import load_experiment
from simgap.results.dataset import build_dataset, empty_results

TAGS, PS, THETAS = (0,), (0, 1, 2, 3, 4, 5, 6, 7, 8, 9), np.deg2rad([0.0, 10.0])
NOISY = (0, 4, 1)  # the (tag, p, theta) index of the one noisy item
QUIET_M, NOISY_M = 1e-5, 3e-3


def _dataset(repeats: int, offset_m: float = 0.0):
    """A dataset whose repeats alternate +-QUIET_M, and +-NOISY_M at :data:`NOISY` (m, rad)."""
    shape = (1, repeats, len(TAGS), len(PS), len(THETAS))
    res = empty_results(shape)
    sign = np.where(np.arange(repeats) % 2 == 0, 1.0, -1.0)[None, :, None, None, None, None]
    amplitude = np.full(shape[2:] + (6,), QUIET_M)
    amplitude[NOISY] = NOISY_M
    err = (
        offset_m + sign * amplitude[None, None] if repeats > 1 else np.full(shape + (6,), offset_m)
    )
    expected = np.zeros(shape[2:] + (6,))
    res["detected"] = np.ones(shape, bool)
    res["error"] = err
    res["estimated"] = expected + err
    res["corners"] = np.zeros(shape + (4, 2))
    visible = np.ones(shape[2:], bool)
    return build_dataset(TAGS, PS, THETAS, expected, visible, res, repeats=tuple(range(repeats)))


def test_item_noise_is_each_items_own():
    """Sim with 4 repeats, capture with 1: the capture's frame is as noisy as a simulated one."""
    noise = gapmod.item_noise(_dataset(1), _dataset(4))
    # sample standard deviation of (+a, -a, +a, -a) is a sqrt(4/3); the gap's noise carries
    # one simulated frame (the capture) and the mean of four (the simulation)
    frame = NOISY_M * np.sqrt(4 / 3)
    assert float(noise[NOISY][0]) == pytest.approx(frame * np.sqrt(1 + 1 / 4), rel=1e-9)
    assert float(noise[0, 0, 0, 0]) == pytest.approx(QUIET_M * np.sqrt(4 / 3 * 5 / 4), rel=1e-9)
    # neither side has repeats: nothing measured
    assert np.isnan(gapmod.item_noise(_dataset(1), _dataset(1)).values).all()


def test_items_carry_their_own_noise():
    """The noisy item's scale is its own noise; the others keep the per-axis level."""
    real, sim = _dataset(1, offset_m=1e-3), _dataset(4)
    field = gapmod.gap_field(real, sim)
    items = build_items(real, sim, field)
    assert items.scale.shape == (len(items), 6)
    floors = np.array([PRACTICAL_FLOOR[u] for u in ("m",) * 3 + ("rad",) * 3])
    level = np.maximum(field.sigma.values, floors)
    at = (items.p == PS[NOISY[1]]) & np.isclose(items.theta, THETAS[NOISY[2]])
    own = NOISY_M * np.sqrt(4 / 3 * 5 / 4)  # above the translation floors, below the rotation ones
    assert items.scale[at] == pytest.approx(np.maximum(level, own)[None], rel=1e-9)
    assert items.scale[at][0, :3] == pytest.approx(np.full(3, own), rel=1e-9)
    assert items.scale[~at] == pytest.approx(np.broadcast_to(level, (len(items) - 1, 6)))
    # the gap of the noisy item, 1 mm, is well inside its noise; elsewhere it is 2 floors
    assert field.gap.values[NOISY][1] == pytest.approx(1e-3)
    sub = items.subset(np.flatnonzero(at))
    assert sub.scale.shape == (1, 6) and sub.scale[0, 1] > 1e-3


def test_a_per_axis_scale_is_given_to_every_item():
    items = Items(
        tag=np.zeros(3, int),
        p=np.arange(3),
        theta=np.zeros(3),
        real_err=np.zeros((3, 6)),
        sim_err=np.zeros((3, 6)),
        real_corners=np.zeros((3, 4, 2)),
        sim_corners=np.zeros((3, 4, 2)),
        scale=np.arange(1.0, 7.0),
    )
    assert items.scale.shape == (3, 6)
    assert items.subset(np.array([2])).scale.tolist() == [[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]]


@pytest.mark.parametrize(("configurations", "seeds"), [(1, 4), (9, 4), (12, 3), (36, 1), (540, 1)])
def test_small_captures_are_simulated_at_several_render_seeds(configurations, seeds):
    settings = DiagnoseSettings()
    assert settings.render_seeds(configurations) == seeds
    exp = load_experiment("experiments/baseline.yaml")
    seeded = with_render_seeds(exp, seeds)
    if seeds == 1:
        assert seeded is exp
    else:
        assert seeded.repeats == seeds and seeded.render.reseed_repeats
        assert dataclasses.replace(seeded, repeats=exp.repeats, render=exp.render) == exp
