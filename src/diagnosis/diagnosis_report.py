"""The diagnosis report: where the gap lies, the effect ranking, before/after, figures, JSON.

The gap figures reuse the comparison figures (:mod:`simgap.analysis.report.figures`): the
simulation and the real data are put into one dataset as two variants, so the signed shift of
``real`` against ``simulation`` is the gap, and the change of mean ``|error|`` is
``mean |real error| - mean |simulated error|`` (not the gap; ``gap_by_distance.png`` says so).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from simgap.analysis.gap import align
from simgap.analysis.image_evidence import plot_image_stats
from simgap.analysis.report.figures import plot_change_by_distance, plot_change_heatmap
from simgap.analysis.report.output import save_figure, save_text
from simgap.analysis.report.tables import markdown_table
from simgap.analysis.thresholds import EQUIVALENT_PX, EQUIVALENT_REL
from simgap.core.axes import AXES, display_unit
from simgap.diagnosis.diagnose import Diagnosis
from simgap.diagnosis.result_json import write_json

#: Title of ``gap_by_distance.png``: what it plots is a difference of absolute errors.
GAP_BY_DISTANCE_TITLE = (
    "mean |real error| − mean |simulated error| vs distance (a change of error size, not the "
    "signed gap; paired configurations, both tags, all view angles)"
)


def gap_dataset(real: xr.Dataset, sim: xr.Dataset) -> xr.Dataset:
    """The simulation and the real data as variants ``simulation`` and ``real`` of one dataset."""
    real, sim = align(real, sim)
    sim = sim.isel(variant=[0]).assign_coords(variant=["simulation"])
    real = real.isel(variant=[0]).assign_coords(variant=["real"])
    keep = ["error", "estimated", "detected", "reproj_px", "corners"]
    both = xr.concat([sim[keep], real[keep]], dim="variant", join="outer", fill_value=np.nan)
    both["detected"] = both.detected.fillna(False).astype(bool)
    visible = real.visible if "variant" not in real.visible.dims else real.visible.isel(variant=0)
    both["visible"] = visible
    both["expected"] = real.expected
    return both


def where_markdown(where: dict[str, Any]) -> list[str]:
    """Markdown lines for the 'where' part."""
    lines = [
        "## Where",
        "",
        f"Comparable configurations (visible, detected in both): "
        f"{where['comparable_configurations']}. "
        f"Significant gap: **{'yes' if where['significant'] else 'no'}**.",
        "",
        "| axis | n | median gap | RMS gap | trend per pin hole | noise | z (median) | z (trend) "
        "| significant |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for axis in AXES:
        a = where["axes"][axis]
        if not a.get("n"):
            lines.append(f"| {axis} | 0 | | | | | | | no |")
            continue
        unit, k = display_unit(axis)
        lines.append(
            f"| {axis} | {a['n']} | {a['median'] * k:+.3f} {unit} | {a['rms'] * k:.3f} {unit} | "
            f"{a['slope_per_pin'] * k:+.4f} {unit} | {a['noise'] * k:.3f} {unit} | "
            f"{a['z_mean']:+.1f} | {a['z_slope']:+.1f} | "
            f"{'**yes**' if a['significant'] else 'no'} |"
        )
    det = where["detection"]
    lines += [
        "",
        f"Detection rate over visible configurations: real {det['real']:.1%}, "
        f"simulation {det['sim']:.1%} ({det['visible_configurations']} configurations).",
        "",
    ]
    lines += evidence_markdown(where)
    if where["regions"]:
        lines += ["Significant regions (median gap, z-score):", ""]
        for r in where["regions"]:
            unit, k = display_unit(r["axis"])
            # a region's result.json key "mean" holds its median gap (the key is kept)
            lines.append(
                f"- {r['axis']}, {r['region']}: {r['mean'] * k:+.3f} {unit} "
                f"(z = {r['z']:+.1f}, n = {r['n']})"
            )
        lines.append("")
    return lines


def _yes(flag: bool) -> str:
    return "**yes**" if flag else "no"


def evidence_markdown(where: dict[str, Any]) -> list[str]:
    """Markdown lines for the scatter, detection and image-evidence tests."""
    found = where.get("significant_evidence", [])
    lines = [
        "Evidence with a significant gap: "
        + (", ".join(f"**{name}**" for name in found) if found else "none")
        + " (pose means, pose scatter, detection rate, image statistics).",
        "",
    ]
    scatter = [r for r in where.get("scatter_tests", []) if r["significant"]]
    if scatter:
        rows = []
        for r in scatter:
            unit, k = display_unit(r["axis"])
            rows.append(
                [
                    r["axis"],
                    r["region"],
                    f"{r['real_scatter'] * k:.3f} {unit}",
                    f"{r['sim_scatter'] * k:.3f} {unit}",
                    f"{r['ratio']:.2f}",
                    f"{r['p_value']:.2g}",
                ]
            )
        header = ["axis", "region", "real", "simulation", "ratio", "p"]
        lines += ["Pose scatter (Brown-Forsythe, robust scales):", ""]
        lines += markdown_table(header, rows) + [""]
    detection = where.get("detection_tests", [])
    if detection:
        header = ["region", "real", "simulation", "difference", "p", "significant"]
        rows = [
            [
                r["region"],
                f"{r['real_detected']}/{r['real_attempts']}",
                f"{r['sim_detected']}/{r['sim_attempts']}",
                f"{r['difference']:+.1%}",
                f"{r['p_value']:.2g}",
                _yes(r["significant"]),
            ]
            for r in detection
        ]
        lines += ["Detection (Fisher's exact test):", ""]
        lines += markdown_table(header, rows) + [""]
    image = where.get("image_tests", [])
    if image:
        header = ["statistic", "real median", "simulation median", "median difference"]
        header += ["floor", "p", "significant"]
        rows = [
            [
                r["stat"],
                f"{r['real_median']:.4g}",
                f"{r['sim_median']:.4g}",
                f"{r['median_difference']:+.3g} ({r['compared_as']})",
                "-" if r["floor"] is None else str(r["floor"]),
                f"{r['p_value']:.2g}",
                _yes(r["significant"]),
            ]
            for r in image
        ]
        lines += ["Image evidence (median real - simulated per tag, Wilcoxon signed-rank):", ""]
        lines += markdown_table(header, rows) + [""]
    return lines


def _render_seeds_sentence(result: dict[str, Any]) -> str:
    """How the simulation of a small capture measured each configuration's noise (or "")."""
    seeds = result.get("render_seeds", 1)
    if seeds <= 1:
        return ""
    return (
        f" The capture is small: its simulation was rendered at {seeds} seeds per configuration, "
        "and each configuration's pose noise is the larger of its own spread over them and the "
        "per-axis noise."
    )


