"""Tests of simgap.analysis.report on a small synthetic result dataset."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
import xarray as xr

from simgap.analysis.paper import AXES, TABLE2, threshold_for
from simgap.analysis.report import fit_abs_error_slope, summarize_variant, write_report

PITCH_M = 0.0254
TAGS = [0, 1]
PINS = [0, 1, 2]
THETA_DEG = [0.0, 90.0, 180.0, 270.0]
VARIANTS = ["baseline", "other"]
REPEATS = [0, 1]
TY_SLOPE = {0: 0.04, 1: 0.07}  # |ty| error per metre of carriage travel (m/m)
TY_INTERCEPT = 0.001  # m
TY_REPEAT_SPREAD = 0.0002  # m, +- around the mean, smaller than |ty| so the mean of |.| is exact
UNDETECTED = {"tag": 0, "p": 1, "theta": 1}  # visible but never detected (indices)
UNEXPECTED = {"tag": 1, "p": 2, "theta": 0}  # detected although not visible (indices)
EXPECTED_FILES = {
    "error_vs_distance_tag0.png",
    "error_vs_distance_tag1.png",
    "heatmap_tag0.png",
    "heatmap_tag1.png",
    "table2.md",
    "summary.md",
}


def _visible() -> np.ndarray:
    """Tag 0 faces the camera around theta = 0, tag 1 around theta = 180 deg."""
    vis = np.zeros((len(TAGS), len(PINS), len(THETA_DEG)), dtype=bool)
    vis[0][:, [0, 1, 3]] = True
    vis[1][:, [1, 2, 3]] = True
    return vis


def _errors(rng: np.random.Generator) -> np.ndarray:
    """Signed errors (variant, repeat, tag, p, theta, axis); ty follows an exact line in |.|."""
    shape = (len(VARIANTS), len(REPEATS), len(TAGS), len(PINS), len(THETA_DEG), len(AXES))
    err = rng.normal(0.0, 0.004, size=shape)
    err[..., 3:] = rng.normal(0.0, 0.05, size=shape[:-1] + (3,))
    carriage = PITCH_M * np.asarray(PINS, dtype=float)
    sign = np.array([1.0, -1.0, 1.0, -1.0])  # per theta: the sign must not matter for |ty|
    spread = np.array([1.0, -1.0])[:, None, None]  # per repeat
    for t, tag in enumerate(TAGS):
        line = TY_INTERCEPT + TY_SLOPE[tag] * carriage
        ty = sign[None, None, :] * (line[None, :, None] + TY_REPEAT_SPREAD * spread)
        err[0, :, t, :, :, 1] = ty
    err[1] *= 10.0  # the second variant must not leak into the report
    return err


def make_dataset(seed: int = 0) -> xr.Dataset:
    """Build a contract-following dataset: 2 variants x 2 repeats x 2 tags x 3 p x 4 theta."""
    rng = np.random.default_rng(seed)
    visible = _visible()
    detected = np.broadcast_to(visible, (len(VARIANTS), len(REPEATS)) + visible.shape).copy()
    u = UNDETECTED
    detected[:, :, u["tag"], u["p"], u["theta"]] = False
    x = UNEXPECTED
    detected[:, :, x["tag"], x["p"], x["theta"]] = True
    error = _errors(rng)
    error[0, :, x["tag"], x["p"], x["theta"], :] = 99.0  # must be excluded from the report
    error[~detected] = np.nan
    expected = rng.normal(0.0, 0.1, size=(len(TAGS), len(PINS), len(THETA_DEG), len(AXES)))
    estimated = expected[None, None] + error
    pose_dims = ("variant", "repeat", "tag", "p", "theta")
    return xr.Dataset(
        {
            "expected": (("tag", "p", "theta", "axis"), expected, {"units": "m or rad"}),
            "estimated": ((*pose_dims, "axis"), estimated, {"units": "m or rad"}),
            "error": ((*pose_dims, "axis"), error, {"units": "m or rad"}),
            "visible": (("tag", "p", "theta"), visible),
            "detected": (pose_dims, detected),
            "reproj_px": (pose_dims, np.where(detected, 0.3, np.nan), {"units": "px"}),
            "corners": (
                (*pose_dims, "corner", "uv"),
                np.zeros(detected.shape + (4, 2)),
                {"units": "px"},
            ),
        },
        coords={
            "tag": TAGS,
            "p": PINS,
            "theta": np.radians(THETA_DEG),
            "axis": list(AXES),
            "variant": VARIANTS,
            "repeat": REPEATS,
        },
    )


def reference_abs_error(ds: xr.Dataset) -> np.ndarray:
    """Independent numpy reduction: first variant, mean over repeats of |error|, visible only."""
    err = ds["error"].transpose("variant", "repeat", "tag", "p", "theta", "axis").values[0]
    det = ds["detected"].transpose("variant", "repeat", "tag", "p", "theta").values[0]
    err = np.where(det[..., None], np.abs(err), np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN slices: "Mean of empty slice"
        mean = np.nanmean(err, axis=0)
    vis = ds["visible"].transpose("tag", "p", "theta").values
    return np.where(vis[..., None], mean, np.nan)  # (tag, p, theta, axis)


def parse_markdown_rows(text: str, first_cells: set[str]) -> list[list[str]]:
    """Return the cells of Markdown table rows whose first cell is in `first_cells`."""
    rows = []
    for line in text.splitlines():
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if cells[0] in first_cells:
                rows.append(cells)
    return rows


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> tuple[xr.Dataset, list[Path]]:
    ds = make_dataset()
    out_dir = tmp_path_factory.mktemp("report") / "nested"
    return ds, write_report(ds, out_dir)


def test_writes_expected_files(report: tuple[xr.Dataset, list[Path]]) -> None:
    _, paths = report
    assert {p.name for p in paths} == EXPECTED_FILES
    assert all(p.is_file() and p.stat().st_size > 0 for p in paths)
    leftovers = [p.name for p in paths[0].parent.iterdir() if p.name not in EXPECTED_FILES]
    assert leftovers == []  # no temporary files left behind


def test_figures_are_non_trivial_pngs(report: tuple[xr.Dataset, list[Path]]) -> None:
    _, paths = report
    for path in (p for p in paths if p.suffix == ".png"):
        image = mpimg.imread(path)
        assert image.ndim == 3 and image.shape[0] > 400 and image.shape[1] > 800, path.name
        rgb = image[..., :3]
        assert rgb.std() > 0.05, path.name
        assert (rgb.min(axis=-1) < 0.9).mean() > 0.02, path.name  # enough non-white pixels
        assert (np.ptp(rgb, axis=-1) > 0.2).mean() > 0.005, path.name  # some colour, not just ink


def test_table2_numbers_match_numpy(report: tuple[xr.Dataset, list[Path]]) -> None:
    ds, paths = report
    text = (paths[0].parent / "table2.md").read_text()
    ref = reference_abs_error(ds)
    rows = parse_markdown_rows(text, set(AXES))
    assert len(rows) == len(AXES) * len(TAGS)
    vis = ds["visible"].values
    for cells in rows:
        axis, unit, tag = cells[0], cells[1], int(cells[2])
        a = AXES.index(axis)
        assert unit == ("m" if axis.startswith("t") else "rad")
        ours_max, ours_min = float(cells[3]), float(cells[4])
        assert ours_max == pytest.approx(np.nanmax(ref[tag, ..., a]), abs=5.1e-7)
        assert ours_min == pytest.approx(np.nanmin(ref[tag, ..., a]), abs=5.1e-7)
        paper = TABLE2[(axis, tag)]
        expected_paper = [
            paper.simulation_max,
            paper.hardware_max,
            paper.simulation_min,
            paper.hardware_min,
        ]
        assert [float(c) for c in cells[5:9]] == expected_paper
        within = int(np.sum(ref[tag, ..., a] <= threshold_for(axis)))
        assert cells[9].startswith(f"{within}/{int(vis[tag].sum())} ")
    assert "99.0" not in text  # the detected-but-not-visible configuration is excluded


def test_detection_rate(report: tuple[xr.Dataset, list[Path]]) -> None:
    ds, paths = report
    text = (paths[0].parent / "table2.md").read_text()
    rows = {int(c[0]): c[1] for c in parse_markdown_rows(text, {"0", "1"})}
    n_rep = ds.sizes["repeat"]
    assert rows[0] == f"{9 * n_rep - n_rep}/{9 * n_rep} ({100 * 8 / 9:.1f} %)"
    assert rows[1] == f"{9 * n_rep}/{9 * n_rep} (100.0 %)"


def test_summary_counts_and_observations(report: tuple[xr.Dataset, list[Path]]) -> None:
    _, paths = report
    text = (paths[0].parent / "summary.md").read_text()
    counts = {c[0]: c[1:] for c in parse_markdown_rows(text, {"0", "1"}) if len(c) == 6}
    assert counts["0"][:3] == ["9", "16", "2"]  # visible configs, detected pairs, failures
    assert counts["1"][:3] == ["9", "18", "0"]
    assert counts["1"][4] == "2"  # detected while not visible, both repeats
    for tag, slope in TY_SLOPE.items():
        assert f"Tag {tag}: |ty| error changes by {slope * 100:.3f} mm per 0.1 m" in text
    assert "`other`" in text  # the unreported variant is named
    for name in EXPECTED_FILES - {"summary.md", "table2.md"}:
        assert f"]({name})" in text


def test_ty_slope_is_exact() -> None:
    ds = make_dataset()
    summary = summarize_variant(ds.isel(variant=0), pin_pitch_m=PITCH_M)
    fit = fit_abs_error_slope(summary, "ty")
    for tag, slope in TY_SLOPE.items():
        assert abs(float(fit["slope"].sel(tag=tag)) - slope) < 1e-9
        assert abs(float(fit["intercept"].sel(tag=tag)) - TY_INTERCEPT) < 1e-9
    assert fit["n_points"].values.tolist() == [8, 9]  # tag 0: one visible config undetected


def test_netcdf_round_trip_gives_same_table(
    report: tuple[xr.Dataset, list[Path]], tmp_path: Path
) -> None:
    ds, paths = report
    nc_path = tmp_path / "result.nc"
    ds.to_netcdf(nc_path, engine="netcdf4")
    with xr.open_dataset(nc_path, engine="netcdf4") as reread:
        new_paths = write_report(reread.load(), tmp_path / "out")
    assert (tmp_path / "out" / "table2.md").read_text() == (
        paths[0].parent / "table2.md"
    ).read_text()
    assert [p.name for p in new_paths] == [p.name for p in paths]


def test_missing_variables_are_named(tmp_path: Path) -> None:
    ds = make_dataset().drop_vars(["visible", "detected"])
    with pytest.raises(
        ValueError, match=re.escape("missing required variables: visible, detected")
    ):
        write_report(ds, tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_missing_coordinate_is_named(tmp_path: Path) -> None:
    ds = make_dataset().drop_vars("repeat")
    with pytest.raises(ValueError, match="missing required coordinates: repeat"):
        write_report(ds, tmp_path)


def test_report_figures_speak_mm_and_mrad() -> None:
    from simgap.analysis.report import plot_error_heatmap, plot_error_vs_distance

    ds = make_dataset()
    summary = summarize_variant(ds.isel(variant=0), pin_pitch_m=PITCH_M)
    for plot in (plot_error_vs_distance, plot_error_heatmap):
        fig = plot(summary, 0)
        titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
        assert any("[mm]" in t and t.startswith("ty") for t in titles), titles
        assert any("[mrad]" in t and t.startswith("rz") for t in titles), titles
        assert not any("[m]" in t or "[rad]" in t for t in titles), titles
    fig = plot_error_vs_distance(summary, 0)
    ty = next(ax for ax in fig.axes if ax.get_title().startswith("ty"))
    assert "threshold 5 mm" in ty.get_title()  # 0.005 m, the mission threshold, in mm
    expected_mm = 1e3 * float(summary.abs_error.sel(tag=0, axis="ty").max())
    drawn = [float(np.nanmax(line.get_ydata())) for line in ty.lines if len(line.get_ydata()) > 2]
    assert max(drawn) == pytest.approx(expected_mm, rel=1e-12)
