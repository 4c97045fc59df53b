"""The blind validation's scores over trials and its report (``validation.md``).

Reads the per-trial scores :meth:`simgap.diagnosis.trial.Trial.score` makes (as
``validation.json`` keeps them): top-1 accuracy overall, per effect and for appearance effects,
recall for pairs, magnitude errors, reductions, and the confusion table.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from simgap.diagnosis.hidden_effects import APPEARANCE, OUTSIDE, REPORTED_AS, found
from simgap.diagnosis.result import DiagnosisResult
from simgap.diagnosis.trial import CRUSHED_BLACK_SHARE


def _share(flags: list[bool]) -> float | None:
    return float(np.mean(flags)) if flags else None


def summarize_scores(scores: list[dict[str, Any]]) -> dict[str, Any]:
    """Scores over trials from each trial's :meth:`Trial.score` (as validation.json keeps)."""
    outside = [s for s in scores if s["hidden"] and set(s["hidden"]) <= set(OUTSIDE)]
    inside = [s for s in scores if s["hidden"] and s not in outside]
    single = [s for s in inside if len(s["hidden"]) == 1]
    pairs = [s for s in inside if len(s["hidden"]) == 2]
    none = [s for s in scores if not s["hidden"]]
    mags = [v for s in inside for v in s.get("magnitude_error", {}).values()]
    red = [s["reduction"] for s in inside if s.get("correct") and s.get("reduction") is not None]
    per_effect = {}
    for name in sorted({h for s in inside for h in s["hidden"]}):
        alone = [s for s in single if s["hidden"] == [name]]
        anywhere = [s for s in inside if name in s["hidden"]]
        errors = [
            v
            for s in anywhere
            for k, v in s.get("magnitude_error", {}).items()
            if k.split(".")[0] in (name, REPORTED_AS.get(name))
        ]
        per_effect[name] = {
            "single_trials": len(alone),
            "top1_single": _share([s["correct"] for s in alone]),
            "trials": len(anywhere),
            "recall": _share([found(name, s["selected"]) for s in anywhere]),
            "magnitude_error_median": float(np.median(errors)) if errors else None,
            "magnitude_error_p90": float(np.percentile(errors, 90)) if errors else None,
        }
    appearance = [s for s in single if s["hidden"][0] in APPEARANCE]
    blur_only = [s for s in single if s["hidden"] == ["blur"]]
    crushed_jpeg = [
        s
        for s in inside
        if "jpeg" in s["hidden"] and (s.get("crushed_black") or 0.0) >= CRUSHED_BLACK_SHARE
    ]
    bins: dict[str, dict[str, dict[str, Any]]] = {}
    for s in scores:
        for dimension, label in s.get("bins", {}).items():
            cell = bins.setdefault(dimension, {}).setdefault(label, {"trials": 0, "correct": 0})
            cell["trials"] += 1
            cell["correct"] += int(bool(s["correct"]))
    for dimension in bins.values():
        for cell in dimension.values():
            cell["share_correct"] = cell["correct"] / cell["trials"]
    return {
        "trials": len(scores),
        "top1_accuracy": _share([s["correct"] for s in inside]),
        "every_effect_accuracy": _share(
            [s.get("recall") == 1.0 and not s["spurious"] for s in inside]
        ),
        "top1_accuracy_single": _share([s["correct"] for s in single]),
        "top1_accuracy_appearance_single": _share([s["correct"] for s in appearance]),
        "pair_recall": _share([s["recall"] for s in pairs]),
        "no_effect_correct": _share([s["correct"] for s in none]),
        "no_effect_free_of_geometry": _share([not s.get("geometric_selected") for s in none]),
        "blur_only_free_of_geometry": _share([not s.get("geometric_selected") for s in blur_only]),
        "jpeg_crushed_recall": _share([found("jpeg", s["selected"]) for s in crushed_jpeg]),
        "jpeg_crushed_trials": len(crushed_jpeg),
        "outside_unexplained": _share([s["correct"] for s in outside]),
        "magnitude_within_25pct": _share([m <= 0.25 for m in mags]),
        "magnitude_error_median": float(np.median(mags)) if mags else None,
        "magnitude_error_p90": float(np.percentile(mags, 90)) if mags else None,
        "reduction_median": float(np.median(red)) if red else None,
        "reduction_at_least_70pct": _share([r >= 0.7 for r in red]),
        "spurious_trials": _share([bool(s.get("spurious")) for s in scores]),
        "on_bound_trials": _share([bool(s.get("on_bound")) for s in scores]),
        "per_effect": per_effect,
        "per_nuisance_bin": bins,
        "confusion": confusion(scores),
    }


