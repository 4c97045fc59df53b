"""Markdown documents: the report's ``table2.md`` and ``summary.md``, the ``comparison.md``.

Composed from :mod:`~simgap.analysis.report._summaries` and :mod:`~simgap.analysis.report._tables`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from simgap.analysis.paper import TABLE2, threshold_for
from simgap.analysis.report._summaries import (
    VariantSummary,
    abs_error_envelope,
    fit_abs_error_slope,
    thresholds,
    within_threshold_counts,
)
from simgap.analysis.report._tables import (
    binned_change_table,
    fmt,
    fraction,
    markdown_table,
    moves_most,
    percent,
    signed,
    variant_summary_table,
)
from simgap.core.axes import AXES, AXIS_UNITS, ROTATION_AXES, TRANSLATION_AXES, display_unit

# --- report: table2.md and summary.md ----------------------------------------------------------


def table2_markdown(summary: VariantSummary) -> str:
    """Render our Table 2 beside the paper's, plus detection rates, as Markdown.

    Parameters
    ----------
    summary : VariantSummary
        The reported variant (:func:`~simgap.analysis.report.summarize_variant`).

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
                    fmt(v, 4)
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
                    fmt(float(envelope["max"].sel(tag=tag, axis=axis))),
                    fmt(float(envelope["min"].sel(tag=tag, axis=axis))),
                    *paper_cells,
                    fraction(
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
        *markdown_table(header, rows),
        "",
        "## Detection rate",
        "",
        *markdown_table(
            ["Tag", "Detected / visible (configuration x repeat)"],
            [[str(tag), _detection_cell(summary, tag)] for tag in summary.tags],
        ),
        "",
    ]
    return "\n".join(lines)


def _detection_cell(summary: VariantSummary, tag: int) -> str:
    attempts = int(summary.n_visible.sel(tag=tag)) * summary.n_repeat
    return fraction(int(summary.n_detected.sel(tag=tag)), attempts)


def summary_markdown(
    summary: VariantSummary, figures: Sequence[Path], variants: Sequence[str]
) -> str:
    """Render the short report text as Markdown.

    Parameters
    ----------
    summary : VariantSummary
        The reported variant (:func:`~simgap.analysis.report.summarize_variant`).
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
    lines += markdown_table(
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
    lines += markdown_table(
        ["Tag", *AXES],
        [
            [
                str(tag),
                *(
                    fraction(int(within.sel(tag=tag, axis=a)), int(summary.n_visible.sel(tag=tag)))
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
                f"- Tag {tag}: |ty| error changes by {fmt(slope * 100.0, 3)} mm per 0.1 m of "
                f"carriage travel (least-squares line over {n_points} configurations, all "
                f"angles; {fmt(intercept * 1e3, 3)} mm at p = 0)."
            )
        else:
            lines.append(f"- Tag {tag}: too few estimates ({n_points}) to fit |ty| vs distance.")
        ratio = envelope["max"].sel(tag=tag) / thresholds()
        if np.isfinite(ratio).any():
            worst = str(ratio.idxmax("axis").values)
            exceeding = ", ".join(a for a in AXES if ratio.sel(axis=a) > 1) or "none"
            lines.append(
                f"- Tag {tag}: largest error relative to its threshold on {worst} "
                f"({fmt(float(ratio.sel(axis=worst)), 2)} x threshold); axes exceeding the "
                f"threshold somewhere: {exceeding}."
            )
    return lines


# --- comparison.md ---------------------------------------------------------------------------


def _moves_most_line(variant: str, axis: str | None, table: pd.DataFrame) -> str:
    if axis is None:
        return f"- `{variant}`: no axis has a finite relative change (no paired estimates)."
    row = table.loc[(variant, axis)]
    unit = row["unit"]
    return (
        f"- `{variant}` moves **{axis}** most: mean |error| {signed(row['change_mean_abs'])} "
        f"{unit} ({percent(row['relative_change'])} of the reference's "
        f"{fmt(row['reference_mean_abs'], 3)} {unit}); mean signed shift "
        f"{signed(row['mean_signed_shift'])} {unit}; noise (std over repeats) "
        f"{fmt(row['variant_noise'], 3)} {unit} vs {fmt(row['reference_noise'], 3)} {unit}."
    )


def _axis_rows(table: pd.DataFrame, variant: str, axes: Sequence[str]) -> list[list[str]]:
    rows = []
    for axis in axes:
        row = table.loc[(variant, axis)]
        rows.append(
            [
                axis,
                str(int(row["n_paired"])),
                fmt(row["reference_mean_abs"], 3),
                fmt(row["reference_max_abs"], 3),
                fmt(row["variant_mean_abs"], 3),
                fmt(row["variant_max_abs"], 3),
                signed(row["change_mean_abs"]),
                percent(row["relative_change"]),
                signed(row["mean_signed_shift"]),
                fmt(row["reference_noise"], 3),
                fmt(row["variant_noise"], 3),
            ]
        )
    return rows


def _axis_header(unit: str) -> list[str]:
    return [
        "Axis",
        "Paired items",
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
                fraction(ref_det, ref_att),
                fraction(det, att),
            ]
        )
    header = ["Tag", "Reference detected / visible", "Variant detected / visible"]
    return markdown_table(header, rows)


def _binned_lines(binned: pd.DataFrame, variant: str) -> list[str]:
    header = ["Bin", "Paired items"] + [f"{a} [{display_unit(a)[0]}]" for a in AXES]
    rows = [
        [str(label), str(int(row["n"])), *(signed(row[a]) for a in AXES)]
        for label, row in binned.loc[variant].iterrows()
    ]
    return markdown_table(header, rows)


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
    facing = ", ".join(
        f"tag {t} at {deg:g} deg" for t, deg in cmp.attrs["facing_theta_deg"].items()
    )
    lines = [
        f"# Variant comparison against `{reference}`",
        "",
        f"Compared variants: {', '.join(f'`{v}`' for v in variants)}. Errors are first averaged "
        f"over {cmp.attrs['n_repeat']} repeat(s) (NaN skipped); every statistic uses the "
        "items (tag, p, theta) that are visible and have an estimate in both the variant "
        "and the reference (paired). abs = mean over repeats of |error|. Change = variant - "
        "reference. Mean signed shift = mean of (variant - reference) signed error; its sign "
        "carries the direction. Noise = standard deviation over repeats (ddof 1), averaged over "
        "items. Translation in mm, rotation in mrad. View angle = turntable angle "
        f"relative to the tag facing the camera ({facing}), wrapped to [-180, 180] deg.",
        "",
        "## What each variant moves most (largest relative change of mean |error|)",
        "",
        *(_moves_most_line(v, axis, table) for v, axis in moves_most(table).items()),
        "",
    ]
    for variant in variants:
        lines += [f"## `{variant}` vs `{reference}`", "", "### Detection", ""]
        lines += _detection_lines(cmp, variant)
        for title, axes in (("Translation", TRANSLATION_AXES), ("Rotation", ROTATION_AXES)):
            unit = display_unit(axes[0])[0]
            lines += ["", f"### {title} [{unit}]", ""]
            lines += markdown_table(_axis_header(unit), _axis_rows(table, variant, axes))
        lines += ["", "### Change of mean |error| by distance (variant - reference)", ""]
        lines += _binned_lines(by_distance, variant)
        lines += ["", "### Change of mean |error| by |view angle| (variant - reference)", ""]
        lines += _binned_lines(by_angle, variant)
        lines += [""]
    if figures:
        lines += ["## Figures", ""]
        lines += [f"![{path.stem}]({path.name})\n" for path in figures]
    return "\n".join(lines)
