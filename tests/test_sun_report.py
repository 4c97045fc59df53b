"""A sweep over the sun's direction: its reduction per direction, its report section and the
error model pooled over the directions (a Monte Carlo over the sun)."""

from __future__ import annotations

import numpy as np
import pytest

from simgap.analysis.report import envelope_rows, summarize_sun, worst_directions, write_sun_report
from simgap.pipeline.experiment import experiment_from_yaml
from simgap.pipeline.sweep import run_experiment
from simgap.results.dataset import POOLED, pooled_variants, read_netcdf, write_netcdf

# render seed 1: the backlit tag 0 at theta 0 under a black sky (sun 0 / 35 deg: only light bounced
# off the fixture) is at the detector's margin: over render seeds 0-7 it was lost once in 8 both
# before and after the converged render took the sun's direct light apart (render key exact-9:
# at seed 2 before, at seed 0 after); at seed 1 every sun finds it in both
SWEEP = """
name: sun_tiny
configurations: {p: [7], theta_deg: [0, 30]}
render: {mode: converged, spp: 4, seed: 1}
effects:
  black_sky: {}
  auto_exposure: {metering: tags}
grid:
  sun.azimuth_deg: [0, 180]
  sun.elevation_deg: [35, 60]
"""


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """Two azimuths (behind the node, behind the camera) x two elevations, tag 0 at two angles."""
    folder = tmp_path_factory.mktemp("sun")
    ds = run_experiment(experiment_from_yaml(SWEEP), folder / "cache", show_progress=False)
    return read_netcdf(write_netcdf(ds, folder / "sun.nc")), folder


def test_each_direction_is_read_from_the_variants_and_reduced(sweep):
    ds, _ = sweep
    s = summarize_sun(ds)
    assert s is not None and len(s.variants) == 4  # the baseline (no sun) is not a direction
    np.testing.assert_array_equal(s.azimuth_deg, [0, 0, 180, 180])
    np.testing.assert_array_equal(s.elevation_deg, [35, 60, 35, 60])
    np.testing.assert_array_equal(s.visible, 2)  # tag 0 at theta 0 and 30, one repeat
    np.testing.assert_array_equal(s.detection_rate, 1.0)  # measured: found under every sun
    assert s.max_abs_error.sizes == {"variant": 4, "axis": 6}
    # every tag found under every sun: the worst are those with the most outside the envelope
    worst = worst_directions(s, 4)
    assert sorted(worst) == [0, 1, 2, 3]
    assert list(np.nan_to_num(s.outside_rate)[worst]) == sorted(np.nan_to_num(s.outside_rate))[::-1]


def test_the_auto_exposure_follows_the_cosine_law_on_the_sunlit_tag(sweep):
    """Front-lit (the sun behind the camera), the tag and the node face are vertical: raising
    the sun from 35 to 60 deg cuts their irradiance by cos 60 / cos 35, so the camera opens up
    log2(cos 35 / cos 60) = 0.712 EV. Measured 0.746 and 0.721 (theta 0, 30; the turntable's
    top, lit by sin(el), is in the metered crop too): 0.05 EV allowed. Backlit, only light
    bounced off the fixture reaches them: about 9 EV more (measured 8.9, 9.7)."""
    ds, _ = sweep
    ev = ds.auto_exposure_ev.isel(repeat=0, p=0)
    front35 = ev.sel(variant="sun.azimuth_deg=180,sun.elevation_deg=35").values
    front60 = ev.sel(variant="sun.azimuth_deg=180,sun.elevation_deg=60").values
    back35 = ev.sel(variant="sun.azimuth_deg=0,sun.elevation_deg=35").values
    expected = np.log2(np.cos(np.radians(35)) / np.cos(np.radians(60)))
    np.testing.assert_allclose(front60 - front35, expected, atol=0.05)
    assert np.all(back35 - front35 > 7.0)


def test_the_report_section_maps_the_sky_and_shows_the_worst_frames(sweep, tmp_path):
    ds, folder = sweep
    paths = write_sun_report(ds, tmp_path, folder / "cache")
    assert [p.name for p in paths] == ["sun_polar.png", "sun_worst_frames.png", "sun.md"]
    assert all(p.stat().st_size > 10_000 for p in paths[:2])  # two real figures
    text = (tmp_path / "sun.md").read_text()
    assert "4 sun directions" in text and "| 35° |" in text and "| 60° |" in text
    rows = envelope_rows(ds, summarize_sun(ds))
    assert f"Detections outside the envelope: {len(rows)}" in text
    assert all(r.share > 1 and abs(r.value) > (5.0 if r.unit == "mm" else 87.3) for r in rows)


def test_a_dataset_without_a_sun_has_no_sun_section(tmp_path):
    exp = experiment_from_yaml("name: lab\nconfigurations: {p: [7], theta_deg: [0]}\n")
    ds = run_experiment(exp, tmp_path / "cache", show_progress=False)
    assert summarize_sun(ds) is None and write_sun_report(ds, tmp_path) == []


def test_pooled_variants_keep_every_draw(sweep):
    ds, _ = sweep
    pooled = pooled_variants(ds)
    n_var, n_rep = ds.sizes["variant"], ds.sizes["repeat"]
    assert list(pooled.variant.values) == [POOLED] and pooled.sizes["repeat"] == n_var * n_rep
    for k in range(n_var):
        for r in range(n_rep):
            np.testing.assert_array_equal(
                pooled.error.isel(variant=0, repeat=k * n_rep + r).values,
                ds.error.isel(variant=k, repeat=r).values,
            )
    assert pooled.error.dims == ds.error.dims


def test_a_pooled_model_is_checked_on_the_variants_it_did_not_see(sweep):
    """Fitted on every other sun direction (the baseline's eclipse among them), tested on the
    others at the same poses. Six detections of tag 0 give a pooled fit (constant bias and
    spread, t intervals): the check half's errors (the other directions' draws) all lie in its
    range."""
    from simgap.analysis.errormodel import check_pooled_model

    ds, _ = sweep
    out = check_pooled_model(ds)
    assert set(out["coverage"]) == {"tx", "ty", "tz", "rx", "ry", "rz"}
    assert out["n_errors"] == 4 and out["n_outside"] == 0  # 2 directions x 2 stops of tag 0
    assert all(0.0 <= v <= 1.0 for v in out["coverage"].values())