def _camera_text(bins: dict[str, str]) -> str:
    """A trial's camera in the trials table: its bins, those of absent stages left out."""
    return "; ".join(f"{k}: {v}" for k, v in bins.items() if v != "none") or "-"


def confusion(scores: list[dict]) -> dict[str, dict[str, int]]:
    """Counts of (hidden effect -> answer), one count per hidden effect of each trial.

    The answer is the hidden effect itself when the diagnosis selected it (a hit, on the
    diagonal), else the diagnosis' top-1 (or ``none``). For an effect-free trial the answer is
    ``none`` unless something the capture does not have was named (then the first of those);
    for an effect outside the catalogue it is ``unexplained`` when reported so.
    """
    table: dict[str, dict[str, int]] = {}
    for s in scores:
        for h in s["hidden"] or ["none"]:
            if h == "none":
                wrong = s.get("spurious", s["geometric_selected"])
                answer = wrong[0] if wrong else "none"
            elif h in OUTSIDE:
                answer = "unexplained" if s["correct"] else s["top1"]
            else:
                answer = h if found(h, s["selected"]) else s["top1"]
            row = table.setdefault(h, {})
            row[answer] = row.get(answer, 0) + 1
    return table


def validation_markdown(summary: dict[str, Any], records: list[dict[str, Any]]) -> str:
    """The validation report with its confusion table.

    ``records`` are the trials as ``validation.json`` keeps them: each trial's score with its
    ``index``, ``result`` and ``seconds``.
    """

    def pct(v):
        return "n/a" if v is None else f"{v:.0%}"

    def num(v):
        return "n/a" if v is None else f"{v:.1%}"

    lines = [
        "# Blind validation of the gap diagnosis",
        "",
        f"{summary['trials']} trials. Each pseudo-real capture is rendered through its own "
        "other camera, drawn per trial (simgap.diagnosis.nuisance: key light type, place, power "
        "and colour; ambient; total exposure -1.5 to +1.5 EV; box, tent or Gaussian pixel "
        "filter; 49-81 spp; nearest or bilinear texture filtering; full well 1000-20000 e-, read "
        "noise 1-10 e-; sRGB or gamma 1.8-2.4; vignetting; node and table paint; 4-6 pin holes x "
        "6-8 stops, both frontal stops among them; one or two frames a pose; where drawn, the "
        "camera's own image pipeline, each stage in some cameras: gain changes per frame, a "
        "black level crushing the shadows, Bayer demosaicing, bilateral denoising, an S-shaped "
        "tone curve, sharpening, lateral colour, and mostly frontal poses in a quarter of the "
        "captures), with hidden effects drawn per trial. Correct: "
        "the hidden effect named (of a pair: at least one; the strict row asks for both, and the "
        "recall for pairs counts them) and nothing named that the capture does not have (the "
        "camera's own exposure, sensor noise and softness may always be named, and its black "
        "level where at least 2 % of a tag is at 0 DN).",
        "",
        "| score | value |",
        "|---|---|",
        f"| top-1 accuracy (trials with a catalogue effect) | {pct(summary['top1_accuracy'])} |",
        "| every hidden effect named, nothing spurious (strict; trials with a catalogue effect) | "
        f"{pct(summary['every_effect_accuracy'])} |",
        f"| top-1 accuracy (single effect) | {pct(summary['top1_accuracy_single'])} |",
        "| top-1 accuracy (single appearance effect) | "
        f"{pct(summary['top1_accuracy_appearance_single'])} |",
        f"| recall for pairs | {pct(summary['pair_recall'])} |",
        "| no-effect trials correct (nothing named but the camera's own effects) | "
        f"{pct(summary['no_effect_correct'])} |",
        "| no-effect trials free of geometric and calibration effects | "
        f"{pct(summary['no_effect_free_of_geometry'])} |",
        "| blur-only trials free of geometric and calibration effects | "
        f"{pct(summary.get('blur_only_free_of_geometry'))} |",
        f"| JPEG named where the capture's blacks are crushed (>= "
        f"{CRUSHED_BLACK_SHARE:.0%} of a tag at 0 DN; {summary.get('jpeg_crushed_trials', 0)} "
        f"trials) | {pct(summary.get('jpeg_crushed_recall'))} |",
        f"| effect outside the catalogue reported unexplained | "
        f"{pct(summary['outside_unexplained'])} |",
        f"| fitted magnitude within 25 % | {pct(summary['magnitude_within_25pct'])} |",
        f"| magnitude error, median / 90th percentile | {num(summary['magnitude_error_median'])} / "
        f"{num(summary['magnitude_error_p90'])} |",
        "| pose-gap reduction on the report split, median (correct trials) | "
        f"{pct(summary['reduction_median'])} |",
        f"| reduced >= 70 % | {pct(summary['reduction_at_least_70pct'])} |",
        f"| trials naming something the capture does not have | "
        f"{pct(summary.get('spurious_trials'))} |",
        "| trials with a selected parameter on the end of its searched range | "
        f"{pct(summary.get('on_bound_trials'))} |",
        "",
        "## Per nuisance bin (share of trials correct)",
        "",
        "| nuisance | bin | trials | correct |",
        "|---|---|---|---|",
    ]
    for dimension, cells in summary.get("per_nuisance_bin", {}).items():
        for label, cell in sorted(cells.items()):
            lines.append(
                f"| {dimension} | {label} | {cell['trials']} | {pct(cell['share_correct'])} |"
            )
    lines += [
        "",
        "## Per effect",
        "",
        "| effect | single trials | correct (single) | trials | recall | magnitude error "
        "(median / 90th pct) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {name} | {e['single_trials']} | {pct(e['top1_single'])} | {e['trials']} | "
        f"{pct(e['recall'])} | {num(e['magnitude_error_median'])} / "
        f"{num(e.get('magnitude_error_p90'))} |"
        for name, e in summary["per_effect"].items()
    ]
    lines += [
        "",
        "## Confusion table (hidden -> answer)",
        "",
        "One count per hidden effect of each trial: on the diagonal when the diagnosis selected "
        "it, otherwise under the diagnosis' top-1 answer (`unexplained` for an effect outside "
        "the catalogue reported as unexplained).",
        "",
    ]
    answers = sorted({a for row in summary["confusion"].values() for a in row})
    lines.append("| hidden \\ answer | " + " | ".join(answers) + " |")
    lines.append("|---|" + "---|" * len(answers))
    for hidden, row in sorted(summary["confusion"].items()):
        lines.append(f"| {hidden} | " + " | ".join(str(row.get(a, "")) for a in answers) + " |")
    lines += [
        "",
        "## Trials",
        "",
        "| # | hidden | selected | unexplained | correct | magnitude error | camera | seconds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in records:
        mags = ", ".join(f"{k} {v:.1%}" for k, v in r.get("magnitude_error", {}).items())
        answer = DiagnosisResult.from_json(r["result"], f"trial {r['index']}'s result")
        left = ", ".join(answer.unexplained_evidence) or "-"
        lines.append(
            f"| {r['index']} | {', '.join(r['hidden']) or 'none'} | "
            f"{', '.join(r['selected']) or '-'} | {left} | {'yes' if r['correct'] else 'no'} | "
            f"{mags or '-'} | {_camera_text(r.get('bins', {}))} | "
            f"{r['seconds']:.0f} |"
        )
    return "\n".join(lines) + "\n"
