"""Paper-style report of one result dataset: figures, Table 2 beside the paper's, and a summary.

The entry point is :func:`write_report`. It validates the dataset against the result-dataset
contract (DESIGN section 3), reduces the first variant to a :class:`VariantSummary` (absolute and
signed errors averaged over repeats, restricted to visible configurations) and writes, atomically:

========================================  ======================================================
file                                      content
========================================  ======================================================
``error_vs_distance_tag{t}.png``          2x3 panels, absolute error (m or rad) against carriage
                                          position (m), one line per turntable angle, threshold
                                          line, visible-but-undetected configurations as ``x``
``heatmap_tag{t}.png``                    2x3 panels, signed error over (theta, p), diverging
                                          colours centred on 0, grey where there is no estimate
``table2.md``                             our max/min absolute error beside the paper's Table 2,
                                          fraction within threshold, detection rate per tag
``summary.md``                            counts, fractions within thresholds, observations
                                          computed from the data, embedded figures
========================================  ======================================================

Only the first variant is reported for now; :func:`summarize_variant` and
:func:`write_variant_report` take a one-variant slice so further variants can be added later.

Examples
--------
>>> import xarray as xr
>>> from pathlib import Path
>>> from simgap.analysis.report import write_report
>>> paths = write_report(xr.open_dataset("results/baseline.nc"), Path("rep"))  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Final

import numpy as np
import xarray as xr
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from simgap.core.atomic import atomic_write

from .image_evidence import plot_image_stats
from .paper import AXES, AXIS_UNITS, TABLE2, threshold_for

REQUIRED_VARIABLES: Final[dict[str, tuple[str, ...]]] = {
    "error": ("variant", "repeat", "tag", "p", "theta", "axis"),
    "visible": ("tag", "p", "theta"),
    "detected": ("variant", "repeat", "tag", "p", "theta"),
}
"""Variables the report reads, with the dims each must have (``visible`` may add ``variant``)."""

REQUIRED_COORDS: Final[tuple[str, ...]] = ("tag", "p", "theta", "axis", "variant", "repeat")
"""Coordinates the report reads."""

DEFAULT_PIN_PITCH_M: Final[float] = 0.0254
"""Default carriage pin-hole pitch in metres (carriage position = pitch * p)."""

FIGURE_DPI: Final[int] = 110
"""Resolution of the written PNG figures, in dots per inch."""

_NO_DATA_GREY: Final[str] = "0.75"
_THETA_CMAP: Final[str] = "cividis"  # no red or green: those mark the maximum and minimum
_SIGNED_CMAP: Final[str] = "RdBu_r"


@dataclass(frozen=True)
class VariantSummary:
    """Repeat-averaged errors and detection counts of one variant.

    Parameters
    ----------
    variant : str
        Name of the variant.
    n_repeat : int
        Number of repeats averaged.
    pin_pitch_m : float
        Carriage pin-hole pitch in metres.
    carriage_m : xarray.DataArray
        Carriage position ``pin_pitch_m * p`` in metres, dim ``p``.
    abs_error : xarray.DataArray
        Mean over repeats of the absolute error (m for ``t*``, rad for ``r*``), dims
        ``(tag, p, theta, axis)``; NaN where the tag is not visible or was never detected.
    signed_error : xarray.DataArray
        Mean over repeats of the signed error, same dims, units and NaN pattern as `abs_error`.
    visible : xarray.DataArray
        Boolean, dims ``(tag, p, theta)``: the tag is expected to be detectable.
    detected_any : xarray.DataArray
        Boolean, dims ``(tag, p, theta)``: visible and detected in at least one repeat.
    n_visible : xarray.DataArray
        Number of visible configurations (p, theta) per tag, dim ``tag``.
    n_detected : xarray.DataArray
        Number of visible (configuration, repeat) pairs that were detected, dim ``tag``.
    n_failed : xarray.DataArray
        Number of visible (configuration, repeat) pairs that were not detected, dim ``tag``.
    n_unexpected : xarray.DataArray
        Number of (configuration, repeat) pairs detected although not visible (excluded from all
        statistics), dim ``tag``.
    """

    variant: str
    n_repeat: int
    pin_pitch_m: float
    carriage_m: xr.DataArray
    abs_error: xr.DataArray
    signed_error: xr.DataArray
    visible: xr.DataArray
    detected_any: xr.DataArray
    n_visible: xr.DataArray
    n_detected: xr.DataArray
    n_failed: xr.DataArray
    n_unexpected: xr.DataArray

    @property
    def tags(self) -> list[int]:
        """Tag ids, in dataset order."""
        return [int(t) for t in self.visible["tag"].values]

    @property
    def detection_rate(self) -> xr.DataArray:
        """Detected / visible (configuration, repeat) pairs per tag (dimensionless, NaN if none)."""
        attempts = self.n_visible * self.n_repeat
        return (self.n_detected / attempts.where(attempts > 0)).rename("detection_rate")


# --------------------------------------------------------------------------------------------
# validation and reduction
# --------------------------------------------------------------------------------------------


def check_report_dataset(ds: xr.Dataset) -> None:
    """Check that a result dataset has what the report reads.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset following the contract of DESIGN section 3.

    Raises
    ------
    ValueError
        Naming every missing variable and coordinate, a variable without its required dims, or
        missing values of the ``axis`` coordinate.
    """
    missing_vars = [name for name in REQUIRED_VARIABLES if name not in ds.data_vars]
    missing_coords = [name for name in REQUIRED_COORDS if name not in ds.coords]
    problems = []
    if missing_vars:
        problems.append(f"missing required variables: {', '.join(missing_vars)}")
    if missing_coords:
        problems.append(f"missing required coordinates: {', '.join(missing_coords)}")
    if problems:
        raise ValueError(f"result dataset cannot be reported: {'; '.join(problems)}")
    for name, dims in REQUIRED_VARIABLES.items():
        lacking = [d for d in dims if d not in ds[name].dims]
        if lacking:
            raise ValueError(
                f"variable {name!r} must have dims {dims}; it has {ds[name].dims}, "
                f"lacking {', '.join(lacking)}"
            )
    missing_axes = [a for a in AXES if a not in ds["axis"].values.tolist()]
    if missing_axes:
        raise ValueError(f"coordinate 'axis' lacks values: {', '.join(missing_axes)}")


def _as_bool(da: xr.DataArray) -> xr.DataArray:
    """Return `da` as booleans, NaN (from a netCDF fill value) read as False."""
    return da.fillna(0).astype(bool) if da.dtype.kind == "f" else da.astype(bool)


def summarize_variant(
    ds_variant: xr.Dataset, pin_pitch_m: float = DEFAULT_PIN_PITCH_M
) -> VariantSummary:
    """Reduce one variant of a result dataset to repeat-averaged errors and detection counts.

    Parameters
    ----------
    ds_variant : xarray.Dataset
        Result dataset sliced to one variant, e.g. ``ds.isel(variant=0)`` (a ``variant`` dim of
        length 1 is also accepted).
    pin_pitch_m : float, optional
        Carriage pin-hole pitch in metres; carriage position is ``pin_pitch_m * p``.

    Returns
    -------
    VariantSummary
        Errors averaged over repeats with NaN skipped, restricted to visible configurations; a
        configuration counts as detected where its tag was detected in at least one repeat.

    Raises
    ------
    ValueError
        If the slice still holds more than one variant.
    """
    if "variant" in ds_variant.dims:
        if ds_variant.sizes["variant"] != 1:
            raise ValueError(
                "summarize_variant needs a one-variant slice; got "
                f"{ds_variant.sizes['variant']} variants"
            )
        ds_variant = ds_variant.isel(variant=0)
    order = ("tag", "p", "theta")
    visible = _as_bool(ds_variant["visible"]).transpose(*order)
    detected = _as_bool(ds_variant["detected"]).transpose("repeat", *order)
    error = ds_variant["error"].transpose("repeat", *order, "axis")
    error = error.where(detected & visible)
    with np.errstate(invalid="ignore"):
        abs_error = abs(error).mean("repeat", skipna=True)
        signed_error = error.mean("repeat", skipna=True)
    return VariantSummary(
        variant=str(ds_variant["variant"].values),
        n_repeat=int(ds_variant.sizes["repeat"]),
        pin_pitch_m=float(pin_pitch_m),
        carriage_m=(pin_pitch_m * ds_variant["p"]).astype(float).rename("carriage_m"),
        abs_error=abs_error.rename("abs_error"),
        signed_error=signed_error.rename("signed_error"),
        visible=visible,
        detected_any=(detected & visible).any("repeat"),
        n_visible=visible.sum(("p", "theta")),
        n_detected=(detected & visible).sum(("repeat", "p", "theta")),
        n_failed=(~detected & visible).sum(("repeat", "p", "theta")),
        n_unexpected=(detected & ~visible).sum(("repeat", "p", "theta")),
    )


def abs_error_envelope(summary: VariantSummary) -> xr.Dataset:
    """Return the max and min repeat-averaged absolute error over configurations.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`summarize_variant`.

    Returns
    -------
    xarray.Dataset
        Variables ``max`` and ``min``, dims ``(tag, axis)``, in m (``t*``) or rad (``r*``); NaN
        where a tag has no estimate.
    """
    dims = ("p", "theta")
    return xr.Dataset(
        {
            "max": summary.abs_error.max(dims, skipna=True),
            "min": summary.abs_error.min(dims, skipna=True),
        }
    )


def _thresholds() -> xr.DataArray:
    return xr.DataArray([threshold_for(a) for a in AXES], dims="axis", coords={"axis": list(AXES)})


def within_threshold_counts(summary: VariantSummary) -> xr.DataArray:
    """Count visible configurations whose absolute error is within the high-precision threshold.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`summarize_variant`.

    Returns
    -------
    xarray.DataArray
        Integer counts, dims ``(tag, axis)``. A visible configuration without an estimate counts
        as not within; divide by ``summary.n_visible`` for the fraction.
    """
    abs_error = summary.abs_error.sel(axis=list(AXES))
    return (abs_error <= _thresholds()).sum(("p", "theta")).transpose("tag", "axis")


def fit_abs_error_slope(summary: VariantSummary, axis: str = "ty") -> xr.Dataset:
    """Fit a least-squares line to the absolute error of one axis against carriage position.

    All visible, detected configurations of a tag (every turntable angle) enter one fit of
    ``|error| = intercept + slope * carriage_m``.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`summarize_variant`.
    axis : str, optional
        Axis to fit, default ``"ty"``.

    Returns
    -------
    xarray.Dataset
        Dim ``tag``: ``slope`` (error unit per metre of carriage travel, i.e. m/m or rad/m),
        ``intercept`` (m or rad, at carriage position 0) and ``n_points``; NaN slope and
        intercept where fewer than two distinct carriage positions have data.
    """
    slopes, intercepts, counts = [], [], []
    for tag in summary.tags:
        y = summary.abs_error.sel(tag=tag, axis=axis).transpose("p", "theta").values
        x = np.broadcast_to(summary.carriage_m.values[:, None], y.shape)
        ok = np.isfinite(y)
        slope, intercept = _line_fit(x[ok], y[ok])
        slopes.append(slope)
        intercepts.append(intercept)
        counts.append(int(ok.sum()))
    coords = {"tag": summary.tags}
    unit = AXIS_UNITS[axis]
    return xr.Dataset(
        {
            "slope": ("tag", slopes, {"units": f"{unit}/m"}),
            "intercept": ("tag", intercepts, {"units": unit}),
            "n_points": ("tag", counts),
        },
        coords=coords,
        attrs={"axis": axis},
    )


def _line_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares ``y = intercept + slope * x``; NaNs if x has fewer than two distinct values."""
    if np.unique(x).size < 2:
        return float("nan"), float("nan")
    design = np.column_stack([x, np.ones_like(x)])
    (slope, intercept), *_ = np.linalg.lstsq(design, y, rcond=None)
    return float(slope), float(intercept)


