"""Figure helpers: sampled heatmap grids, robust colour limits, statistic labels, one distance."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from matplotlib.figure import Figure

from simgap.analysis.errormodel import covariates
from simgap.analysis.report import (
    dataset_distance_m,
    mark_beyond_limit,
    robust_colour_limit,
    row_distance_labels,
    sampled_axis,
)
from simgap.core.distance import DISTANCE_LABEL, camera_to_tag_distance
from simgap.diagnosis.engineering import plot_gap_by_distance
from simgap.pose.image_stats import STAT_NAMES
from simgap.pose.stat_labels import STAT_LABELS, stat_label


def test_sampled_axis_draws_only_the_samples():
    # theta every 30 deg: three cells of unit width, no 15 or 105 deg edge
    axis = sampled_axis(np.array([30.0, 60.0, 90.0]), "{:.0f}")
    assert axis.edges.tolist() == [-0.5, 0.5, 1.5, 2.5]
    assert axis.ticks.tolist() == [0, 1, 2]
    assert axis.labels == ["30", "60", "90"]
    # every seventh pin hole: three cells, not -3.5 .. 17.5
    pins = sampled_axis(np.array([0, 7, 14]))
    assert pins.edges[0] == -0.5 and pins.edges[-1] == 2.5
    assert pins.labels == ["0", "7", "14"]


def test_sampled_axis_thins_dense_labels():
    axis = sampled_axis(np.arange(36) * 10.0, "{:.0f}")  # 36 samples, at most 8 labels
    assert axis.edges.size == 37
    assert axis.ticks.tolist() == list(range(0, 36, 5))
    assert axis.labels[1] == "50"


def test_robust_limit_ignores_one_planar_flip_and_marks_it():
    # eight cells of a few mrad and one planar flip of 217 mrad (issue 29)
    values = np.array([[1.0, -2.0, 3.0], [-4.0, 5.0, np.nan], [2.5, -1.5, 217.0]])
    limit = robust_colour_limit(values)
    assert limit == 5.0  # the largest |value| within Q3 + 3 IQR of the |values|
    ax = Figure().subplots()
    assert mark_beyond_limit(ax, values, limit) == "hatched: 1 beyond ±5, largest |value| 217"
    assert len(ax.patches) == 1 and ax.patches[0].get_xy() == (1.5, 1.5)  # row 2, column 2
    assert mark_beyond_limit(Figure().subplots(), values, 300.0) == ""


def test_robust_limit_keeps_a_heavy_tail_within_twice_the_bulk():
    bulk = [4.0, -4.0, 4.0, 4.1, -4.1, 4.2, 4.2, -4.3]
    q1, q3 = np.percentile(np.abs(bulk + [7.0]), [25, 75])
    assert q3 + 3 * (q3 - q1) < 7.0  # 7 is beyond the far-out fence of these |values|
    # ... but under twice the bulk's 4.3: the full range is kept and nothing is marked
    assert robust_colour_limit(np.array(bulk + [-7.0])) == 7.0
    assert robust_colour_limit(np.array(bulk + [9.0])) == 4.3  # over twice: an outlier


def test_robust_limit_without_outliers_is_the_maximum():
    values = np.array([-3.0, 1.0, 2.0, 2.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    # zeros (unchanged configurations) do not shrink the fence to 0
    assert robust_colour_limit(values) == 3.0
    assert robust_colour_limit(np.array([0.1, 40.0])) == 40.0  # too few for quartiles
    assert robust_colour_limit(np.zeros(5), floor=1e-3) == 1e-3
    assert robust_colour_limit(np.full(3, np.nan), floor=1e-3) == 1e-3


def test_rows_are_ticked_with_their_median_visible_distance():
    d = xr.DataArray([[0.30, 0.34, 0.90], [0.40, 0.44, 0.48]], dims=("p", "theta"))
    shown = xr.DataArray([[True, True, False], [False, False, False]], dims=("p", "theta"))
    assert row_distance_labels(d, shown).labels == ["0.320", "0.440"]


def test_every_statistic_has_a_readable_label_with_a_unit():
    assert set(STAT_LABELS) == set(STAT_NAMES)
    for name, label in STAT_LABELS.items():
        assert "_" not in label.name, name
        assert label.unit and label.unit != "1", name
    assert stat_label("noise_paper_linear").text == "paper noise σ, linear [fraction of full scale]"
    assert stat_label("edge_width_x_px").unit == "px"
    assert stat_label("not_a_stat").name == "not_a_stat"


def test_one_distance_from_poses_dataset_and_model(rig):
    # tag 0 at p = 3, theta = 0: the rig's pose; its length is the camera-to-tag distance
    pose = rig.expected_pose(0, 3, 0.0)
    d = float(camera_to_tag_distance(pose))
    assert d == pytest.approx(np.linalg.norm(pose[:3]), abs=1e-15)
    assert float(covariates(pose[None])[0][0]) == pytest.approx(d, abs=1e-12)
    # Table 1 of docs/conventions.md: X = 0.0325, Y = 0.28314414 + 0.0254 p - 0.0806, Z
    table1 = np.array([0.0325, 0.28314414 + 0.0254 * 3 - 0.0806, -0.01616866])
    assert d == pytest.approx(np.linalg.norm(table1), abs=1e-6)
    ds = xr.Dataset(coords={"tag": [0], "p": [3], "theta": [0.0]})  # no expected: the rig's
    assert float(dataset_distance_m(ds).squeeze()) == pytest.approx(d, abs=1e-12)
    assert DISTANCE_LABEL == "camera-to-tag distance [m]"


def test_gap_figure_plots_real_minus_sim_like_the_table():
    p = np.repeat(np.arange(15), 2)
    distance = 0.3 + 0.0254 * p
    sim = np.zeros((p.size, 6))
    real = sim.copy()
    real[:, 0] = sim[:, 0] + 0.001  # real tx 1 mm larger: the table's gap is +1 mm
    real[:, 5] = -0.003  # real rz -3 mrad, |real| > |sim|: a difference of |.| would be +3
    fig = plot_gap_by_distance(p, distance, real, sim)
    tx, rz = fig.axes[0], fig.axes[5]
    assert np.allclose(tx.collections[0].get_offsets()[:, 1], 1.0)  # mm
    assert np.allclose(rz.collections[0].get_offsets()[:, 1], -3.0)  # mrad
    medians = [line.get_ydata() for line in rz.lines if line.get_linewidth() == 2.5]
    assert len(medians) == 3 and np.allclose(medians, -3.0)  # one per distance third
    assert "real − simulated" in fig._suptitle.get_text()
