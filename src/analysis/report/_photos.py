"""The report of a board's photo set, written from its dataset alone (``simgap report``).

A photo dataset is :func:`simgap.pipeline.photos.measure_photos`'s (``simgap ingest --board``):
each marker sighting's single-marker pose error against the board's reference, in the OpenCV
camera frame (x right, y down, z depth; + farther than the reference says). With ``--simulate``
it holds the photos' simulation along ``image`` (:data:`simgap.analysis.gap.PHOTO_IMAGES`: the
nominal simulation and the one with the camera fitted on the other cross-fit fold), and the
report reads the gap before and after as the PASS diagnosis does: where (thirds of distance,
view angle and image radius), which (the camera's fitted exposure and blur, the rig's geometry
against an external reference), how far (the held-out gap after, mm).

Files written (each atomically):

============================  ===================================================================
``photo_report.md``           the set, errors near / mid / far (mm, mrad), the calibration file
                              held against the photos, and with a simulation the camera fitted,
                              the gap before -> after per third, the rig
``photo_errors.png``          x, y and depth error (mm) of every sighting against distance (m),
                              real and simulated, with each third's median
``photo_gap.png``             with a simulation: the median depth gap (mm) per third of
                              distance, view angle and image radius, before and after
============================  ===================================================================
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from simgap.analysis.gap import PHOTO_IMAGES, PhotoGaps, photo_gaps
from simgap.analysis.report._output import save_figure, save_text
from simgap.analysis.report._tables import markdown_table, signed
from simgap.core.board import Board
from simgap.core.config import ConfigError, from_mapping
from simgap.pipeline.photos import CALIBRATION_CHECK, PHOTO_SOURCE
from simgap.pose.calibration_check import DISAGREE_SIGMAS, MIN_RMS_FALL, FileCheck
from simgap.results.photo_summary import COVARIATES, BandGap, errors_by_distance

#: The report's Markdown file.
PHOTO_REPORT = "photo_report.md"
#: The figure of every sighting's error against distance.
PHOTO_ERRORS_FIGURE = "photo_errors.png"
#: The figure of the gap per third, before and after.
PHOTO_GAP_FIGURE = "photo_gap.png"
#: Colours of the real photos, the simulation and the fitted simulation in the figures.
_COLOURS = {"real": "black", "simulated": "tab:blue", "simulated_fitted": "tab:orange"}
_LABELS = {
    "real": "real photos",
    "simulated": "simulated",
    "simulated_fitted": "simulated, camera fitted (other half)",
}


def is_photo_dataset(ds: xr.Dataset) -> bool:
    """Whether ``ds`` is a board's photo set (``simgap ingest --board``), not a PASS result."""
    return ds.attrs.get("source") == PHOTO_SOURCE


def dataset_board(ds: xr.Dataset) -> Board:
    """The board a photo dataset was measured on (its ``board`` attribute).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the attribute where it is missing or holds no board.
    """
    return from_mapping(Board, attribute_mapping(ds, "board"), where="attribute board: ")


def attribute_mapping(ds: xr.Dataset, name: str) -> dict:
    """A photo dataset's attribute ``name`` that holds a mapping (written as its ``repr``).

    Raises
    ------
    simgap.core.config.ConfigError
        ``attribute <name>: expected ...`` where it is missing or no mapping.
    """
    try:
        value = ast.literal_eval(str(ds.attrs[name]))
    except (KeyError, ValueError, SyntaxError):
        value = None
    if not isinstance(value, dict):
        raise ConfigError(
            f"attribute {name}: expected the mapping simgap ingest --board writes, got "
            f"{ds.attrs.get(name)!r}"
        )
    return value


def board_text(board: Board) -> str:
    """The board in words: kind, squares or markers, sizes (mm) and dictionary."""
    size = f"{board.columns} x {board.rows}"
    if board.kind == "charuco":
        assert board.square_m is not None
        return (
            f"ChArUco {size} squares of {1e3 * board.square_m:g} mm, markers of "
            f"{1e3 * board.marker_m:g} mm, {board.dictionary}"
        )
    assert board.separation_m is not None
    return (
        f"grid of {size} markers of {1e3 * board.marker_m:g} mm, {1e3 * board.separation_m:g} mm "
        f"apart, {board.dictionary}"
    )


def calibration_text(camera: dict) -> str:
    """A calibration (the photo dataset's ``calibration`` attribute) in words (px)."""
    coefficients = ", ".join(f"{c:.4g}" for c in camera.get("distortion", ()))
    return (
        f"{camera['width']} x {camera['height']} px, fx {camera['fx']:.1f} px, fy "
        f"{camera['fy']:.1f} px, principal point ({camera['cx']:.1f}, {camera['cy']:.1f}) px, "
        f"{camera.get('distortion_model', 'plumb_bob')} ({coefficients})"
    )


