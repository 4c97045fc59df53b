"""Blind validation of the gap diagnosis (``simgap validate``).

Each trial draws none, one or two hidden effects with magnitudes, geometric and appearance ones
(:data:`HIDDEN`), or one effect outside the diagnosis catalogue (:data:`OUTSIDE`), renders a
pseudo-real capture folder with them through the full pipeline under another camera's image
formation than the simulation's (:data:`NUISANCE_EFFECTS`, :data:`NUISANCE_SCENE`: another
light, another background, a Gaussian pixel filter, bilinear texture filtering, supersampling,
sensor noise, another render seed), ingests it like hardware data, diagnoses it without being
told, and scores the answer: top-1 accuracy (overall and per effect), recall for pairs, relative
magnitude error, the reduction on the report split, "no geometric or calibration effect" on
effect-free trials and "unexplained" on trials with an effect outside the catalogue.

Thresholds of the diagnosis are fixed before a blind run; reports on a seed never used while
developing are the ones quoted.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simgap.analysis.fitting import geometric_effects
from simgap.core.atomic import atomic_write
from simgap.core.config import deep_merge
from simgap.diagnosis.diagnose import diagnose
from simgap.diagnosis.hidden_effects import (
    APPEARANCE,
    HIDDEN,
    NUISANCE_EFFECTS,
    NUISANCE_SCENE,
    NUISANCE_SPP,
    OUTSIDE,
    REPORTED_AS,
    Sampler,
)
from simgap.diagnosis.result_json import write_json
from simgap.pipeline.capture import ingest, write_capture
from simgap.pipeline.experiment import Configurations, Experiment, VariantSpec
from simgap.pipeline.simulator import Simulator

__all__ = [
    "APPEARANCE",
    "HIDDEN",
    "NUISANCE_EFFECTS",
    "NUISANCE_SCENE",
    "NUISANCE_SPP",
    "OUTSIDE",
    "REPORTED_AS",
    "Sampler",
    "ValidateSettings",
    "Trial",
    "draw_hidden",
    "pseudo_real_experiment",
    "render_capture",
    "run_validation",
    "summarize",
    "summarize_scores",
    "confusion",
    "validation_markdown",
]


@dataclass(frozen=True)
class ValidateSettings:
    """Validation settings.

    Attributes
    ----------
    trials : int
        Number of trials.
    seed : int
        Seed of the draws (and of the pseudo-real render seeds).
    p : tuple of int
        Pin holes of the pseudo-real captures.
    theta_deg : tuple of float
        Turntable stops of the pseudo-real captures (deg).
    p_none, p_pair, p_outside : float
        Probability of a trial with no hidden effect, with two, and with one effect outside the
        catalogue (:data:`OUTSIDE`).
    effects : tuple of str
        Hidden effects drawn from (default: all of :data:`HIDDEN`).
    """

    trials: int = 30
    seed: int = 0
    p: tuple[int, ...] = (0, 3, 6, 9, 12, 14)
    theta_deg: tuple[float, ...] = (0, 20, 40, 320, 340, 160, 180, 200)
    p_none: float = 0.15
    p_pair: float = 0.2
    p_outside: float = 0.1
    effects: tuple[str, ...] = tuple(HIDDEN)


@dataclass
class Trial:
    """One trial: what was hidden and what the diagnosis said."""

    index: int
    hidden: dict[str, dict[str, Any]]
    result: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0

    def score(self) -> dict[str, Any]:
        """Top-1, recall, magnitude errors and gap reduction of this trial."""
        sel = self.result.get("selected", [])
        hidden = list(self.hidden)
        out: dict[str, Any] = {
            "hidden": hidden,
            "selected": sel,
            "top1": sel[0] if sel else "none",
            "unexplained": self.result.get("unexplained"),
        }
        geometric = [e for e in sel if e in geometric_effects()]
        out["geometric_selected"] = geometric
        if not hidden:
            out["correct"] = not geometric
            return out
        if set(hidden) <= set(OUTSIDE):
            out["correct"] = bool(self.result.get("unexplained")) and not geometric
            return out
        accepted = set(hidden) | {REPORTED_AS[h] for h in hidden if h in REPORTED_AS}
        out["correct"] = bool(sel) and sel[0] in accepted
        out["recall"] = sum(found(h, sel) for h in hidden) / len(hidden)
        fitted = {
            e["effect"]: e["params"] for e in self.result.get("combined", {}).get("effects", [])
        }
        mags = {}
        for name, params in self.hidden.items():
            key = HIDDEN[name][1] if name in HIDDEN else None
            if key is None or name not in fitted:
                continue
            true, got = np.atleast_1d(params[key]), np.atleast_1d(fitted[name].get(key, 0.0))
            mags[name] = float(np.linalg.norm(got - true) / np.linalg.norm(true))
        out["magnitude_error"] = mags
        combined = self.result.get("combined", {})
        out["reduction"] = self.result.get("confirmed", combined).get("reduction")
        out["reduction_interval_90"] = combined.get("reduction_interval_90")
        return out


def found(hidden: str, selected: list[str]) -> bool:
    """Whether a hidden effect is among the selected ones (itself or as :data:`REPORTED_AS`)."""
    return hidden in selected or REPORTED_AS.get(hidden) in selected


def draw_hidden(rng: np.random.Generator, settings: ValidateSettings) -> dict[str, dict[str, Any]]:
    """Draw none, one or two hidden effects with magnitudes."""
    u = rng.uniform()
    if u < settings.p_outside:
        name = str(rng.choice(list(OUTSIDE)))
        return {name: OUTSIDE[name](rng)}
    u = rng.uniform()
    k = 0 if u < settings.p_none else (2 if u > 1 - settings.p_pair else 1)
    names = rng.choice(list(settings.effects), size=k, replace=False) if k else []
    return {str(n): HIDDEN[str(n)][0](rng) for n in names}


def pseudo_real_experiment(
    base: Experiment, hidden: dict, seed: int, settings: ValidateSettings
) -> Experiment:
    """The experiment that renders a pseudo-real capture: another camera, hidden effects, seed."""
    effects = {**NUISANCE_EFFECTS, **hidden}
    return dataclasses.replace(
        base,
        name="pseudo_real",
        scene=deep_merge(base.scene, NUISANCE_SCENE),
        configurations=Configurations(tuple(settings.p), tuple(settings.theta_deg), ()),
        render=dataclasses.replace(base.render, seed=seed, spp=NUISANCE_SPP),
        effects=effects,
        variants=(VariantSpec("baseline"),),
        grid={},
        repeats=1,
    )


def render_capture(exp: Experiment, simulator: Simulator | Path, folder: Path) -> Path:
    """Render ``exp``'s frames and write them as a capture folder (what a rig operator records).

    Parameters
    ----------
    exp : Experiment
        The pseudo-real experiment (:func:`pseudo_real_experiment`).
    simulator : Simulator or Path
        The simulator, or a cache folder to build one on.
    folder : Path
        Capture folder to write.
    """
    if not isinstance(simulator, Simulator):
        simulator = Simulator(simulator, show_progress=False)
    frames = [(p, theta, 0, rgb) for p, theta, rgb in simulator.frames(exp)]
    # the operator's calibration is the nominal camera, whatever the true one is
    write_capture(folder, frames, exp.rig_model.camera)
    return folder


def run_validation(
    base: Experiment,
    out_dir: Path,
    cache_dir: Path,
    settings: ValidateSettings,
    log: Callable[[str], object] = print,
    simulator: Simulator | None = None,
) -> dict[str, Any]:
    """Run the trials and write ``validation.md`` and ``validation.json`` into ``out_dir``.

    ``simulator`` renders the captures and runs the diagnoses (default: one on ``cache_dir``).
    """
    simulator = simulator or Simulator(cache_dir)
    rng = np.random.default_rng(settings.seed)
    out_dir = Path(out_dir)
    sim_exp = dataclasses.replace(
        base, configurations=Configurations(tuple(settings.p), tuple(settings.theta_deg), ())
    )
    trials = []
    for i in range(settings.trials):
        hidden = draw_hidden(rng, settings)
        t0 = time.perf_counter()
        folder = out_dir / "captures" / f"trial_{i:03d}"
        exp = pseudo_real_experiment(base, hidden, 1000 + settings.seed * 1000 + i, settings)
        render_capture(exp, simulator, folder)
        real = ingest(folder, exp.rig_model)
        result, _ = diagnose(real, sim_exp, simulator)
        trial = Trial(i, hidden, result, time.perf_counter() - t0)
        trials.append(trial)
        s = trial.score()
        log(
            f"trial {i}: hidden {s['hidden'] or ['none']} -> {s['top1']} "
            f"({'ok' if s['correct'] else 'MISS'}, {trial.seconds:.0f} s)"
        )
        write_json(
            {"trials": [dict(t.score(), params=t.hidden) for t in trials]},
            out_dir / "validation.json",
        )
    summary = summarize(trials)
    write_json(
        {
            "summary": summary,
            "trials": [
                dict(t.score(), params=t.hidden, result=t.result, seconds=t.seconds) for t in trials
            ],
        },
        out_dir / "validation.json",
    )
    atomic_write(out_dir / "validation.md", validation_markdown(summary, trials))
    return summary


def _share(flags: list[bool]) -> float | None:
    return float(np.mean(flags)) if flags else None


def summarize(trials: list[Trial]) -> dict[str, Any]:
    """Scores over trials (DESIGN §5 item 4; issue 8's done-when)."""
    return summarize_scores([t.score() for t in trials])


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


def validation_markdown(summary: dict[str, Any], trials: list[Trial]) -> str:
    """The validation report with its confusion table."""

    def pct(v):
        return "n/a" if v is None else f"{v:.0%}"

    def num(v):
        return "n/a" if v is None else f"{v:.1%}"

    lines = [
        "# Blind validation of the gap diagnosis",
        "",
        f"{summary['trials']} trials. Pseudo-real captures are rendered as another camera: "
        f"effects {json.dumps(NUISANCE_EFFECTS)}, scene {json.dumps(NUISANCE_SCENE)}, "
        f"{NUISANCE_SPP} spp, another render seed; hidden effects drawn per trial.",
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
    for t in trials:
        s = t.score()
        mags = ", ".join(f"{k} {v:.1%}" for k, v in s.get("magnitude_error", {}).items())
        left = ", ".join(t.result.get("unexplained_evidence", [])) or "-"
        lines.append(
            f"| {t.index} | {', '.join(s['hidden']) or 'none'} | "
            f"{', '.join(s['selected']) or '-'} | {left} | {'yes' if s['correct'] else 'no'} | "
            f"{mags or '-'} | {t.seconds:.0f} |"
        )
    return "\n".join(lines) + "\n"
