"""Figures of the report and the comparison (headless Matplotlib, Agg canvas).

Report: :func:`plot_error_vs_distance` (paper style) and :func:`plot_error_heatmap` of one
variant's :class:`~simgap.analysis.report.summaries.VariantSummary`. Comparison:
:func:`plot_change_by_distance`, :func:`plot_change_heatmap` and
:func:`plot_axis_change_heatmap` of a :func:`~simgap.analysis.report.comparisons.compare_variants`
dataset. Units are the dataset's (m, rad) in the report figures and display units (mm, mrad) in
the comparison figures.
"""

from __future__ import annotations

from typing import Final

import numpy as np
import xarray as xr
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure, SubFigure
from matplotlib.lines import Line2D

from simgap.analysis.paper import threshold_for
from simgap.analysis.report.comparisons import as_comparison, change_by_p
from simgap.analysis.report.summaries import VariantSummary
from simgap.core.axes import AXES, AXIS_UNITS, display_unit

NO_DATA_GREY: Final[str] = "0.75"
"""Colour of cells without data."""
THETA_CMAP: Final[str] = "cividis"
"""Colour map of turntable angles (no red or green: those mark the maximum and minimum)."""
SIGNED_CMAP: Final[str] = "RdBu_r"
"""Diverging colour map of signed errors and changes, centred on 0."""
_MIN_COLOUR_LIMIT: Final[float] = 1e-3  # mm or mrad: an unchanged axis shows white, not noise


# --- shared -----------------------------------------------------------------------------------


def new_figure_grid(title: str) -> tuple[Figure, np.ndarray]:
    """A headless (Agg) figure with a 2x3 grid of axes, one per pose axis, and a title."""
    fig = Figure(figsize=(14, 8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    fig.suptitle(title)
    return fig, axes


def cell_edges(centres: np.ndarray) -> np.ndarray:
    """Return cell edges around sorted cell centres (unit width for a single centre)."""
    if centres.size == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    mid = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[2 * centres[0] - mid[0]], mid, [2 * centres[-1] - mid[-1]]])


# --- report: one variant ---------------------------------------------------------------------


def _theta_deg_around_view(summary: VariantSummary, tag: int) -> np.ndarray:
    """Return turntable angles in deg, unwrapped around the circular mean of the visible ones.

    A tag seen from -80 to 80 deg thus gets angles -80..80 instead of 280..360 and 0..80, so a
    sequential colour map orders them without a jump.
    """
    theta = summary.visible["theta"].values.astype(float)
    seen = summary.visible.sel(tag=tag).any("p").values
    centre = np.angle(np.exp(1j * theta[seen]).sum()) if seen.any() else 0.0
    return np.degrees(centre + np.angle(np.exp(1j * (theta - centre))))


def plot_error_vs_distance(summary: VariantSummary, tag: int) -> Figure:
    """Plot absolute error against carriage position for one tag, paper style.

    Parameters
    ----------
    summary : VariantSummary
        One variant (:func:`~simgap.analysis.report.summaries.summarize_variant`): its
        ``abs_error``, ``carriage_m`` and detections are drawn.
    tag : int
        Tag id of the figure.

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels (tx, ty, tz / rx, ry, rz): repeat-averaged absolute error (m or rad) against
        carriage position (m), one line per turntable angle with a visible configuration (angles
        unwrapped around the tag's mean viewing angle, so the colour bar may show negative
        degrees), the high-precision threshold as a dashed line, the largest and smallest
        error circled in red and green, and every visible but undetected configuration as an
        ``x`` at the top of the panel.
    """
    fig, axes = new_figure_grid(
        f"Tag {tag}: absolute pose error vs carriage position (variant {summary.variant!r}, "
        f"mean of {summary.n_repeat} repeat(s))"
    )
    theta_deg = _theta_deg_around_view(summary, tag)
    seen = summary.visible.sel(tag=tag).any("p").values
    shown = theta_deg[seen] if seen.any() else theta_deg
    cmap = ListedColormap(colormaps[THETA_CMAP](np.linspace(0.0, 0.85, 256)))  # no pale yellow
    norm = Normalize(float(shown.min()), float(shown.max()))
    colours = cmap(norm(theta_deg))
    for ax, axis in zip(axes.flat, AXES, strict=True):
        _draw_error_vs_distance(ax, summary, tag, axis, colours)
    for ax in axes[-1]:
        ax.set_xlabel(f"carriage position {summary.pin_pitch_m:g}·p [m]")
    fig.colorbar(ScalarMappable(norm, cmap), ax=axes, label="turntable angle θ [deg]")
    fig.legend(handles=_legend_handles(), loc="outside lower center", ncols=4)
    return fig