# --------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------


def _new_figure_grid(title: str) -> tuple[Figure, np.ndarray]:
    """Return a headless (Agg) figure with a 2x3 grid of axes, one per pose axis."""
    fig = Figure(figsize=(14, 8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    fig.suptitle(title)
    return fig, axes


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
        Output of :func:`summarize_variant`.
    tag : int
        Tag id.

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
    fig, axes = _new_figure_grid(
        f"Tag {tag}: absolute pose error vs carriage position (variant {summary.variant!r}, "
        f"mean of {summary.n_repeat} repeat(s))"
    )
    theta_deg = _theta_deg_around_view(summary, tag)
    seen = summary.visible.sel(tag=tag).any("p").values
    shown = theta_deg[seen] if seen.any() else theta_deg
    cmap = ListedColormap(colormaps[_THETA_CMAP](np.linspace(0.0, 0.85, 256)))  # no pale yellow
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
        Output of :func:`summarize_variant`.
    tag : int
        Tag id.

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels, repeat-averaged signed error (m or rad) with theta (deg, unwrapped around the
        tag's mean viewing angle, so it may be negative) across and p up,
        a diverging colour map centred on 0 with symmetric limits per panel, grey where there is
        no estimate (not visible or not detected) and ``x`` on visible but undetected cells.
    """
    fig, axes = _new_figure_grid(
        f"Tag {tag}: signed pose error (variant {summary.variant!r}, mean of "
        f"{summary.n_repeat} repeat(s)); grey: no estimate, x: visible but not detected"
    )
    for ax, axis in zip(axes.flat, AXES, strict=True):
        _draw_heatmap(fig, ax, summary, tag, axis)
    return fig


def _cell_edges(centres: np.ndarray) -> np.ndarray:
    """Return cell edges around sorted cell centres (unit width for a single centre)."""
    if centres.size == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    mid = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[2 * centres[0] - mid[0]], mid, [2 * centres[-1] - mid[-1]]])


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
    cmap = colormaps[_SIGNED_CMAP].with_extremes(bad=_NO_DATA_GREY)
    mesh = ax.pcolormesh(
        _cell_edges(theta),
        _cell_edges(p),
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


# --------------------------------------------------------------------------------------------
# Markdown
# --------------------------------------------------------------------------------------------


def _fmt(value: float, digits: int = 6) -> str:
    return "n/a" if not np.isfinite(value) else f"{value:.{digits}f}"


def _fraction(count: int, total: int) -> str:
    percent = f"{100.0 * count / total:.1f} %" if total else "n/a"
    return f"{count}/{total} ({percent})"


def _markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(row) + " |" for row in rows]


def table2_markdown(summary: VariantSummary) -> str:
    """Render our Table 2 beside the paper's, plus detection rates, as Markdown.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`summarize_variant`.

    Returns
    -------
    str
        A table with one row per axis and tag: our max and min absolute error (6 decimals, m or
        rad), the paper's simulation and hardware max and min, and our count and fraction of
        visible configurations within the threshold; then a detection-rate table per tag.
    """
    envelope = abs_error_envelope(summary)
    within = within_threshold_counts(summary)
    header = [
        "Axis",
        "Unit",
        "Tag",
        "Ours max",
        "Ours min",
        "Paper sim max",
        "Paper hw max",
        "Paper sim min",
        "Paper hw min",
        "Ours within threshold",
    ]
    rows = []
    for axis in AXES:
        for tag in summary.tags:
            paper = TABLE2.get((axis, tag))
            paper_cells = (
                [
                    _fmt(v, 4)
                    for v in (
                        paper.simulation_max,
                        paper.hardware_max,
                        paper.simulation_min,
                        paper.hardware_min,
                    )
                ]
                if paper
                else ["n/a"] * 4
            )
            rows.append(
                [
                    axis,
                    AXIS_UNITS[axis],
                    str(tag),
                    _fmt(float(envelope["max"].sel(tag=tag, axis=axis))),
                    _fmt(float(envelope["min"].sel(tag=tag, axis=axis))),
                    *paper_cells,
                    _fraction(
                        int(within.sel(tag=tag, axis=axis)), int(summary.n_visible.sel(tag=tag))
                    ),
                ]
            )
    lines = [
        "# Table 2: absolute pose error, ours beside the paper's",
        "",
        f"Variant `{summary.variant}`, absolute error averaged over {summary.n_repeat} repeat(s), "
        "over visible configurations only. Thresholds: "
        f"{threshold_for('tx'):g} m (translation), {threshold_for('rx'):g} rad (rotation); "
        "a visible configuration without an estimate counts as not within.",
        "",
        *_markdown_table(header, rows),
        "",
        "## Detection rate",
        "",
        *_markdown_table(
            ["Tag", "Detected / visible (configuration x repeat)"],
            [[str(tag), _detection_cell(summary, tag)] for tag in summary.tags],
        ),
        "",
    ]
    return "\n".join(lines)


def _detection_cell(summary: VariantSummary, tag: int) -> str:
    attempts = int(summary.n_visible.sel(tag=tag)) * summary.n_repeat
    return _fraction(int(summary.n_detected.sel(tag=tag)), attempts)


def summary_markdown(
    summary: VariantSummary, figures: Sequence[Path], variants: Sequence[str]
) -> str:
    """Render the short report text as Markdown.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`summarize_variant`.
    figures : sequence of pathlib.Path
        Figure files to embed, linked by file name (they sit beside the Markdown file).
    variants : sequence of str
        All variants of the dataset, to say which were left out.

    Returns
    -------
    str
        Counts (visible, detected, failures), fraction within thresholds per axis and tag, and
        observations computed from the data (slope of the ``|ty|`` error against distance).
    """
    lines = [f"# simgap report: variant `{summary.variant}`", ""]
    lines += _scope_lines(summary, variants)
    lines += ["", "## Counts", ""]
    lines += _markdown_table(
        [
            "Tag",
            "Visible configurations",
            "Detected (configuration x repeat)",
            "Detection failures (configuration x repeat)",
            "Detection rate",
            "Detected while not visible",
        ],
        [_count_row(summary, tag) for tag in summary.tags],
    )
    lines += ["", "## Fraction of visible configurations within the high-precision threshold", ""]
    within = within_threshold_counts(summary)
    lines += _markdown_table(
        ["Tag", *AXES],
        [
            [
                str(tag),
                *(
                    _fraction(int(within.sel(tag=tag, axis=a)), int(summary.n_visible.sel(tag=tag)))
                    for a in AXES
                ),
            ]
            for tag in summary.tags
        ],
    )
    lines += ["", "## Observations", "", *_observation_lines(summary), ""]
    lines += ["## Figures", "", "Table 2 beside the paper's: [table2.md](table2.md).", ""]
    lines += [f"![{path.stem}]({path.name})\n" for path in figures]
    return "\n".join(lines)


def _scope_lines(summary: VariantSummary, variants: Sequence[str]) -> list[str]:
    lines = [
        f"Errors are averaged over {summary.n_repeat} repeat(s) (NaN skipped); statistics use "
        "visible configurations only. Translation in m, rotation in rad; carriage position is "
        "pin pitch x p.",
    ]
    others = [v for v in variants if v != summary.variant]
    if others:
        lines += [
            "",
            f"Only the first variant is reported; not reported: "
            f"{', '.join(f'`{v}`' for v in others)}.",
        ]
    return lines


def _count_row(summary: VariantSummary, tag: int) -> list[str]:
    return [
        str(tag),
        str(int(summary.n_visible.sel(tag=tag))),
        str(int(summary.n_detected.sel(tag=tag))),
        str(int(summary.n_failed.sel(tag=tag))),
        _detection_cell(summary, tag),
        str(int(summary.n_unexpected.sel(tag=tag))),
    ]


def _observation_lines(summary: VariantSummary) -> list[str]:
    """Return bullet points computed from the data: ty slope and worst axis per tag."""
    fit = fit_abs_error_slope(summary, "ty")
    envelope = abs_error_envelope(summary)
    lines = []
    for tag in summary.tags:
        slope = float(fit["slope"].sel(tag=tag))
        intercept = float(fit["intercept"].sel(tag=tag))
        n_points = int(fit["n_points"].sel(tag=tag))
        if np.isfinite(slope):
            # slope in m/m -> mm per 0.1 m of carriage travel: * 1e3 mm/m * 0.1 m
            lines.append(
                f"- Tag {tag}: |ty| error changes by {_fmt(slope * 100.0, 3)} mm per 0.1 m of "
                f"carriage travel (least-squares line over {n_points} configurations, all "
                f"angles; {_fmt(intercept * 1e3, 3)} mm at p = 0)."
            )
        else:
            lines.append(f"- Tag {tag}: too few estimates ({n_points}) to fit |ty| vs distance.")
        ratio = envelope["max"].sel(tag=tag) / _thresholds()
        if np.isfinite(ratio).any():
            worst = str(ratio.idxmax("axis").values)
            exceeding = ", ".join(a for a in AXES if ratio.sel(axis=a) > 1) or "none"
            lines.append(
                f"- Tag {tag}: largest error relative to its threshold on {worst} "
                f"({_fmt(float(ratio.sel(axis=worst)), 2)} x threshold); axes exceeding the "
                f"threshold somewhere: {exceeding}."
            )
    return lines


# --------------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------------


def _atomic_write(path: Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Write a file through :func:`~simgap.core.atomic.atomic_write` (binary handle)."""

    def to_file(tmp: Path) -> None:
        with open(tmp, "xb") as handle:
            write(handle)

    return atomic_write(path, to_file)


def _save_figure(fig: Figure, path: Path) -> Path:
    return _atomic_write(path, lambda handle: fig.savefig(handle, format="png", dpi=FIGURE_DPI))


def _save_text(text: str, path: Path) -> Path:
    return _atomic_write(path, lambda handle: handle.write(text.encode("utf-8")))


def write_variant_report(
    summary: VariantSummary,
    out_dir: Path,
    variants: Sequence[str] = (),
    image_datasets: dict[str, xr.Dataset] | None = None,
) -> list[Path]:
    """Write the figures, ``table2.md`` and ``summary.md`` of one variant.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`summarize_variant`.
    out_dir : pathlib.Path
        Existing output folder.
    variants : sequence of str, optional
        All variants of the dataset, named in the summary when some are not reported.
    image_datasets : dict of str to xarray.Dataset, optional
        Datasets with ``image_stats`` to plot against distance and view angle.

    Returns
    -------
    list of pathlib.Path
        Written files: per tag ``error_vs_distance_tag{t}.png``, then per tag
        ``heatmap_tag{t}.png``, then ``image_stats_vs_{distance,view_angle}.png`` when the
        dataset has image statistics, then ``table2.md`` and ``summary.md``.
    """
    plotters = (("error_vs_distance", plot_error_vs_distance), ("heatmap", plot_error_heatmap))
    figures = []
    for stem, plot in plotters:
        for tag in summary.tags:
            figures.append(_save_figure(plot(summary, tag), out_dir / f"{stem}_tag{tag}.png"))
    if image_datasets:
        for against in ("distance", "view_angle"):
            fig = plot_image_stats(image_datasets, against)
            figures.append(_save_figure(fig, out_dir / f"image_stats_vs_{against}.png"))
    table = _save_text(table2_markdown(summary), out_dir / "table2.md")
    text = _save_text(summary_markdown(summary, figures, variants), out_dir / "summary.md")
    return [*figures, table, text]


def write_report(
    ds: xr.Dataset, out_dir: Path, *, pin_pitch_m: float = DEFAULT_PIN_PITCH_M
) -> list[Path]:
    """Write the paper-style report of a result dataset.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset following DESIGN section 3. Only the first variant (``ds.variant[0]``) is
        reported; errors are averaged over ``repeat`` with NaN skipped.
    out_dir : pathlib.Path
        Output folder, created if needed; files in it are replaced atomically.
    pin_pitch_m : float, optional
        Carriage pin-hole pitch in metres (x axis of the error-vs-distance figures and the slope
        fit use carriage position ``pin_pitch_m * p``).

    Returns
    -------
    list of pathlib.Path
        The written files (see :func:`write_variant_report`).

    Raises
    ------
    ValueError
        If required variables or coordinates are missing (all are named), or dims are wrong.
    """
    check_report_dataset(ds)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    variants = [str(v) for v in ds["variant"].values]
    summary = summarize_variant(ds.isel(variant=0), pin_pitch_m=pin_pitch_m)
    images = {variants[0]: ds.isel(variant=[0])} if "image_stats" in ds else None
    return write_variant_report(summary, out_dir, variants, images)
