"""A diagnosis folder's evidence.nc: its records round-trip, its figures are the datasets' own,
and a folder without it is refused in one line (no rendering: small datasets)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from test_cli import small_dataset
from typer.testing import CliRunner

from simgap.analysis.gap import align, plot_image_stats, tag_distance_and_view_angle
from simgap.analysis.report import plot_change_heatmap, plot_comparison_heatmap
from simgap.cli import app
from simgap.core.outputs import claim_folder
from simgap.diagnosis.diagnosis_files import (
    EVIDENCE_FILE,
    RESULT_FILE,
    SPLITS,
    DiagnosisEvidence,
    GapEvidence,
    ImageStatEvidence,
    ItemEvidence,
    gap_dataset,
)
from simgap.diagnosis.result import DiagnosisResult
from simgap.diagnosis.result_json import write_json
from tests.cf_check import assert_cf_valid


@pytest.fixture(scope="module")
def pair():
    """A capture and its simulation on one small grid, both with image statistics."""
    return small_dataset(0, image_stats=True), small_dataset(1, image_stats=True)


def _items(n: int = 7, fitted: bool = True, confirmed: bool = True) -> ItemEvidence:
    """Random items with NaN errors (undetected, flipped) and the measure split's fit only."""
    rng = np.random.default_rng(3)
    in_split = np.zeros((n, len(SPLITS)), bool)
    in_split[np.arange(n), np.arange(n) % len(SPLITS)] = True
    real, sim = rng.normal(0, 1e-3, (n, 6)), rng.normal(0, 1e-3, (n, 6))
    real[1], sim[4, 3:] = np.nan, np.nan
    fast = np.where(in_split[:, [2]], rng.normal(0, 1e-3, (n, 6)), np.nan)
    return ItemEvidence(
        tag=rng.integers(0, 2, n),
        p=rng.integers(0, 15, n),
        theta_rad=rng.uniform(0, 2 * np.pi, n),
        distance_m=rng.uniform(0.2, 0.7, n),
        in_split=in_split,
        real_error=real,
        simulated_error=sim,
        fitted_error=fast if fitted else None,
        confirmed_error=rng.normal(0, 1e-3, (n, 6)) if confirmed else None,
    )


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=60)
    return buffer.getvalue()


@pytest.mark.parametrize(("fitted", "confirmed"), [(True, True), (True, False), (False, False)])
def test_each_record_round_trips_through_its_dataset(pair, fitted, confirmed):
    """from_dataset(to_dataset(x)) == x for the items (fit, confirmation or neither), the gap
    and the image statistics; a record differs from one with other values."""
    items = _items(fitted=fitted, confirmed=confirmed)
    gap, stats = GapEvidence.of(*pair), ImageStatEvidence.of(*pair)
    assert ItemEvidence.from_dataset(items.to_dataset()) == items
    assert GapEvidence.from_dataset(gap.to_dataset()) == gap
    assert ImageStatEvidence.from_dataset(stats.to_dataset()) == stats
    assert items != _items(n=6, fitted=fitted, confirmed=confirmed)
    # what the report shows with the fitted effects: the confirmation, else the fast fit
    shown = items.confirmed_error if confirmed else items.fitted_error if fitted else None
    if shown is None:
        assert np.isnan(items.with_fitted_effects).all()
    else:
        assert items.with_fitted_effects is shown


def test_the_evidence_file_round_trips_and_is_cf(pair, tmp_path):
    """evidence.nc read back is the evidence written, with and without image statistics; its
    root group passes cfchecks (CF-1.10) and every variable of every group has a long_name and
    numbers have units."""
    path = tmp_path / EVIDENCE_FILE
    evidence = DiagnosisEvidence(
        items=_items(), gap=GapEvidence.of(*pair), image_stats=ImageStatEvidence.of(*pair)
    )
    assert DiagnosisEvidence.read(evidence.write(path)) == evidence
    assert_cf_valid(path)
    without = DiagnosisEvidence(items=_items(confirmed=False), gap=evidence.gap)
    assert DiagnosisEvidence.read(without.write(path)) == without
    assert without != evidence


