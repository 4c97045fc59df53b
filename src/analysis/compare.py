"""Compare the variants of a result dataset (rendering/estimation options) with a reference variant.

A *variant* is one rendering or estimation option (``baseline``, ``distortion``, ``glossy_tags``,
``defocus``, ``noise``, ...). The *reference* is the variant named ``baseline``, or the first
variant if none is, unless another is named. Every other variant is compared with it,
configuration by configuration:

1. each variant is reduced by :func:`simgap.analysis.report.summarize_variant` (errors averaged
   over repeats with NaN skipped, visible configurations only);
2. a configuration ``(tag, p, theta)`` is *paired* when both the variant and the reference have an
   estimate of every axis there; all error statistics use paired configurations only, so a change
   of detection does not masquerade as a change of error (detection rates are reported apart);
3. the spread over repeats (sample standard deviation, ``ddof=1``) is the noise level.

:func:`compare_variants` returns all of this as one :class:`xarray.Dataset` in SI units (m, rad);
the tables (:func:`variant_summary_table`, :func:`binned_change_table`) convert to mm and mrad. The
entry point :func:`write_comparison` writes, atomically:

==================================  ==============================================================
file                                content
==================================  ==============================================================
``comparison.md``                   per variant and axis: mean and max ``|error|`` of variant and
                                    reference, change of mean ``|error|``, mean signed shift,
                                    noise, detection rates, change by distance and view angle,
                                    and which axis each variant moves most
``change_by_distance.png``          2x3 panels: change of mean ``|error|`` against p, one line
                                    per variant
``change_heatmap_<variant>.png``    per variant, two rows of 2x3 panels per tag: mean signed
                                    error change over (view angle, p)
==================================  ==============================================================

Examples
--------
>>> from pathlib import Path
>>> from simgap.results.dataset import read_netcdf
>>> from simgap.analysis.compare import compare_variants, variant_summary_table, write_comparison
>>> ds = read_netcdf("results/variants.nc")  # doctest: +SKIP
>>> variant_summary_table(compare_variants(ds))  # doctest: +SKIP
>>> write_comparison(ds, Path("cmp"))  # doctest: +SKIP
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Final, Literal

import numpy as np
import pandas as pd
import xarray as xr
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure, SubFigure

from .paper import AXES, TRANSLATION_AXES
from .report import (
    _NO_DATA_GREY,
    _SIGNED_CMAP,
    _as_bool,
    _cell_edges,
    _fmt,
    _fraction,
    _markdown_table,
    _new_figure_grid,
    _save_figure,
    _save_text,
    check_report_dataset,
    summarize_variant,
)

REFERENCE_NAME: Final[str] = "baseline"
"""Variant used as the reference when none is named (else the first variant)."""

DISPLAY_SCALE: Final[float] = 1e3
"""Factor from SI (m, rad) to the display units of the tables and figures (mm, mrad)."""

DISPLAY_UNITS: Final = MappingProxyType(
    {a: "mm" if a in TRANSLATION_AXES else "mrad" for a in AXES}
)
"""Display unit of each axis: ``"mm"`` for translation, ``"mrad"`` for rotation."""

DISTANCE_BINS: Final[tuple[tuple[str, int, int], ...]] = (
    ("near (p 0-4)", 0, 4),
    ("mid (p 5-9)", 5, 9),
    ("far (p 10-14)", 10, 14),
)
"""Distance bins: label, first and last pin hole (inclusive)."""

ANGLE_BINS_DEG: Final[tuple[tuple[str, float, float], ...]] = (
    ("0-20 deg", 0.0, 20.0),
    ("20-40 deg", 20.0, 40.0),
    ("40+ deg", 40.0, np.inf),
)
"""Bins of the absolute view angle (deg): label, lower bound (inclusive), upper (exclusive)."""

TAG_FACING_THETA_RAD: Final = MappingProxyType({0: 0.0, 1: np.pi})
"""Turntable angle (rad) at which each tag faces the camera (DESIGN section 1: tag 0 on the outer
face at theta = 0, tag 1 on the inner face at theta = pi). Other tags: circular mean of the
turntable angles at which they are visible."""

_MIN_COLOUR_LIMIT: Final[float] = 1e-3  # mm or mrad: an unchanged axis shows white, not noise
_CHANGE_VARIABLES: Final[tuple[str, ...]] = (
    "reference_abs_error",
    "abs_error",
    "abs_change",
    "signed_shift",
    "reference_noise",
    "noise",
)


# --------------------------------------------------------------------------------------------
# variants and angles
# --------------------------------------------------------------------------------------------


def variant_names(ds: xr.Dataset) -> list[str]:
    """Return the variant names of a result dataset, in dataset order."""
    return [str(v) for v in np.atleast_1d(ds["variant"].values)]


def resolve_baseline(ds: xr.Dataset, baseline: str | None = None) -> str:
    """Return the reference variant of a comparison.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset with a ``variant`` coordinate.
    baseline : str, optional
        Reference variant; default: ``"baseline"`` if present, else the first variant.

    Returns
    -------
    str
        Name of the reference variant.

    Raises
    ------
    ValueError
        If the dataset has fewer than two variants, or `baseline` is not one of them (the message
        lists the variants).
    """
    names = variant_names(ds)
    if len(names) < 2:
        raise ValueError(f"needs at least two variants; dataset has: {names}")
    if baseline is None:
        return REFERENCE_NAME if REFERENCE_NAME in names else names[0]
    if baseline not in names:
        raise ValueError(
            f"baseline {baseline!r} is not a variant of the dataset; variants: {names}"
        )
    return baseline


def view_angle_deg(theta_rad: xr.DataArray, facing_theta_rad: Mapping[int, float]) -> xr.DataArray:
    """Return each tag's view angle: turntable angle relative to where the tag faces the camera.

    Parameters
    ----------
    theta_rad : xarray.DataArray
        Turntable angles (rad), dim ``theta``.
    facing_theta_rad : mapping of int to float
        Turntable angle (rad) at which each tag faces the camera, e.g.
        :data:`TAG_FACING_THETA_RAD`.

    Returns
    -------
    xarray.DataArray
        Dims ``(tag, theta)``: ``theta - facing`` wrapped to [-180, 180] deg (rounded to 1e-6 deg
        so that bin edges such as 20 deg are exact); 0 where the tag faces the camera.
    """
    tags = list(facing_theta_rad)
    facing = xr.DataArray([float(facing_theta_rad[t]) for t in tags], coords={"tag": tags})
    wrapped = np.angle(np.exp(1j * (theta_rad - facing).transpose("tag", "theta").values))
    return xr.DataArray(
        np.round(np.degrees(wrapped), 6),
        coords={"tag": tags, "theta": theta_rad["theta"].values},
        dims=("tag", "theta"),
        attrs={"units": "deg", "long_name": "turntable angle relative to facing the camera"},
    )


def _facing_theta(ds: xr.Dataset, facing: Mapping[int, float] | None) -> dict[int, float]:
    """Facing angle per tag of `ds`: from `facing`, else the circular mean of visible angles."""
    facing = TAG_FACING_THETA_RAD if facing is None else facing
    theta = ds["theta"].values.astype(float)
    out = {}
    for tag in (int(t) for t in ds["tag"].values):
        if tag in facing:
            out[tag] = float(facing[tag])
            continue
        seen = _as_bool(ds["visible"].sel(tag=tag))
        seen = seen.any([d for d in seen.dims if d != "theta"]).values
        out[tag] = float(np.angle(np.exp(1j * theta[seen]).sum())) if seen.any() else 0.0
    return out


# --------------------------------------------------------------------------------------------
# reduction
# --------------------------------------------------------------------------------------------


def _repeat_spread(ds_variant: xr.Dataset) -> xr.DataArray:
    """Sample std (ddof=1) over repeats of visible, detected errors; NaN with < 2 estimates."""
    usable = _as_bool(ds_variant["detected"]) & _as_bool(ds_variant["visible"])
    error = ds_variant["error"].where(usable)
    with np.errstate(invalid="ignore", divide="ignore"):
        spread = error.std("repeat", ddof=1, skipna=True)
    return spread.where(error.count("repeat") >= 2).transpose("tag", "p", "theta", "axis")


def _compare_one(ds: xr.Dataset, reference: str, variant: str) -> xr.Dataset:
    """Paired per-configuration comparison of one variant with the reference (SI units)."""
    ref = summarize_variant(ds.sel(variant=reference))
    var = summarize_variant(ds.sel(variant=variant))
    paired = (ref.abs_error.notnull() & var.abs_error.notnull()).all("axis")
    variables = {
        "reference_abs_error": ref.abs_error.where(paired),
        "abs_error": var.abs_error.where(paired),
        "abs_change": (var.abs_error - ref.abs_error).where(paired),
        "signed_shift": (var.signed_error - ref.signed_error).where(paired),
        "reference_noise": _repeat_spread(ds.sel(variant=reference)).where(paired),
        "noise": _repeat_spread(ds.sel(variant=variant)).where(paired),
        "paired": paired,
        "reference_n_detected": ref.n_detected,
        "reference_n_attempts": ref.n_visible * ref.n_repeat,
        "n_detected": var.n_detected,
        "n_attempts": var.n_visible * var.n_repeat,
    }
    # the slices carry their scalar ``variant`` coordinate, which differs between the two
    return xr.Dataset({k: v.drop_vars("variant", errors="ignore") for k, v in variables.items()})


def compare_variants(
    ds: xr.Dataset,
    baseline: str | None = None,
    *,
    facing_theta_rad: Mapping[int, float] | None = None,
) -> xr.Dataset:
    """Compare every variant of a result dataset with the reference, configuration by configuration.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset (DESIGN section 3) with at least two variants; ``visible`` may have dims
        ``(tag, p, theta)`` or ``(variant, tag, p, theta)``.
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).
    facing_theta_rad : mapping of int to float, optional
        Turntable angle (rad) at which each tag faces the camera; default
        :data:`TAG_FACING_THETA_RAD`.

    Returns
    -------
    xarray.Dataset
        Dim ``variant`` holds the compared variants (the reference excluded). Per
        ``(variant, tag, p, theta, axis)``, in m (``t*``) or rad (``r*``), NaN unless paired:
        ``reference_abs_error`` and ``abs_error`` (mean over repeats of ``|error|``),
        ``abs_change`` (their difference, variant - reference), ``signed_shift`` (repeat-mean
        signed error, variant - reference), ``reference_noise`` and ``noise`` (std over repeats).
        ``paired`` (variant, tag, p, theta): both have an estimate of every axis. Detection counts
        per ``(variant, tag)``: ``n_detected``, ``n_attempts`` (visible configurations x
        repeats), ``reference_n_detected``, ``reference_n_attempts``. Coordinate
        ``view_angle_deg`` (tag, theta), see :func:`view_angle_deg`. Attr ``baseline``.

    Raises
    ------
    ValueError
        If the dataset lacks what the report reads, has one variant, or `baseline` is unknown.
    """
    check_report_dataset(ds)
    reference = resolve_baseline(ds, baseline)
    others = [v for v in variant_names(ds) if v != reference]
    out = xr.concat(
        [_compare_one(ds, reference, v) for v in others],
        dim=xr.DataArray(np.asarray(others, dtype=str), dims="variant", name="variant"),
        coords="minimal",
        compat="override",
    )
    for name in _CHANGE_VARIABLES:
        out[name].attrs["units"] = "m (tx, ty, tz); rad (rx, ry, rz)"
    facing = _facing_theta(ds, facing_theta_rad)
    angles = view_angle_deg(ds["theta"].astype(float), facing)
    out = out.assign_coords(view_angle_deg=angles.sel(tag=out["tag"]))
    out.attrs.update(
        baseline=reference,
        n_repeat=int(ds.sizes["repeat"]),
        description="variants compared with attrs['baseline'] over paired configurations",
    )
    return out


def _as_comparison(data: xr.Dataset, baseline: str | None) -> xr.Dataset:
    """Return `data` if it is a :func:`compare_variants` output, else compare its variants."""
    return data if "abs_change" in data.data_vars else compare_variants(data, baseline)


# --------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------


def _detection_rate(n_detected: xr.DataArray, n_attempts: xr.DataArray) -> xr.DataArray:
    """Pooled detected / attempted over tags, dim ``variant``; NaN where nothing was visible."""
    attempts = n_attempts.sum("tag")
    return n_detected.sum("tag") / attempts.where(attempts > 0)


def variant_summary_table(data: xr.Dataset, baseline: str | None = None) -> pd.DataFrame:
    """Tabulate what each variant changes, per axis, in mm (translation) and mrad (rotation).

    Parameters
    ----------
    data : xarray.Dataset
        A result dataset, or the output of :func:`compare_variants` (then `baseline` is ignored).
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).

    Returns
    -------
    pandas.DataFrame
        Index ``(variant, axis)``. Columns: ``unit`` (``"mm"`` or ``"mrad"``), ``n_paired``
        (configurations), ``reference_mean_abs``, ``reference_max_abs``, ``variant_mean_abs``,
        ``variant_max_abs`` (mean and max over paired configurations of the repeat-mean
        ``|error|``), ``change_mean_abs`` (variant - reference), ``relative_change``
        (``change_mean_abs / reference_mean_abs``, dimensionless), ``mean_signed_shift`` (mean of
        variant - reference signed error), ``reference_noise`` and ``variant_noise`` (mean std
        over repeats), ``reference_detection_rate`` and ``variant_detection_rate`` (detected /
        visible configuration x repeat, all tags, dimensionless, repeated on each axis row).
    """
    cmp = _as_comparison(data, baseline)
    dims = ("tag", "p", "theta")
    with np.errstate(invalid="ignore", divide="ignore"):
        stats = xr.Dataset(
            {
                "n_paired": cmp["abs_change"].count(dims),
                "reference_mean_abs": cmp["reference_abs_error"].mean(dims) * DISPLAY_SCALE,
                "reference_max_abs": cmp["reference_abs_error"].max(dims) * DISPLAY_SCALE,
                "variant_mean_abs": cmp["abs_error"].mean(dims) * DISPLAY_SCALE,
                "variant_max_abs": cmp["abs_error"].max(dims) * DISPLAY_SCALE,
                "change_mean_abs": cmp["abs_change"].mean(dims) * DISPLAY_SCALE,
                "mean_signed_shift": cmp["signed_shift"].mean(dims) * DISPLAY_SCALE,
                "reference_noise": cmp["reference_noise"].mean(dims) * DISPLAY_SCALE,
                "variant_noise": cmp["noise"].mean(dims) * DISPLAY_SCALE,
            }
        )
        ref_mean = stats["reference_mean_abs"]
        stats["relative_change"] = stats["change_mean_abs"] / ref_mean.where(ref_mean > 0)
    stats["reference_detection_rate"] = _detection_rate(
        cmp["reference_n_detected"], cmp["reference_n_attempts"]
    )
    stats["variant_detection_rate"] = _detection_rate(cmp["n_detected"], cmp["n_attempts"])
    stats = stats.drop_vars([c for c in stats.coords if c not in ("variant", "axis")])
    table = stats.to_dataframe(dim_order=["variant", "axis"])
    table.insert(0, "unit", [DISPLAY_UNITS[a] for a in table.index.get_level_values("axis")])
    columns = [
        "unit",
        "n_paired",
        "reference_mean_abs",
        "reference_max_abs",
        "variant_mean_abs",
        "variant_max_abs",
        "change_mean_abs",
        "relative_change",
        "mean_signed_shift",
        "reference_noise",
        "variant_noise",
        "reference_detection_rate",
        "variant_detection_rate",
    ]
    return table[columns]


def moves_most(table: pd.DataFrame) -> dict[str, str | None]:
    """Name, per variant, the axis with the largest relative change of mean ``|error|``.

    Parameters
    ----------
    table : pandas.DataFrame
        Output of :func:`variant_summary_table`.

    Returns
    -------
    dict of str to str or None
        Variant -> axis with the largest ``|relative_change|``; None where no axis has a finite
        relative change (e.g. a reference without estimates).
    """
    out: dict[str, str | None] = {}
    for variant, rows in table.groupby(level="variant", sort=False):
        relative = rows["relative_change"].abs().droplevel("variant").dropna()
        out[str(variant)] = str(relative.idxmax()) if len(relative) else None
    return out


def _bin_masks(cmp: xr.Dataset, by: Literal["distance", "angle"]) -> list[tuple[str, xr.DataArray]]:
    """Label and boolean mask (over p, or over tag and theta) of each bin."""
    if by == "distance":
        p = cmp["p"]
        return [(label, (p >= lo) & (p <= hi)) for label, lo, hi in DISTANCE_BINS]
    if by == "angle":
        angle = abs(cmp["view_angle_deg"])
        return [(label, (angle >= lo) & (angle < hi)) for label, lo, hi in ANGLE_BINS_DEG]
    raise ValueError(f"by must be one of 'distance', 'angle'; got {by!r}")


def binned_change_table(
    data: xr.Dataset,
    by: Literal["distance", "angle"],
    baseline: str | None = None,
    variable: str = "abs_change",
) -> pd.DataFrame:
    """Tabulate the mean change per distance or view-angle bin, per variant and axis.

    Parameters
    ----------
    data : xarray.Dataset
        A result dataset, or the output of :func:`compare_variants` (then `baseline` is ignored).
    by : {"distance", "angle"}
        ``"distance"``: bins of pin hole p (:data:`DISTANCE_BINS`); ``"angle"``: bins of the
        absolute view angle from facing the camera (:data:`ANGLE_BINS_DEG`).
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).
    variable : str, optional
        Per-configuration change to average: ``"abs_change"`` (change of ``|error|``, default) or
        ``"signed_shift"``.

    Returns
    -------
    pandas.DataFrame
        Index ``(variant, bin)``; column ``n`` (paired configurations in the bin) and one column
        per axis: the mean change in mm (``t*``) or mrad (``r*``), NaN for an empty bin.
    """
    cmp = _as_comparison(data, baseline)
    dims = ("tag", "p", "theta")
    frames = []
    for label, mask in _bin_masks(cmp, by):
        values = cmp[variable].where(mask)
        with np.errstate(invalid="ignore"):
            mean = (values.mean(dims) * DISPLAY_SCALE).transpose("variant", "axis")
        frame = pd.DataFrame(mean.values, index=mean["variant"].values, columns=list(AXES))
        frame.insert(0, "n", cmp["paired"].where(mask, False).sum(dims).values.astype(int))
        frame["bin"] = label
        frames.append(frame)
    table = pd.concat(frames).rename_axis("variant").set_index("bin", append=True)
    variants = [str(v) for v in cmp["variant"].values]
    labels = [label for label, _ in _bin_masks(cmp, by)]
    return table.reindex(pd.MultiIndex.from_product([variants, labels], names=["variant", "bin"]))


def change_by_p(data: xr.Dataset, baseline: str | None = None) -> xr.DataArray:
    """Return the change of mean ``|error|`` per pin hole, in display units (mm, mrad).

    Parameters
    ----------
    data : xarray.Dataset
        A result dataset, or the output of :func:`compare_variants` (then `baseline` is ignored).
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).

    Returns
    -------
    xarray.DataArray
        Dims ``(variant, p, axis)``: mean over paired ``(tag, theta)`` of variant - reference
        ``|error|``, mm for ``t*`` and mrad for ``r*``; NaN where no configuration is paired.
    """
    cmp = _as_comparison(data, baseline)
    with np.errstate(invalid="ignore"):
        change = cmp["abs_change"].mean(("tag", "theta")) * DISPLAY_SCALE
    change = change.transpose("variant", "p", "axis")
    return change.rename("change_mean_abs").assign_attrs(units="mm (tx, ty, tz); mrad (rx, ry, rz)")


# --------------------------------------------------------------------------------------------
# Markdown
# --------------------------------------------------------------------------------------------


def _signed(value: float, digits: int = 3) -> str:
    if not np.isfinite(value):
        return "n/a"
    return f"{value if round(value, digits) else 0.0:+.{digits}f}"  # no "-0.000"


def _percent(value: float) -> str:
    return "n/a" if not np.isfinite(value) else f"{100.0 * value:+.1f} %"


def _moves_most_line(variant: str, axis: str | None, table: pd.DataFrame) -> str:
    if axis is None:
        return f"- `{variant}`: no axis has a finite relative change (no paired estimates)."
    row = table.loc[(variant, axis)]
    unit = row["unit"]
    return (
        f"- `{variant}` moves **{axis}** most: mean |error| {_signed(row['change_mean_abs'])} "
        f"{unit} ({_percent(row['relative_change'])} of the reference's "
        f"{_fmt(row['reference_mean_abs'], 3)} {unit}); mean signed shift "
        f"{_signed(row['mean_signed_shift'])} {unit}; noise (std over repeats) "
        f"{_fmt(row['variant_noise'], 3)} {unit} vs {_fmt(row['reference_noise'], 3)} {unit}."
    )


def _axis_rows(table: pd.DataFrame, variant: str, axes: Sequence[str]) -> list[list[str]]:
    rows = []
    for axis in axes:
        row = table.loc[(variant, axis)]
        rows.append(
            [
                axis,
                str(int(row["n_paired"])),
                _fmt(row["reference_mean_abs"], 3),
                _fmt(row["reference_max_abs"], 3),
                _fmt(row["variant_mean_abs"], 3),
                _fmt(row["variant_max_abs"], 3),
                _signed(row["change_mean_abs"]),
                _percent(row["relative_change"]),
                _signed(row["mean_signed_shift"]),
                _fmt(row["reference_noise"], 3),
                _fmt(row["variant_noise"], 3),
            ]
        )
    return rows


def _axis_header(unit: str) -> list[str]:
    return [
        "Axis",
        "Paired configurations",
        f"Reference mean abs [{unit}]",
        f"Reference max abs [{unit}]",
        f"Variant mean abs [{unit}]",
        f"Variant max abs [{unit}]",
        f"Change of mean abs [{unit}]",
        "Relative change",
        f"Mean signed shift [{unit}]",
        f"Reference noise [{unit}]",
        f"Variant noise [{unit}]",
    ]


def _detection_lines(cmp: xr.Dataset, variant: str) -> list[str]:
    v = cmp.sel(variant=variant)
    rows = []
    for tag in [*(int(t) for t in cmp["tag"].values), None]:
        sel = v if tag is None else v.sel(tag=tag)
        ref_det, ref_att, det, att = (
            int(sel[name].sum())
            for name in ("reference_n_detected", "reference_n_attempts", "n_detected", "n_attempts")
        )
        rows.append(
            [
                "all" if tag is None else str(tag),
                _fraction(ref_det, ref_att),
                _fraction(det, att),
            ]
        )
    header = ["Tag", "Reference detected / visible", "Variant detected / visible"]
    return _markdown_table(header, rows)


def _binned_lines(binned: pd.DataFrame, variant: str) -> list[str]:
    header = ["Bin", "Paired configurations"] + [f"{a} [{DISPLAY_UNITS[a]}]" for a in AXES]
    rows = [
        [str(label), str(int(row["n"])), *(_signed(row[a]) for a in AXES)]
        for label, row in binned.loc[variant].iterrows()
    ]
    return _markdown_table(header, rows)


def comparison_markdown(cmp: xr.Dataset, figures: Sequence[Path] = ()) -> str:
    """Render the comparison as Markdown.

    Parameters
    ----------
    cmp : xarray.Dataset
        Output of :func:`compare_variants`.
    figures : sequence of pathlib.Path, optional
        Figure files to embed, linked by file name (they sit beside the Markdown file).

    Returns
    -------
    str
        Scope, a "moves most" line per variant, then per variant: detection rates, the per-axis
        tables (translation in mm, rotation in mrad) and the change of mean ``|error|`` by
        distance and by view-angle bin.
    """
    reference = cmp.attrs["baseline"]
    table = variant_summary_table(cmp)
    by_distance = binned_change_table(cmp, "distance")
    by_angle = binned_change_table(cmp, "angle")
    variants = [str(v) for v in cmp["variant"].values]
    lines = [
        f"# Variant comparison against `{reference}`",
        "",
        f"Compared variants: {', '.join(f'`{v}`' for v in variants)}. Errors are first averaged "
        f"over {cmp.attrs['n_repeat']} repeat(s) (NaN skipped); every statistic uses the "
        "configurations (tag, p, theta) that are visible and have an estimate in both the variant "
        "and the reference (paired). abs = mean over repeats of |error|. Change = variant - "
        "reference. Mean signed shift = mean of (variant - reference) signed error; its sign "
        "carries the direction. Noise = standard deviation over repeats (ddof 1), averaged over "
        "configurations. Translation in mm, rotation in mrad. View angle = turntable angle "
        "relative to the tag facing the camera (tag 0 at 0 deg, tag 1 at 180 deg), wrapped to "
        "[-180, 180] deg.",
        "",
        "## What each variant moves most (largest relative change of mean |error|)",
        "",
        *(_moves_most_line(v, axis, table) for v, axis in moves_most(table).items()),
        "",
    ]
    for variant in variants:
        lines += [f"## `{variant}` vs `{reference}`", "", "### Detection", ""]
        lines += _detection_lines(cmp, variant)
        for title, axes, unit in (
            ("Translation", AXES[:3], "mm"),
            ("Rotation", AXES[3:], "mrad"),
        ):
            lines += ["", f"### {title} [{unit}]", ""]
            lines += _markdown_table(_axis_header(unit), _axis_rows(table, variant, axes))
        lines += ["", "### Change of mean |error| by distance (variant - reference)", ""]
        lines += _binned_lines(by_distance, variant)
        lines += ["", "### Change of mean |error| by |view angle| (variant - reference)", ""]
        lines += _binned_lines(by_angle, variant)
        lines += [""]
    if figures:
        lines += ["## Figures", ""]
        lines += [f"![{path.stem}]({path.name})\n" for path in figures]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------


def plot_change_by_distance(data: xr.Dataset, baseline: str | None = None) -> Figure:
    """Plot the change of mean ``|error|`` against pin hole, one line per variant.

    Parameters
    ----------
    data : xarray.Dataset
        A result dataset, or the output of :func:`compare_variants` (then `baseline` is ignored).
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels (tx, ty, tz / rx, ry, rz): variant - reference mean ``|error|`` (mm or mrad)
        over paired (tag, theta) against pin hole p, with a zero line.
    """
    cmp = _as_comparison(data, baseline)
    change = change_by_p(cmp)
    fig, axes = _new_figure_grid(
        f"Change of mean |error| vs distance (variant − {cmp.attrs['baseline']!r}, paired "
        "configurations, both tags, all view angles)"
    )
    p = change["p"].values
    for ax, axis in zip(axes.flat, AXES, strict=True):
        for variant in change["variant"].values:
            ax.plot(p, change.sel(variant=variant, axis=axis), marker="o", ms=3, label=variant)
        ax.axhline(0.0, color="k", lw=0.8)
        unit = DISPLAY_UNITS[axis]
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
    signed = cmp["signed_shift"].sel(variant=variant, tag=tag, axis=axis) * DISPLAY_SCALE
    signed = signed.assign_coords(angle=cmp["view_angle_deg"].sel(tag=tag))
    signed = signed.sortby(["p", "angle"]).transpose("p", "theta")
    shared = np.abs(cmp["signed_shift"].sel(variant=variant, axis=axis).values) * DISPLAY_SCALE
    limit = max(float(np.nanmax(shared, initial=0.0)), _MIN_COLOUR_LIMIT)
    angle_edges = _cell_edges(signed["angle"].values)
    mesh = ax.pcolormesh(
        angle_edges,
        _cell_edges(signed["p"].values.astype(float)),
        np.ma.masked_invalid(signed.values),
        cmap=colormaps[_SIGNED_CMAP].with_extremes(bad=_NO_DATA_GREY),
        norm=Normalize(-limit, limit),
    )
    columns = np.flatnonzero(np.isfinite(signed.values).any(axis=0))
    if columns.size:  # show the paired angles plus one grey cell on each side
        lo, hi = max(columns[0] - 1, 0), min(columns[-1] + 1, angle_edges.size - 2)
        ax.set_xlim(angle_edges[lo], angle_edges[hi + 1])
    unit = DISPLAY_UNITS[axis]
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
        A result dataset, or the output of :func:`compare_variants` (then `baseline` is ignored).
    variant : str
        A compared (non-reference) variant.
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).

    Returns
    -------
    matplotlib.figure.Figure
        One block of 2x3 panels (tx, ty, tz / rx, ry, rz) per tag: repeat-mean signed error,
        variant - reference, in mm or mrad, over view angle (deg, 0 = facing the camera) and pin
        hole; diverging colours centred on 0 with limits shared by the tags of an axis; grey
        where the configuration is not paired.
    """
    cmp = _as_comparison(data, baseline)
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

    Parameters
    ----------
    data : xarray.Dataset
        A result dataset, or the output of :func:`compare_variants` (then `baseline` is ignored).
    variant : str
        A compared (non-reference) variant.
    axis : str, optional
        Pose axis, default ``"ty"`` (depth).
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).

    Returns
    -------
    matplotlib.figure.Figure
        One panel per tag, as in :func:`plot_change_heatmap`.
    """
    cmp = _as_comparison(data, baseline)
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


# --------------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------------


def heatmap_filename(variant: str) -> str:
    """File name of a variant's heatmap: ``change_heatmap_<variant>.png``, unsafe chars as ``_``."""
    return f"change_heatmap_{re.sub(r'[^A-Za-z0-9_.-]', '_', variant)}.png"


def write_comparison(ds: xr.Dataset, out_dir: Path, baseline: str | None = None) -> list[Path]:
    """Write the comparison of a multi-variant result dataset with its reference variant.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset (DESIGN section 3) with at least two variants.
    out_dir : pathlib.Path
        Output folder, created if needed; files in it are replaced atomically.
    baseline : str, optional
        Reference variant; default ``"baseline"`` if present, else the first variant.

    Returns
    -------
    list of pathlib.Path
        ``change_by_distance.png``, ``change_heatmap_<variant>.png`` per compared variant, then
        ``comparison.md``.

    Raises
    ------
    ValueError
        If the dataset has fewer than two variants ("needs at least two variants; dataset has:
        [...]"), `baseline` is not a variant (the variants are listed), or required variables
        are missing.
    """
    cmp = compare_variants(ds, baseline)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figures = [_save_figure(plot_change_by_distance(cmp), out_dir / "change_by_distance.png")]
    for variant in (str(v) for v in cmp["variant"].values):
        figures.append(
            _save_figure(plot_change_heatmap(cmp, variant), out_dir / heatmap_filename(variant))
        )
    text = _save_text(comparison_markdown(cmp, figures), out_dir / "comparison.md")
    return [*figures, text]
