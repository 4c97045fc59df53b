"""The diagnosis report's 'where' section: the gap per axis and the evidence tests, as markdown.

Its part of :mod:`simgap.diagnosis.diagnosis_report`: the per-axis gap table (median, trend,
z-scores, significance) and the scatter, detection and image-evidence tests behind it.
"""

from __future__ import annotations

from simgap.analysis.report import markdown_table
from simgap.core.axes import AXES, display_unit
from simgap.diagnosis.result import Where


def where_markdown(where: Where) -> list[str]:
    """Markdown lines for the 'where' part."""
    lines = [
        "## Where",
        "",
        f"Comparable items (a tag at a configuration, visible and detected in both): "
        f"{where.comparable_items}. "
        f"Significant gap: **{'yes' if where.significant else 'no'}**.",
        "",
        "| axis | n | median gap | RMS gap | trend per pin hole | noise | z (median) | z (trend) "
        "| significant |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for axis in AXES:
        a = where.axis_gaps[axis]
        if not a.n:
            lines.append(f"| {axis} | 0 | | | | | | | no |")
            continue
        if a.median is None or a.rms is None or a.slope_per_pin is None or a.noise is None:
            raise ValueError(f"axis {axis}: {a.n} comparable items but no gap summary")
        unit, k = display_unit(axis)
        lines.append(
            f"| {axis} | {a.n} | {a.median * k:+.3f} {unit} | {a.rms * k:.3f} {unit} | "
            f"{a.slope_per_pin * k:+.4f} {unit} | {a.noise * k:.3f} {unit} | "
            f"{a.z_median:+.1f} | {a.z_slope:+.1f} | {_yes(a.significant)} |"
        )
    det = where.detection
    if det is None:
        raise ValueError("the 'where' part has no detection rates")
    lines += [
        "",
        f"Detection rate over visible items: real {det.real:.1%}, "
        f"simulation {det.sim:.1%} ({det.visible_items} items).",
        "",
    ]
    lines += evidence_markdown(where)
    if where.regions:
        lines += ["Significant regions (median gap, z-score):", ""]
        for r in where.regions:
            unit, k = display_unit(r.axis)
            lines.append(
                f"- {r.axis}, {r.region}: {r.median * k:+.3f} {unit} (z = {r.z:+.1f}, n = {r.n})"
            )
        lines.append("")
    return lines


def _yes(flag: bool) -> str:
    return "**yes**" if flag else "no"


def evidence_markdown(where: Where) -> list[str]:
    """Markdown lines for the scatter, detection and image-evidence tests."""
    found = where.significant_evidence
    lines = [
        "Evidence with a significant gap: "
        + (", ".join(f"**{name}**" for name in found) if found else "none")
        + " (pose means, pose scatter, detection rate, image statistics).",
        "",
    ]
    scatter = [t for t in where.scatter_tests if t.significant]
    if scatter:
        rows = []
        for t in scatter:
            unit, k = display_unit(t.axis)
            rows.append(
                [
                    t.axis,
                    t.region,
                    f"{t.real_scatter * k:.3f} {unit}",
                    f"{t.sim_scatter * k:.3f} {unit}",
                    f"{t.ratio:.2f}",
                    f"{t.p_value:.2g}",
                ]
            )
        header = ["axis", "region", "real", "simulation", "ratio", "p"]
        lines += ["Pose scatter (Brown-Forsythe, robust scales):", ""]
        lines += markdown_table(header, rows) + [""]
    if where.detection_tests:
        header = ["region", "real", "simulation", "difference", "p", "test", "significant"]
        rows = [
            [
                t.region,
                f"{t.real_detected}/{t.real_attempts}",
                f"{t.sim_detected}/{t.sim_attempts}",
                f"{t.difference:+.1%}",
                f"{t.p_value:.2g}",
                t.test,
                _yes(t.significant),
            ]
            for t in where.detection_tests
        ]
        title = "Detection (Boschloo's exact test; the overall one planned, regions by Holm):"
        lines += [title, ""]
        lines += markdown_table(header, rows) + [""]
    if where.image_tests:
        header = ["statistic", "real median", "simulation median", "median difference"]
        header += ["floor", "p", "significant"]
        rows = [
            [
                t.stat,
                f"{t.real_median:.4g}",
                f"{t.sim_median:.4g}",
                f"{t.median_difference:+.3g} ({t.compared_as})",
                "-" if t.floor is None else str(t.floor),
                f"{t.p_value:.2g}",
                _yes(t.significant),
            ]
            for t in where.image_tests
        ]
        lines += ["Image evidence (median real - simulated per tag, Wilcoxon signed-rank):", ""]
        lines += markdown_table(header, rows) + [""]
    return lines