def which_markdown(result: dict[str, Any]) -> list[str]:
    """Markdown lines for the ranking, the selection and the before/after."""
    lines = [
        "## Which",
        "",
        "Each effect fitted on the fit split and scored on the choice split "
        f"({result['split']['train']} / {result['split']['heldout']} configurations; the "
        f"{result['split'].get('report', 0)} of the report split are kept for 'how far'). Ranked "
        "by the combined misfit of all held-out evidence, each channel in units of the smallest "
        "difference that matters: detected corners (px over the capture's corner noise), pose "
        "(per axis the median of ((real - predicted error) / noise)^2, square-rooted; pure noise "
        "~0.7), detection (share of tags detected differently, over 5 %) and every image "
        "statistic (over its floor). Pose gap before/after: on the axes where it is "
        "significant." + _render_seeds_sentence(result),
        "",
        "| rank | effect | parameters | fitted values | corners [px] | pose gap | image "
        "| detection | all evidence |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(result["ranking"], 1):
        params = ", ".join(f"{k}={_fmt(v)}" for k, v in r["params"].items())
        cells = [
            ("heldout_corner_gap_before_px", "heldout_corner_gap_after_px"),
            ("heldout_gap_before", "heldout_gap_after"),
            ("heldout_image_misfit_before", "heldout_image_misfit_after"),
            ("heldout_detection_mismatch_before", "heldout_detection_mismatch_after"),
            ("heldout_evidence_before", "heldout_evidence_after"),
        ]
        values = " | ".join(f"{r[a]:.2f} -> {r[b]:.2f}" for a, b in cells)
        lines.append(f"| {i} | {r['effect']} | {r['n_params']} | {params} | {values} |")
    lines.append("")
    if not result["where"]["significant"]:
        lines.append("**No significant gap**: nothing is selected.")
    elif not result["selected"]:
        lines.append("**Unexplained**: no effect of the catalogue explains the held-out evidence.")
    else:
        minor = result.get("minor", [])
        named = [f"{e} (minor)" if e in minor else e for e in result["selected"]]
        lines.append(f"**Selected** (most important first): {', '.join(named) or '-'}.")
        if minor:
            lines.append(
                "Minor: seen in the corners or images, no pose change beyond the practical floor."
            )
        if result["unexplained"]:
            lines.append(
                "**Unexplained** (significant, and still off on held-out configurations with the "
                f"selected effects): {', '.join(result['unexplained_evidence'])}."
            )
        alternatives = result.get("combined", {}).get("equivalent_models", [])
        if alternatives:
            lines += [
                "",
                "Other models tried explain the held-out corners about as well (residuals "
                f"within {EQUIVALENT_PX} px or {EQUIVALENT_REL:.0%}); this data cannot tell them "
                "apart (where one is simpler, the simpler is selected):",
                "",
            ]
            lines += [
                f"- {' + '.join(a['effects'])} ({a['n_params']} parameters, "
                f"{a['heldout_corner_gap_after_px']:.2f} px)"
                for a in alternatives
            ]
    lines.append("")
    if "combined" in result:
        c = result["combined"]
        lines += [
            "## How far it shrinks",
            "",
            f"Measured on the report split ({c['configurations']} configurations that neither "
            "fitted nor chose the model): pose gap "
            f"{c['heldout_gap_before']:.2f} -> {c['heldout_gap_after']:.2f} "
            f"({c['reduction']:.0%} reduction, 90 % bootstrap interval "
            f"{c['reduction_interval_90'][0]:.0%} to {c['reduction_interval_90'][1]:.0%}); all "
            f"evidence {c['heldout_evidence_before']:.2f} -> {c['heldout_evidence_after']:.2f} "
            f"({c['evidence_reduction']:.0%}, interval "
            f"{c['evidence_reduction_interval_90'][0]:.0%} to "
            f"{c['evidence_reduction_interval_90'][1]:.0%}), with the fitted effects (fast model).",
        ]
        if "confirmed" in result:
            f = result["confirmed"]
            lines.append(
                f"Confirmed by a full re-run of the pipeline with the fitted effects: "
                f"{f['heldout_gap_after']:.2f} ({f['reduction']:.0%} reduction, "
                f"{f['configurations']} held-out configurations, {f['seconds']:.0f} s)."
            )
        lines += [
            "",
            "| selected effect | fitted values | pose contribution |",
            "|---|---|---|",
        ]
        lines += [
            f"| {e['effect']} | {', '.join(f'{k}={_fmt(v)}' for k, v in e['params'].items())} "
            f"| {e['pose_contribution']:.1f} |"
            for e in c["effects"]
        ]
        lines += [
            "",
            "Pose contribution: how far the effect moves the held-out pose predictions with the "
            "other effects held at their fitted values (median |change| over the noise or "
            "practical floor, largest significant axis); below 1 the effect is minor.",
            "",
            "| axis | median abs gap before | after (fast) | after (confirmed) |",
            "|---|---|---|---|",
        ]
        for axis in AXES:
            unit, k = display_unit(axis)
            conf = result.get("confirmed", {}).get("heldout_gap_after_per_axis", {}).get(axis)
            lines.append(
                f"| {axis} | {c['heldout_gap_before_per_axis'][axis] * k:.3f} {unit} | "
                f"{c['heldout_gap_after_per_axis'][axis] * k:.3f} {unit} | "
                + (f"{conf * k:.3f} {unit} |" if conf is not None else "|")
            )
        lines.append("")
    return lines


def _fmt(v: Any) -> str:
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(_fmt(x) for x in v) + ")"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def plot_ranking(result: dict[str, Any]) -> Figure:
    """Held-out misfit of all evidence (the ranking key) and corner residual per candidate."""
    fig = Figure(figsize=(11, 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    ranking = result["ranking"]
    names = [r["effect"] for r in ranking][::-1]
    panels = [
        (
            "heldout_evidence_before",
            "heldout_evidence_after",
            "held-out misfit of all evidence (the ranking key)",
        ),
        (
            "heldout_corner_gap_before_px",
            "heldout_corner_gap_after_px",
            "held-out corner residual [px]",
        ),
    ]
    for i, (before, after, label) in enumerate(panels):
        ax = fig.add_subplot(1, 2, i + 1)
        ax.barh(names, [r[after] for r in ranking][::-1], color="tab:blue")
        if ranking:
            ax.axvline(ranking[0][before], color="k", ls="--", label="before (no effect)")
        if i == 1:
            ax.set_yticklabels([])
        ax.set_xlabel(label)
        ax.legend(loc="lower right")
    fig.suptitle(
        "Which effect explains the gap (ranked by all held-out evidence, best on top)"
    )
    return fig


def write_diagnosis_report(result: dict[str, Any], d: Diagnosis, out_dir: Path) -> list[Path]:
    """Write ``diagnosis.md``, figures (gap heatmap, by distance, ranking) and ``result.json``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    both = gap_dataset(d.real, d.sim)
    paths = [save_figure(plot_ranking(result), out_dir / "ranking.png")]
    paths.append(
        save_figure(
            plot_change_by_distance(both, "simulation", title=GAP_BY_DISTANCE_TITLE),
            out_dir / "gap_by_distance.png",
        )
    )
    paths.append(
        save_figure(
            plot_change_heatmap(both, "real", "simulation"), out_dir / "gap_heatmap.png"
        )
    )
    if "image_stats" in d.real and "image_stats" in d.sim:
        real, sim = align(d.real, d.sim)
        images = {"real": real, "simulation": sim}
        for against in ("distance", "view_angle"):
            fig = plot_image_stats(images, against, title="Image evidence: real vs simulation")
            paths.append(save_figure(fig, out_dir / f"image_stats_vs_{against}.png"))
    lines = ["# Sim-to-real gap diagnosis", ""]
    lines += where_markdown(result["where"])
    lines += which_markdown(result)
    lines += ["## Figures", ""] + [f"![{p.stem}]({p.name})" for p in paths] + [""]
    lines.append(f"Diagnosis time: {result['seconds']:.0f} s.")
    paths.append(save_text("\n".join(lines) + "\n", out_dir / "diagnosis.md"))
    paths.append(write_json(result, out_dir / "result.json"))
    return paths
