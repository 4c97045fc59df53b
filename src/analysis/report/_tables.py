"""Tables of the report and the comparison: cell formats, Markdown tables, per-variant frames.

The comparison tables are :class:`pandas.DataFrame` in display units (mm for translation, mrad
for rotation, :func:`simgap.core.axes.display_unit`); :func:`markdown_table` renders rows of
formatted cells.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final, Literal

import numpy as np
import pandas as pd
import xarray as xr

from simgap.analysis.gap import distance_thirds
from simgap.analysis.report._comparisons import as_comparison, to_display
from simgap.core.axes import AXES, display_unit

ANGLE_BINS_DEG: Final[tuple[tuple[str, float, float], ...]] = (
    ("0-20 deg", 0.0, 20.0),
    ("20-40 deg", 20.0, 40.0),
    ("40+ deg", 40.0, np.inf),
)
"""Bins of the absolute view angle (deg): label, lower bound (inclusive), upper (exclusive)."""


# --- cells -----------------------------------------------------------------------------------


def fmt(value: float, digits: int = 6) -> str:
    """``value`` with ``digits`` decimals, ``"n/a"`` when not finite."""
    return "n/a" if not np.isfinite(value) else f"{value:.{digits}f}"


def fraction(count: int, total: int) -> str:
    """``"count/total (percent %)"``; the percentage is ``"n/a"`` when ``total`` is 0."""
    percent = f"{100.0 * count / total:.1f} %" if total else "n/a"
    return f"{count}/{total} ({percent})"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Lines of a Markdown table with ``header`` and ``rows`` of formatted cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(row) + " |" for row in rows]


def signed(value: float, digits: int = 3) -> str:
    """``value`` with a sign and ``digits`` decimals (never ``-0.000``), ``"n/a"`` if not finite."""
    if not np.isfinite(value):
        return "n/a"
    return f"{value if round(value, digits) else 0.0:+.{digits}f}"  # no "-0.000"


def percent(value: float) -> str:
    """A ratio as a signed percentage with one decimal, ``"n/a"`` when not finite."""
    return "n/a" if not np.isfinite(value) else f"{100.0 * value:+.1f} %"



# --- comparison tables -----------------------------------------------------------------------


def detection_rate(n_detected: xr.DataArray, n_attempts: xr.DataArray) -> xr.DataArray:
    """Pooled detected / attempted over tags, dim ``variant``; NaN where nothing was visible."""
    attempts = n_attempts.sum("tag")
    return n_detected.sum("tag") / attempts.where(attempts > 0)


def variant_summary_table(data: xr.Dataset, baseline: str | None = None) -> pd.DataFrame:
    """Tabulate what each variant changes, per axis, in mm (translation) and mrad (rotation).

    Parameters
    ----------
    data, baseline
        What to compare, as in :func:`~simgap.analysis.report._comparisons.as_comparison`.

    Returns
    -------
    pandas.DataFrame
        Index ``(variant, axis)``. Columns: ``unit`` (``"mm"`` or ``"mrad"``), ``n_paired``
        (items), ``reference_mean_abs``, ``reference_max_abs``, ``variant_mean_abs``,
        ``variant_max_abs`` (mean and max over paired items of the repeat-mean
        ``|error|``), ``change_mean_abs`` (variant - reference), ``relative_change``
        (``change_mean_abs / reference_mean_abs``, dimensionless), ``mean_signed_shift`` (mean of
        variant - reference signed error), ``reference_noise`` and ``variant_noise`` (mean std
        over repeats), ``reference_detection_rate`` and ``variant_detection_rate`` (detected /
        visible item x repeat, all tags, dimensionless, repeated on each axis row).
    """
    cmp = as_comparison(data, baseline)
    dims = ("tag", "p", "theta")
    with np.errstate(invalid="ignore", divide="ignore"):
        stats = xr.Dataset(
            {
                "n_paired": cmp["abs_change"].count(dims),
                "reference_mean_abs": to_display(cmp["reference_abs_error"].mean(dims)),
                "reference_max_abs": to_display(cmp["reference_abs_error"].max(dims)),
                "variant_mean_abs": to_display(cmp["abs_error"].mean(dims)),
                "variant_max_abs": to_display(cmp["abs_error"].max(dims)),
                "change_mean_abs": to_display(cmp["abs_change"].mean(dims)),
                "mean_signed_shift": to_display(cmp["signed_shift"].mean(dims)),
                "reference_noise": to_display(cmp["reference_noise"].mean(dims)),
                "variant_noise": to_display(cmp["noise"].mean(dims)),
            }
        )
        ref_mean = stats["reference_mean_abs"]
        stats["relative_change"] = stats["change_mean_abs"] / ref_mean.where(ref_mean > 0)
    stats["reference_detection_rate"] = detection_rate(
        cmp["reference_n_detected"], cmp["reference_n_attempts"]
    )
    stats["variant_detection_rate"] = detection_rate(cmp["n_detected"], cmp["n_attempts"])
    stats = stats.drop_vars([c for c in stats.coords if c not in ("variant", "axis")])
    table = stats.to_dataframe(dim_order=["variant", "axis"])
    units = [display_unit(a)[0] for a in table.index.get_level_values("axis")]
    table.insert(0, "unit", units)
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
        thirds = distance_thirds(np.asarray(cmp.attrs["pin_holes"]))
        return [(label, (p >= pins.min()) & (p <= pins.max())) for label, pins in thirds.items()]
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
        What to compare, with `baseline`, as in
        :func:`~simgap.analysis.report._comparisons.as_comparison`.
    by : {"distance", "angle"}
        ``"distance"``: near, mid and far thirds of the rig's pin holes
        (:func:`simgap.analysis.gap.distance_thirds`); ``"angle"``: bins of the absolute view
        angle from facing the camera (:data:`ANGLE_BINS_DEG`).
    baseline : str, optional
        Reference variant.
    variable : str, optional
        Per-item change to average: ``"abs_change"`` (change of ``|error|``, default) or
        ``"signed_shift"``.

    Returns
    -------
    pandas.DataFrame
        Index ``(variant, bin)``; column ``n`` (paired items in the bin) and one column
        per axis: the mean change in mm (``t*``) or mrad (``r*``), NaN for an empty bin.
    """
    cmp = as_comparison(data, baseline)
    dims = ("tag", "p", "theta")
    frames = []
    for label, mask in _bin_masks(cmp, by):
        values = cmp[variable].where(mask)
        with np.errstate(invalid="ignore"):
            mean = to_display(values.mean(dims)).transpose("variant", "axis")
        frame = pd.DataFrame(mean.values, index=mean["variant"].values, columns=list(AXES))
        frame.insert(0, "n", cmp["paired"].where(mask, False).sum(dims).values.astype(int))
        frame["bin"] = label
        frames.append(frame)
    table = pd.concat(frames).rename_axis("variant").set_index("bin", append=True)
    variants = [str(v) for v in cmp["variant"].values]
    labels = [label for label, _ in _bin_masks(cmp, by)]
    return table.reindex(pd.MultiIndex.from_product([variants, labels], names=["variant", "bin"]))