def _legend_handles() -> list[Line2D]:
    return [
        Line2D([], [], color="k", ls="--", label="high-precision threshold"),
        Line2D([], [], color="0.3", marker="x", ls="none", label="visible, not detected"),
        Line2D([], [], color="red", marker="o", mfc="none", ls="none", label="maximum"),
        Line2D([], [], color="green", marker="o", mfc="none", ls="none", label="minimum"),
    ]


def _draw_error_vs_distance(
    ax: Axes, summary: VariantSummary, tag: int, axis: str, colours: np.ndarray
) -> None:
    """Draw one panel of :func:`plot_error_vs_distance`; `colours` is RGBA per theta."""
    x = summary.carriage_m.values
    y = summary.abs_error.sel(tag=tag, axis=axis).transpose("p", "theta").values
    visible = summary.visible.sel(tag=tag).transpose("p", "theta").values
    undetected = visible & ~summary.detected_any.sel(tag=tag).transpose("p", "theta").values
    for j in np.flatnonzero(visible.any(axis=0)):
        ax.plot(x, y[:, j], marker="o", ms=3, lw=1, color=colours[j])
    _mark_extremes(ax, x, y)
    threshold = threshold_for(axis)
    ax.axhline(threshold, color="k", ls="--", lw=1)
    rows, cols = np.nonzero(undetected)
    ax.scatter(
        x[rows],
        np.full(rows.size, 0.97),
        c=colours[cols],
        marker="x",
        transform=ax.get_xaxis_transform(),
        clip_on=False,
        zorder=3,
    )
    top = max(threshold, float(np.nanmax(y, initial=0.0)))
    ax.set_ylim(0.0, 1.15 * top)
    unit = AXIS_UNITS[axis]
    ax.set_title(f"{axis}: |error| [{unit}], threshold {threshold:g} {unit}")
    ax.set_ylabel(f"|{axis} error| [{unit}]")
    ax.grid(alpha=0.3)


