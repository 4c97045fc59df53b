"""The diagnosis report: ``diagnosis.md`` and its figures, from the diagnosis folder's files.

:func:`write_diagnosis_report` reads nothing but a :class:`~simgap.diagnosis.result.DiagnosisResult`
(``result.json``) and a :class:`~simgap.diagnosis.diagnosis_files.DiagnosisEvidence`
(``evidence.nc``), so ``simgap report-diagnosis`` writes it again from those two files, byte for
byte. Where the gap lies, its markdown, is :mod:`simgap.diagnosis.where_report`.

The gap heatmap is the comparison figure (:mod:`simgap.analysis.report._figures`) of the real data
against the simulation as two variants (:class:`~simgap.diagnosis.diagnosis_files.GapEvidence`),
so the signed shift of ``real`` against ``simulation`` is the gap. ``gap_by_distance.png``
(:func:`simgap.diagnosis.engineering.plot_gap_by_distance`) draws the same signed gap,
real - simulated, as the report's region table.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from simgap.analysis.gap import plot_image_stats
from simgap.analysis.report import plot_comparison_heatmap, save_figure, save_text
from simgap.analysis.thresholds import EQUIVALENT_PX, EQUIVALENT_REL, GEOMETRY_CORNER_GAP_PX
from simgap.core.axes import AXES, display_unit
from simgap.diagnosis.camera_signatures import pipeline_markdown
from simgap.diagnosis.diagnosis_files import GAP_VARIANT, DiagnosisEvidence
from simgap.diagnosis.engineering import (
    engineering_markdown,
    plot_abs_error_vs_distance,
    plot_gap_by_distance,
)
from simgap.diagnosis.result import DiagnosisResult, EquivalentModel, Finding
from simgap.diagnosis.where_report import where_markdown


def _render_seeds_sentence(result: DiagnosisResult) -> str:
    """How the simulation was rendered and each item's pose noise measured."""
    rendered = f" Simulated {result.simulation_render}." if result.simulation_render else ""
    cfa = result.demosaicing
    if cfa is not None:
        rendered += (
            f" The capture's colour frames are demosaiced from a Bayer {cfa.layout} colour "
            f"filter array (re-mosaicking residual {cfa.residual_ratio:.2f} of the other "
            "layouts'"
            + (
                f", best in the linear light of a gamma {cfa.transfer_gamma:.2f} tone response"
                if cfa.transfer_gamma is not None
                else ""
            )
            + "): the simulation images through it, demosaiced "
            f"{cfa.method.replace('_', '-')}."
        )
    if result.measured_response:
        rendered += (
            " The capture's levels are read through its camera's measured response, and the "
            "simulation images through the same response instead of sRGB."
        )
    return rendered + _pose_noise_sentence(result)


def _noise_shift_sentence(result: DiagnosisResult) -> str:
    """How the converged simulation's poses were shifted by the capture's noise (or "")."""
    if result.noise_shift_corner_px is None:
        return ""
    return (
        " Each simulated pose is the median pose under the capture's corner noise beyond the "
        f"simulation's ({result.noise_shift_corner_px:.2f} px a coordinate): PnP shifts a far, "
        "oblique tag's pose under noise, and the capture's pose carries that shift."
    )


def _pose_noise_sentence(result: DiagnosisResult) -> str:
    """How each item's pose noise was measured (or "" where by the per-axis noise)."""
    seeds = result.render_seeds
    if result.propagated_corner_noise_px is not None:
        frames = f" at {seeds} seeds per configuration (all the capture's frames a pose)"
        return (
            " The simulation is converged" + (frames if seeds > 1 else "") + ": each "
            "item's pose noise is the larger of the per-axis noise and the pose's "
            f"response to {result.propagated_corner_noise_px:.2f} px of corner noise a "
            "coordinate (the corner channel's unit over sqrt 2: the capture's and the "
            "simulation's, one frame each), propagated through PnP."
        ) + _noise_shift_sentence(result)
    if seeds <= 1:
        return ""
    return (
        f" The capture is small: its simulation was rendered at {seeds} seeds per configuration, "
        "and each item's pose noise is the larger of its own spread over them and the "
        "per-axis noise."
    )


