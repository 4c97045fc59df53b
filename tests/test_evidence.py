"""Where the gap lies beyond pose means: scatter, detection and image-evidence tests."""

from __future__ import annotations

import numpy as np
import pytest

from simgap.analysis.gap import (
    detection_pvalue,
    detection_tests,
    holm_reject,
    line_residuals,
    scatter_tests,
)
from simgap.core.rig import load_rig
from simgap.diagnosis.items import split_items
from simgap.results.dataset import build_dataset, empty_results

PS = tuple(range(0, 15, 2))
THETAS = np.deg2rad(np.arange(0, 360, 20.0))


def _dataset(
    seed: int,
    noise_mm: float = 0.3,
    lost: float = 0.0,
    repeats: int = 1,
    ps: tuple[int, ...] = PS,
    thetas: np.ndarray = THETAS,
):
    """A result dataset over the rig's geometry: a smooth depth error plus noise (m, rad)."""
    PS, THETAS = ps, thetas  # noqa: N806 (the module's grid, or another)
    rig = load_rig()
    tags = rig.tags.ids
    rng = np.random.default_rng(seed)
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in THETAS] for p in PS] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in THETAS] for p in PS] for t in tags])
    shape = (1, repeats, len(tags), len(PS), len(THETAS))
    res = empty_results(shape)
    trend = np.zeros(shape + (6,))
    trend[..., 1] = 2e-4 * np.asarray(PS)[None, None, None, :, None]  # ty grows with distance
    scale = np.array([1, 1, 1, 20, 20, 20]) * noise_mm * 1e-3
    err = trend + rng.normal(0, 1, shape + (6,)) * scale
    detected = np.broadcast_to(visible, shape).copy()
    if lost:  # lose the most frontal detections first
        view = np.array(
            [[[rig.view_angle(t, p, th) for th in THETAS] for p in PS] for t in tags]
        )
        order = np.argsort(-np.where(visible, view, -np.inf), axis=None)
        k = int(round(lost * visible.sum()))
        flat = detected.reshape(repeats, -1)
        flat[:, order[:k]] = False
        detected = flat.reshape(shape)
    res["detected"] = detected
    res["error"] = np.where(detected[..., None], err, np.nan)
    res["estimated"] = np.where(detected[..., None], expected + err, np.nan)
    return build_dataset(tags, PS, THETAS, expected, visible, res, repeats=tuple(range(repeats)))


def test_no_difference_is_not_significant():
    real, sim = _dataset(1), _dataset(2)
    assert not any(t.significant for t in scatter_tests(real, sim))
    assert not any(t.significant for t in detection_tests(real, sim))


def test_a_capture_that_loses_a_fifth_of_its_detections_is_significant():
    real, sim = _dataset(1, lost=0.2), _dataset(2)
    rows = {t.region: t for t in detection_tests(real, sim)}
    assert rows["all"].significant
    assert rows["all"].difference == pytest.approx(-0.2, abs=0.01)
    # the lost ones are the frontal views: that band carries the loss
    assert rows["view 60-90 deg"].significant
    assert not any(t.significant for t in scatter_tests(real, sim))


def test_the_issue_numbers_of_lost_detections_are_significant():
    """Issue 25: 36 of 45 detected against 45 of 45 (a glossy laminate under a light beside the
    lens) is significant by the planned overall test (Boschloo p 0.00098 < 0.01; Fisher's 0.0025
    failed Bonferroni over seven tests, 0.0014), and so is half of one 15-configuration region
    under Holm over the six regional tests (7 of 15: p 0.00082 < 0.01 / 6)."""
    assert detection_pvalue(36, 45, 45, 45) == pytest.approx(0.00098, abs=2e-5)
    assert detection_pvalue(7, 15, 15, 15) == pytest.approx(0.00082, abs=2e-5)
    assert detection_pvalue(45, 45, 45, 45) == 1.0
    # Holm: the smallest against alpha / 6, the next against alpha / 5, ... stopping at a miss
    # (0.0008 < 0.00167, 0.0019 < 0.002, 0.003 >= 0.0025: stop)
    assert holm_reject([0.0008, 0.003, 0.5, 0.0019, 0.2, 0.9]) == [
        True, False, False, True, False, False,
    ]  # fmt: skip
    assert holm_reject([0.002, 0.0021]) == [True, True]  # 0.002 < 0.005, 0.0021 < 0.01
    assert holm_reject([0.012, 0.0021]) == [False, True]  # 0.012 >= 0.01


