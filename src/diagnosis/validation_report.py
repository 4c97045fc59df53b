"""The blind validation's scores over trials and its report (``validation.md``).

Reads the per-trial scores :meth:`simgap.diagnosis.validate.Trial.score` makes (as
``validation.json`` keeps them): top-1 accuracy overall, per effect and for appearance effects,
recall for pairs, magnitude errors, reductions, and the confusion table.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from simgap.diagnosis.hidden_effects import (
    APPEARANCE,
    NUISANCE_EFFECTS,
    NUISANCE_SCENE,
    NUISANCE_SPP,
    OUTSIDE,
    found,
)
from simgap.diagnosis.result import DiagnosisResult


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
        errors = [s["magnitude_error"][name] for s in anywhere if name in s["magnitude_error"]]
        per_effect[name] = {
            "single_trials": len(alone),
            "top1_single": _share([s["correct"] for s in alone]),
            "trials": len(anywhere),
            "recall": _share([found(name, s["selected"]) for s in anywhere]),
            "magnitude_error_median": float(np.median(errors)) if errors else None,
        }
    appearance = [s for s in single if s["hidden"][0] in APPEARANCE]
    return {
        "trials": len(scores),
        "top1_accuracy": _share([s["correct"] for s in inside]),
        "top1_accuracy_single": _share([s["correct"] for s in single]),
        "top1_accuracy_appearance_single": _share([s["correct"] for s in appearance]),
        "pair_recall": _share([s["recall"] for s in pairs]),
        "no_effect_correct": _share([s["correct"] for s in none]),
        "outside_unexplained": _share([s["correct"] for s in outside]),
        "magnitude_within_25pct": _share([m <= 0.25 for m in mags]),
        "magnitude_error_median": float(np.median(mags)) if mags else None,
        "magnitude_error_p90": float(np.percentile(mags, 90)) if mags else None,
        "reduction_median": float(np.median(red)) if red else None,
        "reduction_at_least_70pct": _share([r >= 0.7 for r in red]),
        "per_effect": per_effect,
        "confusion": confusion(scores),
    }


def confusion(scores: list[dict]) -> dict[str, dict[str, int]]:
    """Counts of (hidden effect -> answer), one count per hidden effect of each trial.

    The answer is the hidden effect itself when the diagnosis selected it or the effect it is
    reported as (:data:`REPORTED_AS`; a hit, on the diagonal), else the diagnosis' top-1 (or
    ``none``). For an effect-free trial the answer is
    ``none`` unless a geometric or calibration effect was selected (then the first of those);
    for an effect outside the catalogue it is ``unexplained`` when reported so.
    """
    table: dict[str, dict[str, int]] = {}
    for s in scores:
        for h in s["hidden"] or ["none"]:
            if h == "none":
                answer = s["geometric_selected"][0] if s["geometric_selected"] else "none"
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
        f"{summary['trials']} trials. Pseudo-real captures are rendered as another camera: "
        f"effects {json.dumps(NUISANCE_EFFECTS)}, scene {json.dumps(NUISANCE_SCENE)}, "
        f"{summary.get('pseudo_real_spp', NUISANCE_SPP)} spp, another render seed, "
        f"{summary.get('pseudo_real_frames_per_pose', 1)} frame(s) a pose; hidden effects drawn "
        "per trial.",
        "",
        "| score | value |",
        "|---|---|",
        f"| top-1 accuracy (trials with a catalogue effect) | {pct(summary['top1_accuracy'])} |",
        f"| top-1 accuracy (single effect) | {pct(summary['top1_accuracy_single'])} |",
        "| top-1 accuracy (single appearance effect) | "
        f"{pct(summary['top1_accuracy_appearance_single'])} |",
        f"| recall for pairs | {pct(summary['pair_recall'])} |",
        "| no-effect trials free of geometric and calibration effects | "
        f"{pct(summary['no_effect_correct'])} |",
        f"| effect outside the catalogue reported unexplained | "
        f"{pct(summary['outside_unexplained'])} |",
        f"| fitted magnitude within 25 % | {pct(summary['magnitude_within_25pct'])} |",
        f"| magnitude error, median / 90th percentile | {num(summary['magnitude_error_median'])} / "
        f"{num(summary['magnitude_error_p90'])} |",
        "| pose-gap reduction on the report split, median (correct trials) | "
        f"{pct(summary['reduction_median'])} |",
        f"| reduced >= 70 % | {pct(summary['reduction_at_least_70pct'])} |",
        "",
        "## Per effect",
        "",
        "| effect | single trials | top-1 (single) | trials | recall | magnitude error (median) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {name} | {e['single_trials']} | {pct(e['top1_single'])} | {e['trials']} | "
        f"{pct(e['recall'])} | {num(e['magnitude_error_median'])} |"
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
        "| # | hidden | selected | unexplained | correct | magnitude error | seconds |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in records:
        mags = ", ".join(f"{k} {v:.1%}" for k, v in r.get("magnitude_error", {}).items())
        answer = DiagnosisResult.from_json(r["result"], f"trial {r['index']}'s result")
        left = ", ".join(answer.unexplained_evidence) or "-"
        lines.append(
            f"| {r['index']} | {', '.join(r['hidden']) or 'none'} | "
            f"{', '.join(r['selected']) or '-'} | {left} | {'yes' if r['correct'] else 'no'} | "
            f"{mags or '-'} | {r['seconds']:.0f} |"
        )
    return "\n".join(lines) + "\n"
