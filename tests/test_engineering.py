"""The diagnosis in an engineer's units: per axis and distance third, flips named and counted."""

from __future__ import annotations

import numpy as np
import pytest

from simgap.diagnosis.engineering import (
    flip_sentence,
    planar_flips,
    plot_abs_error_vs_distance,
    region_rows,
    region_table,
)


def _items(n_per_pin: int = 4):
    p = np.repeat(np.arange(15), n_per_pin)
    distance = 0.3 + 0.0254 * p
    real = np.zeros((len(p), 6))
    sim = np.zeros((len(p), 6))
    real[:, 1] = -0.004 * (p / 14)  # ty: 4 mm short at the far end, growing with distance
    return p, distance, real, sim


def test_region_rows_read_the_gap_in_mm_per_third_before_and_after():
    p, distance, real, sim = _items()
    fitted = sim.copy()
    fitted[:, 1] = real[:, 1] + 0.0001  # the fit explains ty to 0.1 mm
    fitted[:, 5] = 0.002  # and makes rz 2 mrad worse everywhere
    rows = {(r.axis, r.region.split()[0]): r for r in region_rows(p, distance, real, sim, fitted)}
    far = rows[("ty", "far")]
    # far third: pins 10-14, ty gap -0.004 * 12 / 14 at its median pin
    assert far.gap_before == pytest.approx(-0.004 * 12 / 14)
    assert far.gap_after == pytest.approx(-0.0001)
    assert far.distance_m == pytest.approx((0.3 + 0.254, 0.3 + 0.0254 * 14))
    assert not far.worse
    # 2 mrad more is less than half the rotation floor (8.7 mrad): not counted as worse
    assert not rows[("rz", "near")].worse
    table = "\n".join(region_table(list(rows.values())))
    assert "-3.43 mm -> -0.10 mm" in table


def test_an_axis_that_gets_worse_is_marked():
    p, distance, real, sim = _items()
    fitted = sim.copy()
    fitted[:, 0] = 0.002  # tx 2 mm off after the fit, 0 before: half the 0.5 mm floor is 0.25 mm
    rows = region_rows(p, distance, real, sim, fitted)
    worse = {(r.axis, r.region.split()[0]) for r in rows if r.worse}
    assert worse == {("tx", "near"), ("tx", "mid"), ("tx", "far")}
    assert "**worse**" in "\n".join(region_table(rows))


def test_a_frontal_flip_is_named_and_left_out_of_the_medians():
    p, distance, real, sim = _items()
    real[3, 5] = 0.217  # the 217 mrad rz outlier: a frontal tag's mirrored pose
    real[3, 1] = 0.001
    assert planar_flips(real).sum() == 1 and not planar_flips(sim).any()
    # a large translation error with it is no flip
    bad = real.copy()
    bad[3, 0] = 0.02
    assert not planar_flips(bad).any()
    assert "real 1, simulated 0" in flip_sentence(real, sim)
    rows = region_rows(p, distance, real, sim)
    near = next(r for r in rows if r.axis == "rz" and r.region.startswith("near"))
    assert near.n == 4 * 5 - 1 and near.real_abs == 0.0
    fig = plot_abs_error_vs_distance(distance, real, sim, sim)
    assert len(fig.axes) == 6


def test_the_verdict_names_the_largest_gap_in_mm_and_what_gets_worse():
    from simgap.diagnosis.engineering import verdict

    p, distance, real, sim = _items()
    fitted = real.copy()
    fitted[:, 3] = 0.01  # rx 10 mrad off everywhere after the fit
    rows = region_rows(p, distance, real, sim, fitted)
    text = "\n".join(verdict(rows, "focal_length", "re-rendered"))
    # far third: median ty gap -0.004 * 12 / 14 = -3.43 mm, the largest over the 0.5 mm floor
    assert "Largest gap: **ty far**" in text and "-3.43 mm" in text
    assert "Selected: focal_length. With it the gap there is +0.00 mm (re-rendered)" in text
    assert "**Worse after the fit**: rx near +0.00 mrad -> -10.00 mrad" in text
    assert "No effect of the catalogue" in "\n".join(verdict(rows, "-", ""))