def test_the_figures_drawn_from_the_evidence_are_the_datasets_own(pair):
    """The gap heatmap and the image-evidence figures from the evidence are those drawn from
    the capture and its simulation themselves, pixel for pixel."""
    real, sim = pair
    direct = plot_change_heatmap(gap_dataset(real, sim), "real", "simulation")
    drawn = plot_comparison_heatmap(GapEvidence.of(real, sim).comparison(), "real")
    assert _png(drawn) == _png(direct)
    aligned = dict(zip(("real", "simulation"), align(real, sim), strict=True))
    views = ImageStatEvidence.of(real, sim).views()
    drawn = plot_image_stats(views, "view_angle")
    assert _png(drawn) == _png(plot_image_stats(aligned, "view_angle"))
    for source, ds in aligned.items():  # the other figure's x: the distance
        distance, _ = tag_distance_and_view_angle(ds)
        assert np.array_equal(views[source].distance_m.values, distance.values)
    # a side without image statistics: no image-evidence figures, none in the file
    assert ImageStatEvidence.of(real, sim.drop_vars("image_stats")) is None


def test_an_evidence_file_of_another_schema_is_refused(pair, tmp_path):
    """Another schema_version, or a missing variable, is named with the file."""
    import xarray as xr

    path = DiagnosisEvidence(items=_items(), gap=GapEvidence.of(*pair)).write(
        tmp_path / EVIDENCE_FILE
    )
    with xr.open_dataset(path) as ds:
        root = ds.load()
    root.attrs["schema_version"] = 7
    root.to_netcdf(path, mode="a")
    expected = rf"{EVIDENCE_FILE}: schema_version: expected 1 or 2, got 7"
    with pytest.raises(ValueError, match=expected):
        DiagnosisEvidence.read(path)
    with pytest.raises(ValueError, match="missing variable 'simulated_error'"):
        ItemEvidence.from_dataset(_items().to_dataset().drop_vars("simulated_error"))


def test_an_evidence_file_of_schema_1_is_read_under_the_new_split_name(pair, tmp_path):
    """Schema 1 named the measure split ``report``: such a file (this one's root group as
    schema 1 wrote it) reads as the evidence it holds."""
    import netCDF4
    import xarray as xr

    evidence = DiagnosisEvidence(items=_items(), gap=GapEvidence.of(*pair))
    path = evidence.write(tmp_path / EVIDENCE_FILE)
    with netCDF4.Dataset(path, "a") as nc:  # the labels as char arrays (simgap.results.cf)
        labels = nc["split"]
        labels.set_auto_chartostring(False)
        old = np.array(["fit", "choose", "report"], f"S{labels.shape[1]}")
        labels[:] = netCDF4.stringtochar(old)
        nc.setncattr("schema_version", np.int64(1))
    with xr.open_dataset(path) as ds:
        assert list(ds.split.values) == ["fit", "choose", "report"]
        assert ds.attrs["schema_version"] == 1
    assert DiagnosisEvidence.read(path) == evidence


def test_report_diagnosis_names_the_missing_evidence_file(tmp_path):
    """A folder with result.json but no evidence.nc (or no folder at all): exit code 2, one
    line naming the file, no traceback, nothing written."""
    folder = claim_folder(tmp_path / "diagnosis")  # simgap's: written into without --overwrite
    write_json(DiagnosisResult(), folder / RESULT_FILE)
    runner = CliRunner()
    out = tmp_path / "again"
    res = runner.invoke(app, ["report-diagnosis", str(folder), "-o", str(out)])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    assert f"{folder / EVIDENCE_FILE}: diagnosis evidence not found" in lines[0]
    assert "Traceback" not in res.output and not out.exists()
    res = runner.invoke(app, ["report-diagnosis", str(tmp_path / "absent")])
    assert res.exit_code == 2 and "absent: diagnosis folder not found" in res.output
    # result.json that is not JSON: named with the file
    (folder / RESULT_FILE).write_text("{")
    res = runner.invoke(app, ["report-diagnosis", str(folder)])
    assert res.exit_code == 2 and f"{folder / RESULT_FILE}: not JSON" in res.output
    assert not (folder / "diagnosis.md").exists()