def which_markdown(result: DiagnosisResult) -> list[str]:
    """Markdown lines for the ranking, the selection and the before/after."""
    split = result.split
    if split is None:
        raise ValueError("the result has no split: the 'which' part reports on its splits")
    lines = [
        "## Which",
        "",
        "Each effect fitted on the fit split and scored on the choose split "
        f"({split.fit} / {split.choose} items; the {split.measure} of the measure split "
        "are kept for 'how far'). Ranked by the combined misfit of all evidence on the choose "
        "split, each channel in units of the smallest difference that matters: detected corners "
        "(px over the capture's corner noise), pose (per axis the median of ((real - predicted "
        "error) / noise)^2, square-rooted; pure noise ~0.7), detection (share of tags detected "
        "differently, over 5 %) and every image statistic (over its floor). Pose gap "
        "before/after: on the axes where it is significant." + _render_seeds_sentence(result),
        "",
        "| rank | effect | parameters | fitted values | corners [px] | pose gap | image "
        "| detection | all evidence |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(result.ranking, 1):
        params = ", ".join(f"{k}={_fmt(v)}" for k, v in r.params.items())
        s = r.scores
        cells = [
            (s.corner_gap_before_px, s.corner_gap_after_px),
            (s.pose_gap_before, s.pose_gap_after),
            (s.image_misfit_before, s.image_misfit_after),
            (s.detection_mismatch_before, s.detection_mismatch_after),
            (s.evidence_before, s.evidence_after),
        ]
        values = " | ".join(f"{a:.2f} -> {b:.2f}" for a, b in cells)
        lines.append(f"| {i} | {r.effect} | {r.n_params} | {params} | {values} |")
    lines.append("")
    if result.on_bound:
        lines += [
            "Fitted with a parameter on the end of its searched range, so left out (the fit "
            "stands in for something the effect cannot express; softness is blur's, a scale "
            "beyond its range is another effect's): "
            + "; ".join(
                f"{r.effect} ({', '.join(f'{k}={_fmt(v)}' for k, v in r.params.items())})"
                for r in result.on_bound
            )
            + ".",
            "",
        ]
    refused = result.refused_geometry
    if refused is not None:
        lines += [
            f"Geometry left out: the best model with it ({', '.join(refused.effects)}) leaves "
            f"the detected corners {refused.scores.corner_gap_after_px:.2f} px off (more than "
            f"{GEOMETRY_CORNER_GAP_PX:.1f} px): something the catalogue does not model moved "
            "them (a motion smear, a defocus), and a geometry fitted to them would stand in "
            "for it.",
            "",
        ]
    if not result.where.significant and not result.selection:
        lines.append("**No significant gap**: nothing is selected.")
    elif not result.selection:
        lines.append("**Unexplained**: no effect of the catalogue explains the evidence.")
    else:
        lines += selection_markdown(result)
    lines.append("")
    if result.combined:
        lines += how_far_markdown(result)
    return lines


def selected_names(result: DiagnosisResult) -> str:
    """The selected effects, most important first, minor ones marked (``-`` for none).

    Where other models explain the capture as well (look-alikes its poses cannot tell apart),
    they are named after it: the selection is then the simplest of equals, not a verdict.
    """
    findings = result.selection.findings if result.selection else []
    names = ", ".join(_finding_name(f) for f in findings) or "-"
    alike = (
        [" + ".join(a.effects) for a in result.selection.equivalent_models]
        if result.selection
        else []
    )
    if alike:
        names += f" (these poses cannot tell it from {' or '.join(alike)})"
    return names


def _finding_name(finding: Finding) -> str:
    """A finding's name, marked minor, and undecided with its look-alikes where it is."""
    if finding.undecided:
        return f"{finding.effect} or {' or '.join(finding.look_alikes)} (minor, undecided)"
    return f"{finding.effect} (minor)" if finding.minor else finding.effect


def selection_markdown(result: DiagnosisResult) -> list[str]:
    """Markdown lines for the selected effects, what stays unexplained and the look-alikes."""
    if result.selection is None:
        raise ValueError("the result selects nothing")
    lines = [f"**Selected** (most important first): {selected_names(result)}."]
    if result.minor:
        lines.append(
            "Minor: seen in the corners or images, no pose change beyond the practical floor."
        )
    if any(f.undecided for f in result.selection.findings):
        lines.append(
            "Undecided: a minor finding whose look-alikes, each in its place, explain the "
            "evidence as well; these poses cannot tell which of them the capture has (the "
            "poses that would are listed with the look-alike models below)."
        )
    if result.unexplained:
        lines.append(
            "**Unexplained** (significant, and still off on the choose split with the selected "
            f"effects): {', '.join(result.unexplained_evidence)}."
        )
    alternatives = result.selection.equivalent_models
    if alternatives:
        lines += [
            "",
            "Other models tried explain the choose split's evidence about as well (corner "
            f"residuals within {EQUIVALENT_PX} px or {EQUIVALENT_REL:.0%}); this data cannot tell "
            "them apart (where one is simpler, the simpler is selected):",
            "",
        ]
        lines += [_look_alike_line(a) for a in alternatives]
    return lines


def _look_alike_line(model: EquivalentModel) -> str:
    """One look-alike: its effects, and the poses that would tell it from the selected model."""
    line = (
        f"- {' + '.join(model.effects)} ({model.n_params} parameters, "
        f"{model.scores.corner_gap_after_px:.2f} px)"
    )
    if model.capture_difference_px is not None and model.telling_poses:
        poses = "; ".join(
            f"pin hole {t.p}, turntable {t.theta_deg:g} deg (tag {t.tag}, {t.distance_m:.2f} m): "
            f"{t.corner_difference_px:.2f} px"
            for t in model.telling_poses
        )
        line += (
            f": its corners differ from the selected model's by at most "
            f"{model.capture_difference_px:.2f} px on the capture's poses; frames at these poses "
            f"would tell the two apart ({poses})"
        )
    return line + "."


def how_far_markdown(result: DiagnosisResult) -> list[str]:
    """Markdown lines for the chosen model on the measure split (fast and confirmed)."""
    if result.combined is None or result.selection is None:
        raise ValueError("the result has no selected model scored on the measure split")
    c, s, f = result.combined, result.combined.scores, result.confirmed
    lines = [
        "## How far it shrinks",
        "",
        f"On the measure split ({c.items} items that neither "
        "fitted nor chose the model): pose gap "
        f"{s.pose_gap_before:.2f} -> {s.pose_gap_after:.2f} "
        f"({s.pose_gap_reduction:.0%} reduction, 90 % bootstrap interval "
        f"{c.pose_gap_reduction_interval_90[0]:.0%} to "
        f"{c.pose_gap_reduction_interval_90[1]:.0%}); all evidence "
        f"{s.evidence_before:.2f} -> {s.evidence_after:.2f} ({s.evidence_reduction:.0%}, "
        f"interval {c.evidence_reduction_interval_90[0]:.0%} to "
        f"{c.evidence_reduction_interval_90[1]:.0%}), with the fitted effects (fast model).",
    ]
    if f:
        lines.append(
            f"Confirmed by a full re-run of the pipeline with the fitted effects: "
            f"{f.pose_gap_after:.2f} ({f.pose_gap_reduction:.0%} reduction, "
            f"{f.items} measure-split items, {f.seconds:.0f} s)."
        )
    lines += [
        "",
        "| selected effect | fitted values | pose contribution |",
        "|---|---|---|",
    ]
    lines += [
        f"| {e.effect} | {', '.join(f'{k}={_fmt(v)}' for k, v in e.params.items())} "
        f"| {e.pose_contribution:.1f} |"
        for e in result.selection.findings
    ]
    lines += [
        "",
        "Pose contribution: how far the effect moves the choose split's pose predictions with "
        "the other effects held at their fitted values (median |change| over the noise or "
        "practical floor, largest significant axis); below 1 the effect is minor.",
        "",
        "| axis | median abs gap before | after (fast) | after (confirmed) |",
        "|---|---|---|---|",
    ]
    for axis in AXES:
        unit, k = display_unit(axis)
        confirmed = f"{f.median_abs_gap_after[axis] * k:.3f} {unit} |" if f else "|"
        lines.append(
            f"| {axis} | {s.median_abs_gap_before[axis] * k:.3f} {unit} | "
            f"{s.median_abs_gap_after[axis] * k:.3f} {unit} | " + confirmed
        )
    lines.append("")
    return lines


def _fmt(v: Any) -> str:
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(_fmt(x) for x in v) + ")"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def plot_ranking(result: DiagnosisResult) -> Figure:
    """Misfit of all evidence (the ranking key) and corner residual per candidate (choose split)."""
    fig = Figure(figsize=(11, 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    ranking = result.ranking
    names = [r.effect for r in ranking][::-1]
    scores = [r.scores for r in ranking]
    panels = [
        (
            [s.evidence_after for s in scores],
            scores[0].evidence_before if scores else None,
            "misfit of all evidence on the choose split (the ranking key)",
        ),
        (
            [s.corner_gap_after_px for s in scores],
            scores[0].corner_gap_before_px if scores else None,
            "corner residual on the choose split [px]",
        ),
    ]
    for i, (after, before, label) in enumerate(panels):
        ax = fig.add_subplot(1, 2, i + 1)
        ax.barh(names, after[::-1], color="tab:blue")
        if before is not None:
            ax.axvline(before, color="k", ls="--", label="before (no effect)")
        if i == 1:
            ax.set_yticklabels([])
        ax.set_xlabel(label)
        ax.legend(loc="lower right")
    fig.suptitle("Which effect explains the gap (ranked by all evidence, best on top)")
    return fig


def write_diagnosis_report(
    result: DiagnosisResult, evidence: DiagnosisEvidence, out_dir: Path
) -> list[Path]:
    """Write ``diagnosis.md`` and its figures into ``out_dir``; return their paths.

    Figures: |error| and the signed gap against distance, the ranking, the gap heatmap and,
    where both sides have image statistics, those against distance and view angle. A function
    of ``result`` and ``evidence`` alone (the diagnosis folder's ``result.json`` and
    ``evidence.nc``, :func:`~simgap.diagnosis.diagnosis_files.read_diagnosis_files`): the same
    two give the same bytes.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [save_figure(plot_ranking(result), out_dir / "ranking.png")]
    heatmap = plot_comparison_heatmap(evidence.gap.comparison(), GAP_VARIANT)
    paths.append(save_figure(heatmap, out_dir / "gap_heatmap.png"))
    if evidence.image_stats is not None:
        views = evidence.image_stats.views()
        for against in ("distance", "view_angle"):
            fig = plot_image_stats(views, against, title="Image evidence: real vs simulation")
            paths.append(save_figure(fig, out_dir / f"image_stats_vs_{against}.png"))
    items = evidence.items
    real, sim, fitted = items.real_error, items.simulated_error, items.with_fitted_effects
    figure = plot_abs_error_vs_distance(items.distance_m, real, sim, fitted)
    paths.insert(0, save_figure(figure, out_dir / "abs_error_vs_distance.png"))
    figure = plot_gap_by_distance(items.p, items.distance_m, real, sim, fitted)
    paths.insert(2, save_figure(figure, out_dir / "gap_by_distance.png"))
    lines = ["# Sim-to-real gap diagnosis", ""]
    lines += engineering_markdown(items, selected_names(result))
    lines += where_markdown(result.where)
    lines += which_markdown(result)
    lines += pipeline_markdown(result.camera_pipeline, result.edge_offset)
    lines += ["## Figures", ""] + [f"![{p.stem}]({p.name})" for p in paths] + [""]
    lines.append(f"Diagnosis time: {result.seconds:.0f} s.")
    paths.append(save_text("\n".join(lines) + "\n", out_dir / "diagnosis.md"))
    return paths
