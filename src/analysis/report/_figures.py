"""Figures of the report and the comparison (headless Matplotlib, Agg canvas).

Report: :func:`plot_error_vs_distance` (paper style) and :func:`plot_error_heatmap` of one
variant's :class:`~simgap.analysis.report._summaries.VariantSummary`. Comparison:
:func:`plot_change_by_distance`, :func:`plot_change_heatmap` and
:func:`plot_axis_change_heatmap` of a :func:`~simgap.analysis.report.compare_variants`
dataset. Every figure speaks the display units (mm, mrad; :func:`simgap.core.axes.display_unit`)
of the dataset's m and rad. Their heatmaps' cells, colour limits and legend are
:mod:`simgap.analysis.report._heatmaps`'.
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
from simgap.analysis.report._comparisons import as_comparison, change_by_p
from simgap.analysis.report._heatmaps import (
    ROW_DISTANCE_LABEL,
    heatmap_legend_handles,
    robust_colour_limit,
    row_distance_labels,
    sampled_axis,
    shown_columns,
    signed_mesh,
)
from simgap.analysis.report._summaries import VariantSummary
from simgap.core.axes import AXES, display_unit
from simgap.core.distance import DISTANCE_LABEL

THETA_CMAP: Final[str] = "cividis"
"""Colour map of turntable angles (no red or green: those mark the maximum and minimum)."""
_MIN_COLOUR_LIMIT: Final[float] = 1e-3  # mm or mrad: an unchanged axis shows white, not noise


# --- shared -----------------------------------------------------------------------------------


def new_figure_grid(title: str) -> tuple[Figure, np.ndarray]:
    """A headless (Agg) figure with a 2x3 grid of axes, one per pose axis, and a title."""
    fig = Figure(figsize=(14, 8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    fig.suptitle(title)
    return fig, axes


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
    """Plot absolute error against camera-to-tag distance for one tag, paper style.

    Parameters
    ----------
    summary : VariantSummary
        One variant (:func:`~simgap.analysis.report.summarize_variant`): its
        ``abs_error``, ``distance_m`` and detections are drawn.
    tag : int
        Tag id of the figure.

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels (tx, ty, tz / rx, ry, rz): repeat-averaged absolute error (mm or mrad) against
        camera-to-tag distance (m), one line per turntable angle with a visible configuration
        (angles unwrapped around the tag's mean viewing angle, so the colour bar may show negative
        degrees), the high-precision threshold as a dashed line, the largest and smallest
        error circled in red and green, and every visible but undetected configuration as an
        ``x`` at the top of the panel.
    """
    fig, axes = new_figure_grid(
        f"Tag {tag}: absolute pose error vs camera-to-tag distance (variant {summary.variant!r}, "
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
        ax.set_xlabel(DISTANCE_LABEL)
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
    x = summary.distance_m.sel(tag=tag).transpose("p", "theta").values
    unit, scale = display_unit(axis)
    y = scale * summary.abs_error.sel(tag=tag, axis=axis).transpose("p", "theta").values
    visible = summary.visible.sel(tag=tag).transpose("p", "theta").values
    undetected = visible & ~summary.detected_any.sel(tag=tag).transpose("p", "theta").values
    for j in np.flatnonzero(visible.any(axis=0)):
        ax.plot(x[:, j], y[:, j], marker="o", ms=3, lw=1, color=colours[j])
    _mark_extremes(ax, x, y)
    threshold = scale * threshold_for(axis)
    ax.axhline(threshold, color="k", ls="--", lw=1)
    rows, cols = np.nonzero(undetected)
    ax.scatter(
        x[rows, cols],
        np.full(rows.size, 0.97),
        c=colours[cols],
        marker="x",
        transform=ax.get_xaxis_transform(),
        clip_on=False,
        zorder=3,
    )
    top = max(threshold, float(np.nanmax(y, initial=0.0)))
    ax.set_ylim(0.0, 1.15 * top)
    ax.set_title(f"{axis}: |error| [{unit}], threshold {threshold:g} {unit}")
    ax.set_ylabel(f"|{axis} error| [{unit}]")
    ax.grid(alpha=0.3)


def _mark_extremes(ax: Axes, x: np.ndarray, y: np.ndarray) -> None:
    """Circle the largest (red) and smallest (green) finite value of ``y[p, theta]`` at ``x``."""
    if not np.isfinite(y).any():
        return
    for reducer, colour in ((np.nanargmax, "red"), (np.nanargmin, "green")):
        flat = int(reducer(y))
        ax.plot(x.flat[flat], y.flat[flat], marker="o", ms=9, mfc="none", mec=colour, mew=1.5)


def plot_error_heatmap(summary: VariantSummary, tag: int) -> Figure:
    """Plot the signed error of one tag over turntable angle and pin hole, on the sampled grid.

    Parameters
    ----------
    summary : VariantSummary
        One variant (:func:`~simgap.analysis.report.summarize_variant`): its
        ``signed_error`` is drawn, and its undetected cells marked.
    tag : int
        Tag whose panels are drawn.

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels, repeat-averaged signed error (mm or mrad), one cell per sampled configuration
        (:class:`~simgap.analysis.report._heatmaps.SampledAxis`): theta (deg, unwrapped around
        the tag's mean viewing angle, so it may be negative) across, pin-hole rows up, ticked
        with each row's median camera-to-tag distance (m). A diverging colour map centred on 0
        with a robust symmetric limit per panel (:func:`robust_colour_limit`; cells beyond it
        hatched, counted in the panel's title), grey where there is no estimate (not visible or
        not detected) and ``x`` on visible but undetected cells.
    """
    fig, axes = new_figure_grid(
        f"Tag {tag}: signed pose error (variant {summary.variant!r}, mean of "
        f"{summary.n_repeat} repeat(s))"
    )
    for ax, axis in zip(axes.flat, AXES, strict=True):
        _draw_heatmap(fig, ax, summary, tag, axis)
    fig.legend(handles=heatmap_legend_handles(), loc="outside lower center", ncols=3)
    return fig


def _on_view_grid(da: xr.DataArray, theta_deg: xr.DataArray) -> xr.DataArray:
    """Sort a ``(p, theta)`` array by p and by `theta_deg`, the angle unwrapped around the view."""
    return da.assign_coords(theta_deg=theta_deg).sortby(["p", "theta_deg"]).transpose("p", "theta")


def _with_note(title: str, note: str) -> str:
    """``title``, and ``note`` on a second line where there is one."""
    return f"{title}\n{note}" if note else title


def _draw_heatmap(fig: Figure, ax: Axes, summary: VariantSummary, tag: int, axis: str) -> None:
    """Draw one panel of :func:`plot_error_heatmap`: the visible angles plus one on each side."""
    theta_deg = xr.DataArray(
        _theta_deg_around_view(summary, tag), coords={"theta": summary.visible["theta"]}
    )
    shown = _on_view_grid(summary.visible.sel(tag=tag), theta_deg)
    keep = shown_columns(shown.values)
    shown = shown.isel(theta=keep)

    def on_grid(da: xr.DataArray) -> xr.DataArray:
        return _on_view_grid(da, theta_deg).isel(theta=keep)

    signed = on_grid(summary.signed_error.sel(tag=tag, axis=axis))
    unit, scale = display_unit(axis)
    values = scale * signed.values
    beyond = signed_mesh(fig, ax, values, robust_colour_limit(values), f"{axis} error [{unit}]")
    undetected = on_grid((summary.visible & ~summary.detected_any).sel(tag=tag))
    rows, cols = np.nonzero(undetected.values)
    ax.plot(cols, rows, "kx", ms=6, ls="none")
    sampled_axis(signed["theta_deg"].values, "{:.0f}").apply(ax, "x")
    row_distance_labels(on_grid(summary.distance_m.sel(tag=tag)), shown).apply(ax, "y")
    ax.set_title(_with_note(f"{axis}: signed error (estimated − expected) [{unit}]", beyond))
    ax.set_xlabel("turntable angle θ [deg]")
    ax.set_ylabel(ROW_DISTANCE_LABEL)


# --- comparison: variants against the reference --------------------------------------------


def plot_change_by_distance(
    data: xr.Dataset, baseline: str | None = None, title: str | None = None
) -> Figure:
    """Plot the change of mean ``|error|`` against camera-to-tag distance, one line per variant.

    Parameters
    ----------
    data, baseline
        What to compare, as in :func:`~simgap.analysis.report._comparisons.as_comparison`.
    title : str, optional
        Figure title; default names the variant - reference change of mean ``|error|``.

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels (tx, ty, tz / rx, ry, rz): variant - reference mean ``|error|`` (mm or mrad)
        over paired (tag, theta) of each pin hole, against the mean camera-to-tag distance (m)
        of those items (:func:`~simgap.analysis.report.change_by_p`), with
        a zero line.
    """
    cmp = as_comparison(data, baseline)
    change = change_by_p(cmp)
    fig, axes = new_figure_grid(
        title
        or f"Change of mean |error| vs camera-to-tag distance (variant − "
        f"{cmp.attrs['baseline']!r}, paired items, both tags, all view angles)"
    )
    for ax, axis in zip(axes.flat, AXES, strict=True):
        for variant in change["variant"].values:
            one = change.sel(variant=variant, axis=axis)
            ax.plot(one["distance_m"], one, marker="o", ms=3, label=variant)
        ax.axhline(0.0, color="k", lw=0.8)
        unit = display_unit(axis)[0]
        ax.set_title(f"{axis}: change of mean |error| [{unit}]")
        ax.set_ylabel(f"Δ mean |{axis} error| [{unit}]")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel(f"{DISTANCE_LABEL}, pin-hole mean")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=max(1, len(labels)))
    return fig


def _draw_change_heatmap(
    fig: Figure | SubFigure, ax: Axes, cmp: xr.Dataset, variant: str, tag: int, axis: str
) -> None:
    """Draw the signed shift of one variant, tag and axis over (view angle, pin hole)."""
    unit, scale = display_unit(axis)

    def on_grid(da: xr.DataArray) -> xr.DataArray:
        da = da.assign_coords(angle=cmp["view_angle_deg"].sel(tag=tag))
        return da.sortby(["p", "angle"]).transpose("p", "theta")

    signed = on_grid(cmp["signed_shift"].sel(variant=variant, tag=tag, axis=axis) * scale)
    paired = on_grid(cmp["paired"].sel(variant=variant, tag=tag))
    keep = shown_columns(paired.values)  # the paired angles plus one grey cell on each side
    signed, paired = signed.isel(theta=keep), paired.isel(theta=keep)
    shared = cmp["signed_shift"].sel(variant=variant, axis=axis).values * scale
    limit = robust_colour_limit(shared, floor=_MIN_COLOUR_LIMIT)
    beyond = signed_mesh(fig, ax, signed.values, limit, f"Δ {axis} [{unit}]")
    sampled_axis(signed["angle"].values, "{:.0f}").apply(ax, "x")
    distance = on_grid(cmp["distance_m"].sel(tag=tag)).sel(theta=signed["theta"])
    row_distance_labels(distance, paired).apply(ax, "y")
    ax.set_title(_with_note(f"tag {tag}, {axis}: signed change [{unit}]", beyond))
    ax.set_xlabel("turntable angle from facing [deg] (0: the tag faces the camera)")
    ax.set_ylabel(ROW_DISTANCE_LABEL)


def plot_change_heatmap(data: xr.Dataset, variant: str, baseline: str | None = None) -> Figure:
    """Plot the mean signed error change of one variant over (view angle, p), all axes and tags.

    Parameters
    ----------
    data : xarray.Dataset
        What to compare, with `baseline`, as in
        :func:`~simgap.analysis.report._comparisons.as_comparison`.
    variant : str
        A compared (non-reference) variant.
    baseline : str, optional
        Reference variant.

    Returns
    -------
    matplotlib.figure.Figure
        One block of 2x3 panels (tx, ty, tz / rx, ry, rz) per tag: repeat-mean signed error,
        variant - reference, in mm or mrad, one cell per sampled view angle (deg, 0 = facing
        the camera) and pin hole (rows ticked with their median camera-to-tag distance, m);
        diverging colours centred on 0 with a robust limit shared by the tags of an axis
        (:func:`robust_colour_limit`; cells beyond it hatched, counted in the panel's title);
        grey where the item is not paired.
    """
    return plot_comparison_heatmap(as_comparison(data, baseline), variant)


def plot_comparison_heatmap(cmp: xr.Dataset, variant: str) -> Figure:
    """:func:`plot_change_heatmap` of a comparison: what it reads of it, and nothing else.

    Parameters
    ----------
    cmp : xarray.Dataset
        :func:`~simgap.analysis.report.compare_variants`' layout, with at least
        ``signed_shift`` (variant, tag, p, theta, axis; m or rad), ``paired`` (variant, tag, p,
        theta), the coordinates ``view_angle_deg`` (tag, theta; deg) and ``distance_m`` (tag, p,
        theta; m), and the attrs ``baseline`` and ``n_repeat``.
    variant : str
        A compared (non-reference) variant.
    """
    _check_compared(cmp, variant)
    tags = [int(t) for t in cmp["tag"].values]
    fig = Figure(figsize=(15, 7.5 * len(tags)), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(
        f"Signed error change, {variant!r} − {cmp.attrs['baseline']!r} (mean of "
        f"{cmp.attrs['n_repeat']} repeat(s))"
    )
    for sub, tag in zip(fig.subfigures(len(tags), 1, squeeze=False)[:, 0], tags, strict=True):
        sub.suptitle(f"Tag {tag}")
        for ax, axis in zip(sub.subplots(2, 3).flat, AXES, strict=True):
            _draw_change_heatmap(sub, ax, cmp, variant, tag, axis)
    legend = heatmap_legend_handles("not paired", undetected=False)
    fig.legend(handles=legend, loc="outside lower center", ncols=2)
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
    legend = heatmap_legend_handles("not paired", undetected=False)
    fig.legend(handles=legend, loc="outside lower center", ncols=1)
    return fig


def _check_compared(cmp: xr.Dataset, variant: str) -> None:
    compared = [str(v) for v in cmp["variant"].values]
    if variant not in compared:
        raise ValueError(
            f"variant {variant!r} is not compared (the reference is {cmp.attrs['baseline']!r}); "
            f"compared variants: {compared}"
        )
