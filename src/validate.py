"""Blind validation of the gap diagnosis (``simgap validate``).

Each trial draws none, one or two hidden effects with magnitudes, renders a pseudo-real capture
folder with them through the full pipeline under *other* nuisance settings than the simulation's
(another light, sensor noise, another render seed), ingests it like hardware data, diagnoses it
without being told, and scores the answer: top-1 accuracy, recall for pairs, relative magnitude
error, held-out gap reduction, and "no significant gap" on effect-free trials.
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

from simgap.atomic import atomic_write
from simgap.experiment import Configurations, Experiment, VariantSpec

Sampler = Callable[[np.random.Generator], dict[str, Any]]


def _signed(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(lo, hi))


#: Hidden effects and how their magnitudes are drawn (realistic hardware ranges), with the
#: parameter whose fitted value is scored (None: not a magnitude effect).
HIDDEN: dict[str, tuple[Sampler, str | None]] = {
    "focal_length": (lambda r: {"scale": _signed(r, 0.01, 0.03)}, "scale"),
    "principal_point": (
        lambda r: {"dx_px": _signed(r, 4, 12), "dy_px": _signed(r, 4, 12)},
        "dx_px",
    ),
    "lens_distortion": (lambda r: {"k1": _signed(r, 0.08, 0.2)}, "k1"),
    "camera_mount": (
        lambda r: {"translation_m": (_signed(r, 0.001, 0.003), 0.0, _signed(r, 0.001, 0.003))},
        "translation_m",
    ),
    "turntable_offset": (lambda r: {"angle_rad": _signed(r, 0.015, 0.04)}, "angle_rad"),
    "carriage_pitch": (lambda r: {"scale": _signed(r, 0.01, 0.03)}, "scale"),
    "tag_scale": (lambda r: {"scale": _signed(r, 0.015, 0.04)}, "scale"),
}

#: What makes the pseudo-real data "other hardware" even without a hidden effect.
NUISANCE: dict[str, dict[str, Any]] = {
    "lighting": {"type": "area", "position": [0.2, -0.25, 0.45], "power": 7.0, "cct_k": 4500},
    "sensor_noise": {"full_well_e": 9000, "read_noise_e": 3},
}


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
    p_none, p_pair : float
        Probability of a trial with no hidden effect and with two.
    effects : tuple of str
        Hidden effects drawn from (default: all of :data:`HIDDEN`).
    """

    trials: int = 30
    seed: int = 0
    p: tuple[int, ...] = (0, 3, 6, 9, 12, 14)
    theta_deg: tuple[float, ...] = (0, 20, 40, 320, 340, 160, 180, 200)
    p_none: float = 0.2
    p_pair: float = 0.2
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
        if not hidden:
            out["correct"] = not sel and not self.result["where"]["significant"]
            return out
        out["correct"] = bool(sel) and sel[0] in hidden
        out["recall"] = len(set(sel) & set(hidden)) / len(hidden)
        fitted = {
            e["effect"]: e["params"] for e in self.result.get("combined", {}).get("effects", [])
        }
        mags = {}
        for name, params in self.hidden.items():
            key = HIDDEN[name][1]
            if key is None or name not in fitted:
                continue
            true, got = np.atleast_1d(params[key]), np.atleast_1d(fitted[name].get(key, 0.0))
            mags[name] = float(np.linalg.norm(got - true) / np.linalg.norm(true))
        out["magnitude_error"] = mags
        reduction = self.result.get("confirmed", self.result.get("combined", {})).get("reduction")
        out["reduction"] = reduction
        return out


def draw_hidden(rng: np.random.Generator, settings: ValidateSettings) -> dict[str, dict[str, Any]]:
    """Draw none, one or two hidden effects with magnitudes."""
    u = rng.uniform()
    k = 0 if u < settings.p_none else (2 if u > 1 - settings.p_pair else 1)
    names = rng.choice(list(settings.effects), size=k, replace=False) if k else []
    return {str(n): HIDDEN[str(n)][0](rng) for n in names}


def pseudo_real_experiment(
    base: Experiment, hidden: dict, seed: int, settings: ValidateSettings
) -> Experiment:
    """The experiment that renders a pseudo-real capture: nuisance + hidden effects, other seed."""
    effects = {**NUISANCE, **hidden}
    return dataclasses.replace(
        base,
        name="pseudo_real",
        configurations=Configurations(tuple(settings.p), tuple(settings.theta_deg), ()),
        render=dataclasses.replace(base.render, seed=seed),
        effects=effects,
        variants=(VariantSpec("baseline"),),
        grid={},
        repeats=1,
    )


