"""Tests of the variant comparison (simgap.analysis.report), the `compare` command and the
notebook notebooks/compare_rendering_options.ipynb, on a synthetic multi-variant dataset (no
rendering)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from simgap.analysis.report import (
    binned_change_table,
    change_by_p,
    compare_variants,
    moves_most,
    resolve_baseline,
    variant_summary_table,
    write_comparison,
)
from simgap.cli import app
from simgap.results.dataset import build_dataset, write_netcdf

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "notebooks" / "compare_rendering_options.ipynb"
VARIANTS = ("baseline", "distortion", "noise")
REPEATS = (0, 1)
TAGS = (0, 1)
PS = (0, 7, 14)
THETAS = np.deg2rad(np.arange(36) * 10.0)
FACING = {0: 0.0, 1: np.pi}
MAX_VIEW_DEG = 80.0
TY_SHIFT_M = 0.002  # distortion: +2 mm on ty everywhere
JITTER_M = 0.0005  # noise: antithetic jitter +-j per repeat (zero mean by construction)
MISSED = (0, 2, 0)  # (tag, p, theta) indices the distortion variant never detects
EXPECTED_FILES = {
    "comparison.md",
    "change_by_distance.png",
    "change_heatmap_distortion.png",
    "change_heatmap_noise.png",
}


def _view_deg() -> np.ndarray:
    """Signed view angle (deg), dims (tag, theta)."""
    rel = THETAS[None, :] - np.array([FACING[t] for t in TAGS])[:, None]
    return np.degrees(np.angle(np.exp(1j * rel)))


def synthetic(seed: int = 0, variant_visible: bool = False) -> tuple[xr.Dataset, dict]:
    """Three variants x 2 repeats x 2 tags x 3 p x 36 theta, with known differences.

    baseline: errors identical over repeats, ty positive (1-3 mm); distortion: baseline + 2 mm on
    ty, one visible configuration never detected; noise: baseline +- a jitter per repeat.
    """
    rng = np.random.default_rng(seed)
    shape = (len(TAGS), len(PS), len(THETAS))
    visible = np.broadcast_to((np.abs(_view_deg()) <= MAX_VIEW_DEG)[:, None, :], shape).copy()
    base = np.concatenate(
        [rng.normal(0, 0.002, shape + (3,)), rng.normal(0, 0.02, shape + (3,))], axis=-1
    )
    base[..., 1] = rng.uniform(0.001, 0.003, shape)
    jitter = np.concatenate(
        [rng.normal(0, JITTER_M, shape + (3,)), rng.normal(0, 10 * JITTER_M, shape + (3,))], axis=-1
    )
    error = np.empty((len(VARIANTS), len(REPEATS)) + shape + (6,))
    error[0] = base
    error[1] = base
    error[1, ..., 1] += TY_SHIFT_M
    error[2, 0] = base + jitter
    error[2, 1] = base - jitter
    full = (len(VARIANTS), len(REPEATS)) + shape
    detected = np.broadcast_to(visible, full).copy()
    detected[(1, slice(None), *MISSED)] = False
    error[~detected] = np.nan
    expected = np.zeros(shape + (6,))
    results = {
        "detected": detected,
        "estimated": expected[None, None] + error,
        "error": error,
        "reproj_px": np.where(detected, 0.1, np.nan),
        "corners": np.where(detected[..., None, None], np.full(full + (4, 2), 500.0), np.nan),
    }
    vis = np.broadcast_to(visible, (len(VARIANTS),) + shape) if variant_visible else visible
    ds = build_dataset(
        TAGS,
        PS,
        THETAS,
        expected,
        vis,
        results,
        variants=VARIANTS,
        repeats=REPEATS,
        attrs={"experiment_yaml": "name: compare-test\nvariants: [distortion, noise]\n"},
    )
    return ds, {"base": base, "jitter": jitter, "visible": visible, "error": error}


@pytest.fixture(scope="module")
def data():
    return synthetic()


@pytest.fixture(scope="module")
def table(data):
    return variant_summary_table(compare_variants(data[0]))


def test_reference_is_baseline_and_errors_name_variants(data):
    ds = data[0]
    assert resolve_baseline(ds) == "baseline"
    assert resolve_baseline(ds.isel(variant=[2, 1])) == "noise"  # no "baseline": the first
    assert resolve_baseline(ds, "noise") == "noise"
    with pytest.raises(ValueError, match=r"needs at least two variants; dataset has: \['noise'\]"):
        write_comparison(ds.isel(variant=[2]), Path("unused"))
    with pytest.raises(ValueError, match=r"'glossy'.*\['baseline', 'distortion', 'noise'\]"):
        compare_variants(ds, "glossy")


def test_distortion_shifts_ty_by_exactly_2_mm(table, data):
    rows = table.loc["distortion"]
    assert rows.loc["ty", "unit"] == "mm" and rows.loc["rx", "unit"] == "mrad"
    assert rows.loc["ty", "mean_signed_shift"] == pytest.approx(2.0, abs=1e-9)
    assert rows.loc["ty", "change_mean_abs"] == pytest.approx(2.0, abs=1e-9)
    others = rows.drop(index="ty")
    np.testing.assert_allclose(others["mean_signed_shift"], 0.0, atol=1e-12)
    np.testing.assert_allclose(others["change_mean_abs"], 0.0, atol=1e-12)
    visible = data[1]["visible"]
    n_visible = int(visible.sum())
    assert (rows["n_paired"] == n_visible - 1).all()
    assert rows.loc["ty", "variant_detection_rate"] == pytest.approx(1 - 1 / n_visible)
    assert rows.loc["ty", "reference_detection_rate"] == 1.0
    paired = visible.copy()
    paired[MISSED] = False
    base_ty = data[1]["base"][..., 1][paired]
    assert rows.loc["ty", "reference_mean_abs"] == pytest.approx(1e3 * base_ty.mean())
    assert rows.loc["ty", "variant_max_abs"] == pytest.approx(1e3 * (base_ty.max() + TY_SHIFT_M))
    assert moves_most(table)["distortion"] == "ty"


def test_noise_has_zero_shift_and_measured_spread(table, data):
    rows = table.loc["noise"]
    np.testing.assert_allclose(rows["mean_signed_shift"], 0.0, atol=1e-12)
    visible = data[1]["visible"]
    jitter = data[1]["jitter"][visible]  # (config, axis)
    np.testing.assert_allclose(rows["variant_noise"], 1e3 * np.sqrt(2) * np.abs(jitter).mean(0))
    np.testing.assert_allclose(rows["reference_noise"], 0.0, atol=1e-12)
    err = data[1]["error"][2][:, visible]  # (repeat, config, axis)
    base = data[1]["base"][visible]
    change = np.abs(err).mean(0) - np.abs(base)
    np.testing.assert_allclose(rows["change_mean_abs"], 1e3 * change.mean(0), atol=1e-12)
    assert (rows["variant_detection_rate"] == 1.0).all()


def test_binned_changes(data):
    cmp = compare_variants(data[0])
    by_p = binned_change_table(cmp, "distance")
    assert list(by_p.index.get_level_values("bin")[:3]) == [
        "near (p 0-4)",
        "mid (p 5-9)",
        "far (p 10-14)",
    ]
    np.testing.assert_allclose(by_p.loc["distortion", "ty"], 2.0, atol=1e-9)
    np.testing.assert_allclose(by_p.loc["distortion", "tx"], 0.0, atol=1e-12)
    by_angle = binned_change_table(cmp, "angle")
    n_visible = int(data[1]["visible"].sum())
    assert by_angle.loc["noise", "n"].sum() == n_visible  # 0-20, 20-40, 40+ cover all
    # theta stops of 10 deg within 80 deg of facing, per tag: 0-20: -10, 0, 10; 20-40: +-20, +-30
    assert by_angle.loc[("noise", "0-20 deg"), "n"] == 3 * len(TAGS) * len(PS)
    assert by_angle.loc[("noise", "20-40 deg"), "n"] == 4 * len(TAGS) * len(PS)
    np.testing.assert_allclose(by_angle.loc["distortion", "ty"], 2.0, atol=1e-9)
    signed = binned_change_table(cmp, "angle", variable="signed_shift")
    np.testing.assert_allclose(signed.loc["noise", ["tx", "ty", "rz"]], 0.0, atol=1e-12)
    per_p = change_by_p(cmp)
    assert per_p.dims == ("variant", "p", "axis")
    np.testing.assert_allclose(per_p.sel(variant="distortion", axis="ty"), 2.0, atol=1e-9)


def test_view_angle_wraps_around_each_tags_facing(data):
    angle = compare_variants(data[0])["view_angle_deg"]
    assert float(angle.sel(tag=0).isel(theta=0)) == 0.0
    assert float(angle.sel(tag=1).isel(theta=18)) == 0.0
    assert abs(float(angle.sel(tag=1).isel(theta=0))) == pytest.approx(180.0)
    assert float(angle.sel(tag=0).isel(theta=35)) == pytest.approx(-10.0)


def test_visible_per_variant_and_other_baseline():
    ds, _ = synthetic(variant_visible=True)
    assert ds["visible"].dims == ("variant", "tag", "p", "theta")
    table = variant_summary_table(ds, baseline="distortion")
    assert list(table.index.get_level_values("variant").unique()) == ["baseline", "noise"]
    assert table.loc[("baseline", "ty"), "mean_signed_shift"] == pytest.approx(-2.0, abs=1e-9)


def test_write_comparison_files(data, tmp_path):
    paths = write_comparison(data[0], tmp_path / "cmp")
    assert {p.name for p in paths} == EXPECTED_FILES
    assert {p.name for p in (tmp_path / "cmp").iterdir()} == EXPECTED_FILES  # no temp files
    for path in paths:
        assert path.stat().st_size > 0
    text = (tmp_path / "cmp" / "comparison.md").read_text()
    assert "Variant comparison against `baseline`" in text
    assert "`distortion` moves **ty** most" in text
    assert "Mean signed shift [mm]" in text and "Mean signed shift [mrad]" in text
    assert "+2.000" in text
    assert "![change_heatmap_noise](change_heatmap_noise.png)" in text


def test_cli_compare_errors_exit_2_naming_the_file(data, tmp_path):
    runner = CliRunner()
    nc = write_netcdf(data[0], tmp_path / "v.nc")
    out = tmp_path / "cmp"
    result = runner.invoke(app, ["compare", str(nc), "-o", str(out), "--baseline", "nope"])
    assert result.exit_code == 2
    assert str(nc) in result.output and "'nope'" in result.output and "'noise'" in result.output
    single = write_netcdf(data[0].isel(variant=[0]), tmp_path / "one.nc")
    result = runner.invoke(app, ["compare", str(single), "-o", str(out)])
    assert result.exit_code == 2
    assert str(single) in result.output and "needs at least two variants" in result.output
    result = runner.invoke(app, ["compare", str(tmp_path / "missing.nc"), "-o", str(out)])
    assert result.exit_code == 2 and "missing.nc" in result.output
    assert not out.exists()


def test_cli_compare_and_report_call_the_comparison(data, tmp_path, monkeypatch):
    """Wiring only (the files are checked above): stubs keep this test free of plotting."""
    import simgap.analysis.report as report_module

    calls = []

    def fake_comparison(ds, out_dir, baseline=None, progress=None):
        calls.append(("compare", list(ds["variant"].values), Path(out_dir), baseline))
        return [Path(out_dir) / "comparison.md"]

    def fake_report(ds, out_dir, **kwargs):
        calls.append(("report", list(ds["variant"].values), Path(out_dir), None))
        return [Path(out_dir) / "summary.md"]

    monkeypatch.setattr(report_module, "write_comparison", fake_comparison)
    monkeypatch.setattr(report_module, "write_report", fake_report)
    runner = CliRunner()
    nc = write_netcdf(data[0], tmp_path / "v.nc")
    out = tmp_path / "out"
    result = runner.invoke(app, ["compare", str(nc), "-o", str(out), "--baseline", "noise"])
    assert result.exit_code == 0, result.output
    assert calls == [("compare", list(VARIANTS), out, "noise")]
    assert str(out / "comparison.md") in result.output
    calls.clear()
    result = runner.invoke(app, ["report", str(nc), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert calls == [("report", list(VARIANTS), out, None), ("compare", list(VARIANTS), out, None)]
    assert "summary.md" in result.output and "comparison.md" in result.output
    calls.clear()
    single = write_netcdf(data[0].isel(variant=[0]), tmp_path / "one.nc")
    result = runner.invoke(app, ["report", str(single), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert [c[0] for c in calls] == ["report"]


def _python3_kernel_manager(tmp_path: Path):
    """A kernel manager for a ``python3`` kernel run by this interpreter (no global install)."""
    from jupyter_client.kernelspec import KernelSpecManager
    from jupyter_client.manager import KernelManager

    spec_dir = tmp_path / "kernels" / "python3"
    spec_dir.mkdir(parents=True)
    spec = {
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "Python 3 (simgap test)",
        "language": "python",
    }
    (spec_dir / "kernel.json").write_text(json.dumps(spec))
    specs = KernelSpecManager(kernel_dirs=[str(tmp_path / "kernels")])
    return KernelManager(kernel_name="python3", kernel_spec_manager=specs)


def test_notebook_runs_on_smoke_variants(smoke_variants_nc, tmp_path, monkeypatch):
    """The notebook executes on the real `experiments/smoke_variants.yaml` dataset."""
    import nbclient
    import nbformat

    nb = nbformat.read(NOTEBOOK, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert not cell.outputs and cell.execution_count is None, "commit with outputs cleared"
    monkeypatch.setenv("SIMGAP_VARIANTS_NC", str(smoke_variants_nc))
    client = nbclient.NotebookClient(
        nb,
        km=_python3_kernel_manager(tmp_path),
        timeout=120,
        resources={"metadata": {"path": str(tmp_path)}},
    )
    client.execute()  # raises CellExecutionError naming the cell if one fails
    errors = [
        out
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.outputs
        if out.output_type == "error"
    ]
    assert not errors
    images = [
        out
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.outputs
        if "image/png" in out.get("data", {})
    ]
    assert len(images) >= 2  # change-by-distance figure and ty heatmap