def write_photo_report(ds: xr.Dataset, output: Path) -> list[Path]:
    """Write a photo dataset's report into the folder ``output``; return the paths written.

    Parameters
    ----------
    ds : xarray.Dataset
        A photo dataset (:func:`is_photo_dataset`), with or without its simulation.
    output : Path
        The report folder (created).
    """
    output.mkdir(parents=True, exist_ok=True)
    simulated = "image" in ds.dims
    real = ds.sel(image="real", drop=True) if simulated else ds
    board = dataset_board(ds)
    gaps = photo_gaps(ds, board) if simulated else None
    paths = [save_figure(plot_photo_errors(ds), output / PHOTO_ERRORS_FIGURE)]
    if gaps is not None:
        paths.append(save_figure(plot_photo_gap(gaps), output / PHOTO_GAP_FIGURE))
    text = photo_report_markdown(ds, real, board, gaps, [p.name for p in paths])
    paths.append(save_text(text, output / PHOTO_REPORT))
    return paths


def photo_report_markdown(
    ds: xr.Dataset, real: xr.Dataset, board: Board, gaps: PhotoGaps | None, figures: list[str]
) -> str:
    """The report's Markdown: the set, its errors, and with a simulation the gap and its causes."""
    seen = int(real["detected"].sum())
    lines = [
        "# Single-marker pose against the board: real photos",
        "",
        f"- Photos: {ds.attrs.get('frames')} ({ds.attrs.get('frames_unreadable')} unreadable); "
        f"{seen} marker sightings against the {ds.attrs.get('reference')}.",
        f"- Board: {board_text(board)}.",
        f"- Calibration: {calibration_text(attribute_mapping(ds, 'calibration'))}.",
        "- Errors in the OpenCV camera frame: x right, y down, z depth (+ farther than the "
        "reference); medians per third of the sightings' distances.",
        "",
        "## Errors near / mid / far",
        "",
    ]
    header = ["band", "distance (m)", "sightings", "x (mm)", "y (mm)", "depth (mm)"]
    header += [f"abs {a} (mrad)" for a in ("rx", "ry", "rz")]
    rows = [
        [b.band, f"{b.distance_min_m:.3f}-{b.distance_max_m:.3f}", str(b.markers)]
        + [signed(v, 2) for v in b.translation_median_mm]
        + [f"{v:.1f}" for v in b.rotation_median_abs_mrad]
        for b in errors_by_distance(real)
    ]
    lines += markdown_table(header, rows)
    if CALIBRATION_CHECK in ds.attrs:
        lines += calibration_check_lines(dataset_calibration_check(ds))
    if gaps is not None:
        lines += _simulation_lines(ds, gaps)
    lines += ["", "## Figures", ""] + [f"![{name}]({name})" for name in figures]
    return "\n".join(lines) + "\n"


def dataset_calibration_check(ds: xr.Dataset) -> FileCheck:
    """The calibration file held against the photos, as ``ingest --board`` recorded it.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the attribute (:data:`CALIBRATION_CHECK`) where it holds no such check.
    """
    mapping = attribute_mapping(ds, CALIBRATION_CHECK)
    try:
        return FileCheck.from_mapping(mapping)
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(
            f"attribute {CALIBRATION_CHECK}: expected the check simgap ingest --board writes "
            f"({exc!r} in {mapping!r})"
        ) from None


def calibration_check_lines(check: FileCheck) -> list[str]:
    """The report's section on the calibration file held against the photos."""
    header = ["parameter", "correction", "jackknife sd", "RMS before -> after (px)", "verdict"]
    rows = [
        [
            c.name,
            c.value,
            f"{c.std:.2g} {c.unit}".rstrip(),
            f"{c.rms_before_px:.3f} -> {c.rms_after_px:.3f}",
            "**does not describe the photos**" if c.disagrees else "-",
        ]
        for c in check.parameters
    ]
    return [
        "",
        "## The calibration file held against the photos",
        "",
        f"Against {check.against}: each parameter corrected alone, the file's others kept, to "
        "the least RMS reprojection of all board points; a fault where the correction is "
        f"{DISAGREE_SIGMAS:g} jackknife sd from zero and lowers the RMS by "
        f"{100 * MIN_RMS_FALL:g} % (simgap.pose.calibration_check).",
        "",
        *markdown_table(header, rows),
        "",
        check.verdict("The file") + ".",
    ]