def _mark_extremes(ax: Axes, x: np.ndarray, y: np.ndarray) -> None:
    """Circle the largest (red) and smallest (green) finite value of ``y[p, theta]``."""
    if not np.isfinite(y).any():
        return
    for reducer, colour in ((np.nanargmax, "red"), (np.nanargmin, "green")):
        flat = int(reducer(y))
        ax.plot(
            x[flat // y.shape[1]], y.flat[flat], marker="o", ms=9, mfc="none", mec=colour, mew=1.5
        )


def plot_error_heatmap(summary: VariantSummary, tag: int) -> Figure:
    """Plot the signed error of one tag over pin hole and turntable angle.

    Parameters
    ----------
    summary : VariantSummary
        One variant (:func:`~simgap.analysis.report.summaries.summarize_variant`): its
        ``signed_error`` is drawn, and its undetected cells marked.
    tag : int
        Tag whose panels are drawn.

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels, repeat-averaged signed error (m or rad) with theta (deg, unwrapped around the
        tag's mean viewing angle, so it may be negative) across and p up,
        a diverging colour map centred on 0 with symmetric limits per panel, grey where there is
        no estimate (not visible or not detected) and ``x`` on visible but undetected cells.
    """
    fig, axes = new_figure_grid(
        f"Tag {tag}: signed pose error (variant {summary.variant!r}, mean of "
        f"{summary.n_repeat} repeat(s)); grey: no estimate, x: visible but not detected"
    )
    for ax, axis in zip(axes.flat, AXES, strict=True):
        _draw_heatmap(fig, ax, summary, tag, axis)
    return fig


def _on_view_grid(da: xr.DataArray, theta_deg: xr.DataArray) -> xr.DataArray:
    """Sort a ``(p, theta)`` array by p and by `theta_deg`, the angle unwrapped around the view."""
    return da.assign_coords(theta_deg=theta_deg).sortby(["p", "theta_deg"]).transpose("p", "theta")


def _draw_heatmap(fig: Figure, ax: Axes, summary: VariantSummary, tag: int, axis: str) -> None:
    """Draw one panel of :func:`plot_error_heatmap`."""
    theta_deg = xr.DataArray(
        _theta_deg_around_view(summary, tag), coords={"theta": summary.visible["theta"]}
    )
    signed = _on_view_grid(summary.signed_error.sel(tag=tag, axis=axis), theta_deg)
    values = signed.values
    theta = signed["theta_deg"].values
    p = signed["p"].values.astype(float)
    limit = float(np.nanmax(np.abs(values), initial=0.0)) or 1e-12
    cmap = colormaps[SIGNED_CMAP].with_extremes(bad=NO_DATA_GREY)
    mesh = ax.pcolormesh(
        cell_edges(theta),
        cell_edges(p),
        np.ma.masked_invalid(values),
        cmap=cmap,
        norm=Normalize(-limit, limit),
    )
    undetected = _on_view_grid((summary.visible & ~summary.detected_any).sel(tag=tag), theta_deg)
    rows, cols = np.nonzero(undetected.values)
    ax.plot(theta[cols], p[rows], "kx", ms=6, ls="none")
    unit = AXIS_UNITS[axis]
    fig.colorbar(mesh, ax=ax, label=f"{axis} error [{unit}]")
    ax.set_title(f"{axis}: signed error (estimated − expected) [{unit}]")
    ax.set_xlabel("turntable angle θ [deg]")
    ax.set_ylabel("pin hole p")


# --- comparison: variants against the reference --------------------------------------------


def plot_change_by_distance(
    data: xr.Dataset, baseline: str | None = None, title: str | None = None
) -> Figure:
    """Plot the change of mean ``|error|`` against pin hole, one line per variant.

    Parameters
    ----------
    data, baseline
        What to compare, as in :func:`~simgap.analysis.report.comparisons.as_comparison`.
    title : str, optional
        Figure title; default names the variant - reference change of mean ``|error|``.

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels (tx, ty, tz / rx, ry, rz): variant - reference mean ``|error|`` (mm or mrad)
        over paired (tag, theta) against pin hole p, with a zero line.
    """
    cmp = as_comparison(data, baseline)
    change = change_by_p(cmp)
    fig, axes = new_figure_grid(
        title
        or f"Change of mean |error| vs distance (variant − {cmp.attrs['baseline']!r}, paired "
        "configurations, both tags, all view angles)"
    )
    p = change["p"].values
    for ax, axis in zip(axes.flat, AXES, strict=True):
        for variant in change["variant"].values:
            ax.plot(p, change.sel(variant=variant, axis=axis), marker="o", ms=3, label=variant)
        ax.axhline(0.0, color="k", lw=0.8)
        unit = display_unit(axis)[0]
        ax.set_title(f"{axis}: change of mean |error| [{unit}]")
        ax.set_ylabel(f"Δ mean |{axis} error| [{unit}]")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("pin hole p")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=max(1, len(labels)))
    return fig


