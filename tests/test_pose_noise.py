"""Each item's pose noise propagated from corner noise (simgap.analysis.gap)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from simgap.analysis.candidates import project_items
from simgap.analysis.gap import SHIFT_DRAWS, Items, noise_shift, propagated_pose_noise
from simgap.core.axes import AXES
from simgap.diagnosis.items import with_noise_shift, with_propagated_noise
from simgap.pipeline.experiment import load_experiment

#: near (p 0) and far (p 14) tag 0, frontal and turned by 50 deg
CONFIGS = [(0, 0, 0.0), (0, 14, 0.0), (0, 14, np.deg2rad(50.0)), (0, 0, np.deg2rad(50.0))]


def _items(real_corners=None, sim_corners=None, scale=None) -> Items:
    """The items of :data:`CONFIGS` (errors zero; corners zero unless given)."""
    tag, p, theta = (np.array(x) for x in zip(*CONFIGS, strict=True))
    zeros = np.zeros((len(CONFIGS), 4, 2))
    return Items(
        tag=tag, p=p, theta=theta, real_err=np.zeros((len(tag), 6)),
        sim_err=np.zeros((len(tag), 6)),
        real_corners=zeros if real_corners is None else real_corners,
        sim_corners=zeros if sim_corners is None else sim_corners,
        scale=np.ones(6) if scale is None else scale,
    )  # fmt: skip


def _corners():
    exp = load_experiment("experiments/baseline.yaml")
    base, rig = exp.variant_states()[0][1], exp.rig_model
    s = base.scene
    return project_items(rig, s.camera, s.errors, s.tag_scale, _items()), rig, base


def test_far_items_are_noisier_and_noise_scales_with_the_corners():
    corners, rig, base = _corners()
    small = propagated_pose_noise(corners, 0.1, rig, base)
    large = propagated_pose_noise(corners, 0.2, rig, base)
    ty = small[:, 1]
    # measured (0.1 px): ty 0.12 mm near frontal, 0.85 mm far frontal, 1.16 mm far at 50 deg,
    # 0.17 mm near at 50 deg; the far tags' depth-like axes move 5-7x more
    assert ty[1] > 4 * ty[0] and ty[2] > 4 * ty[3]
    assert ty[0] == pytest.approx(1.2e-4, rel=0.3)
    # the same draws at twice the noise: twice the spread where PnP is linear (measured 2.00
    # on ty at the near, turned tag; 32 draws, so only the linearity is asserted tightly)
    assert large[3, 1] / small[3, 1] == pytest.approx(2.0, rel=0.05)
    # same corners, same noise: the draws are seeded
    np.testing.assert_array_equal(small, propagated_pose_noise(corners, 0.1, rig, base))


def test_missing_corners_give_nan_and_leave_the_others_as_they_were():
    corners, rig, base = _corners()
    full = propagated_pose_noise(corners, 0.1, rig, base)
    corners[1] = np.nan
    out = propagated_pose_noise(corners, 0.1, rig, base)
    assert np.isnan(out[1]).all()
    # each item takes its own draws whichever others have corners
    np.testing.assert_array_equal(out[[0, 2, 3]], full[[0, 2, 3]])


def test_items_take_the_larger_scale_and_the_real_corners_where_the_simulation_has_none():
    corners, rig, base = _corners()
    sim = corners.copy()
    sim[2] = np.nan  # not detected in the simulation: the real corners stand in
    floor = np.full(6, 1e-4)
    items = _items(corners, sim, floor)
    noise = propagated_pose_noise(corners, 0.1, rig, base)
    out = with_propagated_noise(items, 0.1, rig, base)
    np.testing.assert_array_equal(out.scale, np.fmax(floor, noise))
    assert np.isfinite(out.scale).all()


def test_corner_noise_shifts_a_far_tags_pose_not_only_spreads_it():
    """The median pose under corner noise moves at the far tag, by more than its standard error."""
    corners, rig, base = _corners()
    small = noise_shift(corners, 0.1, rig, base)
    large = noise_shift(corners, 0.2, rig, base)
    spread = propagated_pose_noise(corners, 0.2, rig, base)
    # measured ty shift (mm) at 0.1 / 0.2 px: near frontal +0.05 / +0.10, far frontal -0.73 /
    # -1.54, far at 50 deg +0.01 / +0.01; the far frontal one is 6 standard errors of a median
    # of SHIFT_DRAWS draws (1.25 sd / sqrt(64), sd 1.6 mm at 0.2 px) and grows with the noise
    se = 1.25 * spread[1, 1] / np.sqrt(SHIFT_DRAWS)
    assert large[1, 1] < -4 * se and large[1, 1] < small[1, 1] < 0.0
    assert abs(large[1, 1]) > 5 * abs(large[0, 1])
    # no noise, no shift; same corners and noise, the same shift (seeded draws)
    np.testing.assert_array_equal(noise_shift(corners, 0.0, rig, base), np.zeros((4, 6)))
    np.testing.assert_array_equal(small, noise_shift(corners, 0.1, rig, base))


def _dataset(corners: np.ndarray, reproj_px: float) -> xr.Dataset:
    """A one-variant, one-repeat dataset of the configurations of :data:`CONFIGS`: tag 0, p 0
    and 14, theta 0 and 50 deg; errors 1e-3 everywhere (m, rad)."""
    grid = np.full((1, 2, 2, 4, 2), np.nan)
    for (_, p, theta), c in zip(CONFIGS, corners, strict=True):
        grid[0, p // 14, int(theta > 0)] = c
    coords = {"tag": [0], "p": [0, 14], "theta": [0.0, np.deg2rad(50.0)], "axis": list(AXES)}
    dims = ("variant", "repeat", "tag", "p", "theta")
    return xr.Dataset(
        {
            "error": (dims + ("axis",), np.full((1, 1, 1, 2, 2, 6), 1e-3)),
            "corners": (dims + ("corner", "uv"), grid[None, None]),
            "reproj_px": (dims, np.full((1, 1, 1, 2, 2), reproj_px)),
        },
        coords=coords,
    )  # fmt: skip


def test_a_converged_simulation_reads_its_poses_with_the_captures_extra_noise():
    """Each simulated error moves by the shift under the capture's noise beyond the simulation's:
    median reprojection 0.1 px (capture) and 0.06 px (simulation): 2 sqrt(0.1^2 - 0.06^2) = 0.16
    px a coordinate (:func:`simgap.analysis.gap.frame_corner_noise`)."""
    corners, rig, base = _corners()
    sim_corners = corners.copy()
    sim_corners[3] = np.nan  # not detected in the simulation: its error is left as it was
    real, sim = _dataset(corners, 0.1), _dataset(sim_corners, 0.06)
    shifted, shift = with_noise_shift(real, sim, rig, base)
    assert shift.corner_px == pytest.approx(0.16) and shift.frames == 1
    grid_order = [0, 3, 1, 2]  # CONFIGS in the dataset's (p, theta) order: the draws' order
    expected = np.empty((4, 6))
    expected[grid_order] = noise_shift(sim_corners[grid_order], 0.16, rig, base)
    items = _items(corners, sim_corners)
    np.testing.assert_allclose(shift.at(items)[:3], expected[:3])
    moved = shifted.error.isel(variant=0, repeat=0).sel(tag=0).values  # p, theta, axis
    for (_, p, theta), e in zip(CONFIGS[:3], expected[:3], strict=True):
        np.testing.assert_allclose(moved[p // 14, int(theta > 0)], 1e-3 + e)
    np.testing.assert_array_equal(moved[0, 1], np.full(6, 1e-3))
    # a capture no noisier than the simulation: nothing moves
    same, none = with_noise_shift(_dataset(corners, 0.05), sim, rig, base)
    assert none.corner_px == 0.0
    np.testing.assert_array_equal(same.error.values, sim.error.values)