def _simulation_lines(ds: xr.Dataset, gaps: PhotoGaps) -> list[str]:
    """The camera fitted, the gap before -> after per third, and the rig."""
    edge = {
        name: float(np.nanmedian(ds["edge_width"].sel(image=name).values)) for name in PHOTO_IMAGES
    }
    lines = [
        "",
        "## Which: the camera, fitted on the markers' images",
        "",
        f"Each photo rendered at its reference pose ({ds.attrs.get('render_spp')} spp, seed "
        f"{ds.attrs.get('render_seed')}) and measured as the photo is. Fitted on the paper level "
        "and the edge width around the markers, never on the pose: exposure "
        f"**{float(ds.attrs['fitted_exposure_ev']):+.2f} EV**, blur "
        f"**{float(ds.attrs['fitted_blur_sigma_px']):.3f} px**. Median edge width "
        f"{edge['real']:.3f} px real, {edge['simulated']:.3f} px simulated, "
        f"{edge['simulated_fitted']:.3f} px with the camera fitted.",
        "",
        "## Where and how far: real - simulated",
        "",
        "Median over the sightings seen in both of real minus simulated error (mm), in thirds of "
        "the sightings seen in both before (each third's range); after: each photo simulated "
        "with the camera fitted on the other half of the photos"
        + (", then the rig's model fitted on the other half taken off" if gaps.after_rig else "")
        + ".",
    ]
    for covariate, (unit, _) in COVARIATES.items():
        header = ["band", f"{covariate.replace('_', ' ')} ({unit})", "sightings", "depth real"]
        header += ["depth simulated", "depth gap before", "depth gap after", "x, y gap after"]
        after = {a.band: a for a in gaps.after_rig.get(covariate) or gaps.after[covariate]}
        rows = [
            [b.band, f"{b.low:.3g}-{b.high:.3g}", str(b.markers)]
            + [signed(v, 2) for v in (b.real_median_mm[2], b.simulated_median_mm[2])]
            + [signed(b.gap_median_mm[2], 2)]
            + _after_cells(after.get(b.band))
            for b in gaps.before[covariate]
        ]
        lines += [""] + markdown_table(header, rows)
    if gaps.rig is not None:
        lines += ["", "## The rig's own geometry", "", "```"]
        lines += gaps.rig.lines(str(ds.attrs.get("reference")))
        lines += ["```"]
    return lines


def _after_cells(band: BandGap | None) -> list[str]:
    """The depth gap after (bold) and the x, y gap after of a third (``n/a`` where none)."""
    if band is None:
        return ["n/a", "n/a"]
    x, y, z = band.gap_median_mm
    return [f"**{signed(z, 2)}**", f"{signed(x, 2)}, {signed(y, 2)}"]


def plot_photo_errors(ds: xr.Dataset) -> Figure:
    """x, y and depth error (mm) of every sighting against distance (m), per image source."""
    fig = Figure(figsize=(13, 4.2), layout="constrained")
    axes = fig.subplots(1, 3, sharex=True)
    names = [str(n) for n in ds["image"].values] if "image" in ds.dims else ["real"]
    for name in names:
        one = ds.sel(image=name, drop=True) if "image" in ds.dims else ds
        dist = one["distance"].transpose("frame", "marker").values.ravel()
        err = one["error_translation"].transpose("frame", "marker", "camera_axis").values
        err = 1e3 * err.reshape(-1, 3)
        ok = np.isfinite(dist) & np.isfinite(err).all(axis=1)
        bands = errors_by_distance(one)
        for k, ax in enumerate(axes):
            ax.plot(dist[ok], err[ok, k], ".", ms=3, alpha=0.35, color=_COLOURS[name])
            centres = [(b.distance_min_m + b.distance_max_m) / 2 for b in bands]
            medians = [b.translation_median_mm[k] for b in bands]
            ax.plot(centres, medians, "o-", color=_COLOURS[name], label=_LABELS[name])
    for ax, axis in zip(axes, ("x (right)", "y (down)", "depth (z)"), strict=True):
        ax.axhline(0.0, color="grey", lw=0.8)
        ax.set_xlabel("distance (m)")
        ax.set_ylabel(f"{axis} error (mm)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Single-marker error against the board's reference; lines: medians per third")
    return fig


def plot_photo_gap(gaps: PhotoGaps) -> Figure:
    """Median depth gap (mm) per third of each covariate, before and after."""
    fig = Figure(figsize=(13, 4.2), layout="constrained")
    axes = fig.subplots(1, len(COVARIATES), sharey=True)
    for ax, (covariate, (unit, _)) in zip(axes, COVARIATES.items(), strict=True):
        series: list[tuple[str, list[BandGap]]] = [
            ("before", gaps.before[covariate]),
            ("camera fitted", gaps.after[covariate]),
        ]
        if gaps.after_rig:
            series.append(("camera and rig fitted", gaps.after_rig[covariate]))
        width = 0.8 / len(series)
        for k, (label, bands) in enumerate(series):
            x = np.arange(len(bands)) + (k - (len(series) - 1) / 2) * width
            ax.bar(x, [b.gap_median_mm[2] for b in bands], width, label=label)
        bands = gaps.before[covariate]
        ax.set_xticks(np.arange(len(bands)), [f"{b.band}\n{b.low:.3g}-{b.high:.3g}" for b in bands])
        ax.axhline(0.0, color="grey", lw=0.8)
        ax.set_xlabel(f"{covariate.replace('_', ' ')} ({unit})")
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("depth gap, real - simulated (mm)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Where the gap lies, and how far it shrinks (held-out photos)")
    return fig
