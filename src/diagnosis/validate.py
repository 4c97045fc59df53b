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

from simgap.analysis.candidates import geometric_effects
from simgap.core.atomic import atomic_write
from simgap.core.config import deep_merge
from simgap.diagnosis.diagnose import diagnose
from simgap.diagnosis.hidden_effects import (
    APPEARANCE,
    CAPTURE_REPEATS,
    HIDDEN,
    NUISANCE_EFFECTS,
    NUISANCE_SCENE,
    NUISANCE_SPP,
    OUTSIDE,
    REPORTED_AS,
    Sampler,
    found,
)
from simgap.diagnosis.result import DiagnosisResult
from simgap.diagnosis.result_json import jsonable, write_json
from simgap.diagnosis.validation_report import confusion, summarize_scores, validation_markdown
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
    "summarize_scores",
    "confusion",
    "found",
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
    shard : (int, int)
        ``(K, N)``: run only the trials whose index is K modulo N (processes side by side).
    spp : int
        Samples per pixel of the pseudo-real captures (:data:`NUISANCE_SPP`).
    """

    trials: int = 30
    seed: int = 0
    p: tuple[int, ...] = (0, 3, 6, 9, 12, 14)
    theta_deg: tuple[float, ...] = (0, 20, 40, 320, 340, 160, 180, 200)
    p_none: float = 0.15
    p_pair: float = 0.2
    p_outside: float = 0.1
    effects: tuple[str, ...] = tuple(HIDDEN)
    shard: tuple[int, int] = (0, 1)
    spp: int = NUISANCE_SPP

    def __post_init__(self) -> None:
        k, n = self.shard
        if not (n >= 1 and 0 <= k < n):
            raise ValueError(f"shard: expected K/N with 0 <= K < N, got {k}/{n}")
        unknown = [e for e in self.effects if e not in HIDDEN]
        if unknown or not self.effects:
            raise ValueError(
                f"effects: expected names among {', '.join(HIDDEN)}, got {', '.join(unknown)}"
                if unknown
                else "effects: expected at least one hidden effect"
            )


@dataclass
class Trial:
    """One trial: what was hidden and what the diagnosis said."""

    index: int
    hidden: dict[str, dict[str, Any]]
    result: DiagnosisResult = field(default_factory=DiagnosisResult)
    seconds: float = 0.0

    def record(self) -> dict[str, Any]:
        """The trial as ``validation.json`` keeps it: its score, params, result and seconds."""
        return jsonable(
            dict(
                self.score(),
                index=self.index,
                params=self.hidden,
                result=self.result,
                seconds=self.seconds,
            )
        )

    def score(self) -> dict[str, Any]:
        """Top-1, recall, magnitude errors and gap reduction of this trial."""
        sel = self.result.selected
        hidden = list(self.hidden)
        out: dict[str, Any] = {
            "hidden": hidden,
            "selected": sel,
            "top1": sel[0] if sel else "none",
            "unexplained": self.result.unexplained,
        }
        geometric = [e for e in sel if e in geometric_effects()]
        out["geometric_selected"] = geometric
        if not hidden:
            out["correct"] = not geometric
            return out
        if set(hidden) <= set(OUTSIDE):
            out["correct"] = self.result.unexplained and not geometric
            return out
        accepted = set(hidden) | {REPORTED_AS[h] for h in hidden if h in REPORTED_AS}
        out["correct"] = bool(sel) and sel[0] in accepted
        out["recall"] = sum(found(h, sel) for h in hidden) / len(hidden)
        selection = self.result.selection
        fitted = {f.effect: f.params for f in selection.findings} if selection else {}
        mags = {}
        for name, params in self.hidden.items():
            key = HIDDEN[name][1] if name in HIDDEN else None
            if key is None or name not in fitted:
                continue
            true, got = np.atleast_1d(params[key]), np.atleast_1d(fitted[name].get(key, 0.0))
            mags[name] = float(np.linalg.norm(got - true) / np.linalg.norm(true))
        out["magnitude_error"] = mags
        combined, confirmed = self.result.combined, self.result.confirmed
        if confirmed is not None:
            out["reduction"] = confirmed.pose_gap_reduction
        else:
            out["reduction"] = combined.scores.pose_gap_reduction if combined else None
        out["reduction_interval_90"] = combined.pose_gap_reduction_interval_90 if combined else None
        return out


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
        base.with_render(seed=seed, spp=settings.spp),
        name="pseudo_real",
        scene=deep_merge(base.scene, NUISANCE_SCENE),
        configurations=Configurations(tuple(settings.p), tuple(settings.theta_deg), ()),
        effects=effects,
        variants=(VariantSpec("baseline"),),
        grid={},
        repeats=CAPTURE_REPEATS,
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
    frames = list(simulator.frames(exp))
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

    Each finished trial is kept in ``out_dir/trials/trial_NNN.json`` (atomic write): a run that is
    stopped resumes where it was, and processes given disjoint shards (``settings.shard``) may
    run side by side on one output folder and cache; the hidden draws are the same whatever the
    shard, since every process draws all trials in order. The summary covers every trial finished
    by then, by any shard: the last shard to finish writes the complete one.

    ``simulator`` renders the captures and runs the diagnoses (default: one on ``cache_dir``).

    Raises
    ------
    ValueError
        When a kept trial file was made with other hidden effects (another seed or settings).
    """
    simulator = simulator or Simulator(cache_dir)
    rng = np.random.default_rng(settings.seed)
    out_dir = Path(out_dir)
    sim_exp = dataclasses.replace(
        base, configurations=Configurations(tuple(settings.p), tuple(settings.theta_deg), ())
    )
    shard, shards = settings.shard
    draws = [draw_hidden(rng, settings) for _ in range(settings.trials)]
    for i, hidden in enumerate(draws):
        path = out_dir / "trials" / f"trial_{i:03d}.json"
        if i % shards != shard or _kept_trial(path, hidden) is not None:
            continue
        t0 = time.perf_counter()
        folder = out_dir / "captures" / f"trial_{i:03d}"
        exp = pseudo_real_experiment(base, hidden, 1000 + settings.seed * 1000 + i, settings)
        render_capture(exp, simulator, folder)
        real = ingest(folder, exp.rig_model)
        result, _ = diagnose(real, sim_exp, simulator)
        trial = Trial(i, hidden, result, time.perf_counter() - t0)
        record = trial.record()
        write_json(record, path)
        log(
            f"trial {i}: hidden {record['hidden'] or ['none']} -> {record['top1']} "
            f"({'ok' if record['correct'] else 'MISS'}, {trial.seconds:.0f} s)"
        )
    kept = (_kept_trial(out_dir / "trials" / f"trial_{i:03d}.json", h) for i, h in enumerate(draws))
    records = [r for r in kept if r is not None]  # every shard's trials finished so far
    summary = summarize_scores(records)
    summary["trials_planned"] = settings.trials
    summary["pseudo_real_spp"] = settings.spp
    summary["pseudo_real_frames_per_pose"] = CAPTURE_REPEATS
    write_json({"summary": summary, "trials": records}, out_dir / "validation.json")
    atomic_write(out_dir / "validation.md", validation_markdown(summary, records))
    return summary


def _kept_trial(path: Path, hidden: dict[str, Any]) -> dict[str, Any] | None:
    """The trial kept at ``path`` (None if there is none yet), checked against its draw."""
    if not path.is_file():
        return None
    record = json.loads(path.read_text())
    if record["params"] != jsonable(hidden):
        raise ValueError(
            f"{path}: made with other hidden effects ({record['params']}, this run draws "
            f"{jsonable(hidden)}); use another output folder for another seed or settings"
        )
    return record