def _draw_change_heatmap(
    fig: Figure | SubFigure, ax: Axes, cmp: xr.Dataset, variant: str, tag: int, axis: str
) -> None:
    """Draw the signed shift of one variant, tag and axis over (view angle, p)."""
    unit, scale = display_unit(axis)
    signed = cmp["signed_shift"].sel(variant=variant, tag=tag, axis=axis) * scale
    signed = signed.assign_coords(angle=cmp["view_angle_deg"].sel(tag=tag))
    signed = signed.sortby(["p", "angle"]).transpose("p", "theta")
    shared = np.abs(cmp["signed_shift"].sel(variant=variant, axis=axis).values) * scale
    limit = max(float(np.nanmax(shared, initial=0.0)), _MIN_COLOUR_LIMIT)
    angle_edges = cell_edges(signed["angle"].values)
    mesh = ax.pcolormesh(
        angle_edges,
        cell_edges(signed["p"].values.astype(float)),
        np.ma.masked_invalid(signed.values),
        cmap=colormaps[SIGNED_CMAP].with_extremes(bad=NO_DATA_GREY),
        norm=Normalize(-limit, limit),
    )
    columns = np.flatnonzero(np.isfinite(signed.values).any(axis=0))
    if columns.size:  # show the paired angles plus one grey cell on each side
        lo, hi = max(columns[0] - 1, 0), min(columns[-1] + 1, angle_edges.size - 2)
        ax.set_xlim(angle_edges[lo], angle_edges[hi + 1])
    fig.colorbar(mesh, ax=ax, label=f"Δ {axis} [{unit}]")
    ax.set_title(f"tag {tag}, {axis}: signed change [{unit}]")
    ax.set_xlabel("view angle from facing [deg]")
    ax.set_ylabel("pin hole p")
    ax.set_yticks(signed["p"].values)


def plot_change_heatmap(data: xr.Dataset, variant: str, baseline: str | None = None) -> Figure:
    """Plot the mean signed error change of one variant over (view angle, p), all axes and tags.

    Parameters
    ----------
    data : xarray.Dataset
        What to compare, with `baseline`, as in
        :func:`~simgap.analysis.report.comparisons.as_comparison`.
    variant : str
        A compared (non-reference) variant.
    baseline : str, optional
        Reference variant.

    Returns
    -------
    matplotlib.figure.Figure
        One block of 2x3 panels (tx, ty, tz / rx, ry, rz) per tag: repeat-mean signed error,
        variant - reference, in mm or mrad, over view angle (deg, 0 = facing the camera) and pin
        hole; diverging colours centred on 0 with limits shared by the tags of an axis; grey
        where the configuration is not paired.
    """
    cmp = as_comparison(data, baseline)
    _check_compared(cmp, variant)
    tags = [int(t) for t in cmp["tag"].values]
    fig = Figure(figsize=(15, 7.5 * len(tags)), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(
        f"Signed error change, {variant!r} − {cmp.attrs['baseline']!r} (mean of "
        f"{cmp.attrs['n_repeat']} repeat(s)); grey: not paired"
    )
    for sub, tag in zip(np.atleast_1d(fig.subfigures(len(tags), 1)), tags, strict=True):
        sub.suptitle(f"Tag {tag}")
        for ax, axis in zip(sub.subplots(2, 3).flat, AXES, strict=True):
            _draw_change_heatmap(sub, ax, cmp, variant, tag, axis)
    return fig


def plot_axis_change_heatmap(
    data: xr.Dataset, variant: str, axis: str = "ty", baseline: str | None = None
) -> Figure:
    """Plot the mean signed error change of one variant and one axis, one panel per tag.

    As :func:`plot_change_heatmap` (same `data`, `variant` and `baseline`) for the one pose
    ``axis`` (default ``"ty"``, the depth): one panel per tag, in mm or mrad.
    """
    cmp = as_comparison(data, baseline)
    _check_compared(cmp, variant)
    if axis not in AXES:
        raise ValueError(f"axis must be one of {', '.join(AXES)}; got {axis!r}")
    tags = [int(t) for t in cmp["tag"].values]
    fig = Figure(figsize=(6 * len(tags), 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(f"Signed {axis} error change, {variant!r} − {cmp.attrs['baseline']!r}")
    for ax, tag in zip(np.atleast_1d(fig.subplots(1, len(tags))), tags, strict=True):
        _draw_change_heatmap(fig, ax, cmp, variant, tag, axis)
    return fig


def _check_compared(cmp: xr.Dataset, variant: str) -> None:
    compared = [str(v) for v in cmp["variant"].values]
    if variant not in compared:
        raise ValueError(
            f"variant {variant!r} is not compared (the reference is {cmp.attrs['baseline']!r}); "
            f"compared variants: {compared}"
        )