def test_a_fifth_of_45_detections_lost_is_significant_overall():
    """45 visible configurations (5 pin holes x 9 stops of tag 0), the 9 most frontal lost."""
    ps, thetas = (0, 3, 7, 10, 14), np.deg2rad([0, 10, 20, 30, 40, 320, 330, 340, 350])
    real = _dataset(1, lost=0.2, ps=ps, thetas=thetas)
    sim = _dataset(2, ps=ps, thetas=thetas)
    rows = {r.region: r for r in detection_tests(real, sim)}
    assert (rows["all"].real_detected, rows["all"].real_attempts) == (36, 45)
    assert rows["all"].significant and rows["all"].test == "planned"
    assert rows["all"].p_value == pytest.approx(0.00098, abs=2e-5)


@pytest.mark.parametrize("repeats", [1, 3])
def test_doubled_scatter_is_significant_with_or_without_repeats(repeats):
    real, sim = _dataset(1, noise_mm=0.6, repeats=repeats), _dataset(2, repeats=repeats)
    pooled = [t for t in scatter_tests(real, sim) if t.region == "all"]
    # ~90 (single repeat) or ~350 samples per axis: measured 5-6 of 6 axes significant over
    # seeds 1, 5, 9 (ratios 1.3-2.9 for a true 2; the robust scale of 90 samples varies ~15 %)
    assert sum(t.significant for t in pooled) >= 5
    assert 1.6 < np.median([t.ratio for t in pooled]) < 2.6


def test_line_residuals_remove_any_linear_trend_on_uneven_spacing():
    x = np.array([0.0, 3, 6, 9, 12, 14])
    field = 0.7 * x + 2.0
    np.testing.assert_allclose(line_residuals(field, x), 0.0, atol=1e-12)
    noise = np.random.default_rng(0).normal(0, 1, (4000, x.size))
    # unit white noise stays unit variance (measured 1.00 +/- 0.01 per position)
    assert line_residuals(noise, x).std(axis=0) == pytest.approx(1.0, abs=0.05)


@pytest.mark.parametrize("n", [3, 9, 48, 101])
def test_fit_choose_and_report_splits_are_disjoint_and_complete(n):
    fit, choose, report = split_items(n, 0.5, 0.25, seed=4)
    assert len(fit) and len(choose) and len(report)
    assert not (set(fit) & set(choose) or set(fit) & set(report) or set(choose) & set(report))
    assert sorted([*fit, *choose, *report]) == list(range(n))


def test_a_pose_flip_on_either_side_is_left_out_of_the_pose_comparison():
    """An item on the other branch of the planar ambiguity keeps its corners, not its errors."""
    from simgap.analysis.gap import gap_field
    from simgap.analysis.thresholds import FLIP_RAD
    from simgap.diagnosis.items import build_items

    real, sim = _dataset(1), _dataset(2)
    err = real["error"].values.copy()
    t, p, k = np.argwhere(np.isfinite(err[0, 0, ..., 5]))[0]
    err[0, 0, t, p, k, 5] += 0.75  # rz: a flip as measured on a far inward tag (0.73-0.75 rad)
    real["error"].values[:] = err
    items = build_items(real, sim, gap_field(real, sim))
    at = (items.tag == real.tag.values[t]) & (items.p == real.p.values[p])
    at &= np.isclose(items.theta, real.theta.values[k])
    assert at.sum() == 1 and 0.75 > FLIP_RAD
    assert np.isnan(items.real_err[at]).all() and np.isnan(items.sim_err[at]).all()
    # the other items compare as before, and no corner or detection is dropped
    assert np.isfinite(items.real_err[~at]).all()
    assert len(items) == int(real["visible"].values.sum())


def test_signed_rank_pvalue_is_scipys_wilcoxon():
    """The vectorised exact test for small samples with ties or zeros gives SciPy's p-values."""
    from scipy import stats

    from simgap.core.robust import signed_rank_pvalue

    rng = np.random.default_rng(0)
    for _ in range(12):  # up to 9 pairs: SciPy's own permutations stay quick
        d = np.round(rng.normal(0.3, 1.0, rng.integers(3, 10)), 1)  # rounding makes ties
        d[: rng.integers(0, 3)] = 0.0
        if np.all(d == 0):
            continue
        for alternative in ("two-sided", "greater"):
            expected = stats.wilcoxon(d, alternative=alternative).pvalue
            assert signed_rank_pvalue(d, alternative) == pytest.approx(expected, abs=1e-12)
    assert signed_rank_pvalue(np.zeros(5)) == 1.0