def render_capture(exp: Experiment, cache_dir: Path, folder: Path) -> Path:
    """Run ``exp`` and write its frames as a capture folder (what a rig operator records)."""
    from simgap.capture import write_capture
    from simgap.sweep import experiment_pipelines, run_experiment

    run_experiment(exp, cache_dir, show_progress=False)
    pipe = experiment_pipelines(exp, cache_dir)[0]
    ps, thetas, _ = exp.configuration_axes()
    frames = []
    for p in ps:
        for theta in thetas:
            frame = pipe.frame(int(p), float(theta), 0, 0)
            if frame is not None:
                frames.append((int(p), float(theta), 0, frame.rgb()))
    # the operator's calibration is the nominal camera, whatever the true one is
    write_capture(folder, frames, exp.rig_model.camera)
    return folder


def run_validation(
    base: Experiment, out_dir: Path, cache_dir: Path, settings: ValidateSettings, log=print
) -> dict[str, Any]:
    """Run the trials and write ``validation.md`` and ``validation.json`` into ``out_dir``."""
    from simgap.analysis.diagnose import diagnose, write_json
    from simgap.capture import ingest

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
        render_capture(exp, cache_dir, folder)
        real = ingest(folder, exp.rig_model)
        result, _ = diagnose(real, sim_exp, cache_dir)
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


def summarize(trials: list[Trial]) -> dict[str, Any]:
    """Scores over trials (DESIGN §5 item 4)."""
    scores = [t.score() for t in trials]
    single = [s for s in scores if len(s["hidden"]) == 1]
    pairs = [s for s in scores if len(s["hidden"]) == 2]
    none = [s for s in scores if not s["hidden"]]
    with_effect = [s for s in scores if s["hidden"]]
    mags = [v for s in with_effect for v in s.get("magnitude_error", {}).values()]
    red = [
        s["reduction"] for s in with_effect if s.get("correct") and s.get("reduction") is not None
    ]
    return {
        "trials": len(scores),
        "top1_accuracy": float(np.mean([s["correct"] for s in with_effect]))
        if with_effect
        else None,
        "top1_accuracy_single": float(np.mean([s["correct"] for s in single])) if single else None,
        "pair_recall": float(np.mean([s["recall"] for s in pairs])) if pairs else None,
        "no_effect_correct": float(np.mean([s["correct"] for s in none])) if none else None,
        "magnitude_within_20pct": float(np.mean([m <= 0.2 for m in mags])) if mags else None,
        "magnitude_error_median": float(np.median(mags)) if mags else None,
        "reduction_median": float(np.median(red)) if red else None,
        "reduction_at_least_70pct": float(np.mean([r >= 0.7 for r in red])) if red else None,
        "confusion": confusion(scores),
    }


def confusion(scores: list[dict]) -> dict[str, dict[str, int]]:
    """Counts of (hidden effect -> answer), one count per hidden effect of each trial.

    The answer is the hidden effect itself when the diagnosis selected it (a hit, on the
    diagonal), else the diagnosis' top-1 (or ``none``).
    """
    table: dict[str, dict[str, int]] = {}
    for s in scores:
        for h in s["hidden"] or ["none"]:
            answer = h if h in s["selected"] or (h == "none" and not s["selected"]) else s["top1"]
            row = table.setdefault(h, {})
            row[answer] = row.get(answer, 0) + 1
    return table


def validation_markdown(summary: dict[str, Any], trials: list[Trial]) -> str:
    """The validation report with its confusion table."""

    def pct(v):
        return "n/a" if v is None else f"{v:.0%}"

    lines = [
        "# Blind validation of the gap diagnosis",
        "",
        f"{summary['trials']} trials; pseudo-real captures rendered with nuisance settings "
        f"{json.dumps(NUISANCE)} and hidden effects drawn per trial.",
        "",
        "| score | value |",
        "|---|---|",
        f"| top-1 accuracy (trials with an effect) | {pct(summary['top1_accuracy'])} |",
        f"| top-1 accuracy (single effect) | {pct(summary['top1_accuracy_single'])} |",
        f"| recall for pairs | {pct(summary['pair_recall'])} |",
        f"| no-effect trials: no significant gap | {pct(summary['no_effect_correct'])} |",
        f"| fitted magnitude within 20 % | {pct(summary['magnitude_within_20pct'])} |",
        f"| held-out gap reduction, median (correct trials) | {pct(summary['reduction_median'])} |",
        f"| held-out gap reduced >= 70 % | {pct(summary['reduction_at_least_70pct'])} |",
        "",
        "## Confusion table (hidden -> answer)",
        "",
        "One count per hidden effect of each trial: on the diagonal when the diagnosis selected "
        "it, otherwise under the diagnosis' top-1 answer.",
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
        "| # | hidden | selected | correct | magnitude error | seconds |",
        "|---|---|---|---|---|---|",
    ]
    for t in trials:
        s = t.score()
        mags = ", ".join(f"{k} {v:.1%}" for k, v in s.get("magnitude_error", {}).items())
        lines.append(
            f"| {t.index} | {', '.join(s['hidden']) or 'none'} | "
            f"{', '.join(s['selected']) or '-'} | {'yes' if s['correct'] else 'no'} | "
            f"{mags or '-'} | {t.seconds:.0f} |"
        )
    return "\n".join(lines) + "\n"
