"""Blind validation of the gap diagnosis (``simgap validate``).

Each trial draws none, one or two hidden effects with magnitudes, geometric and appearance ones
(:data:`HIDDEN`), or one effect outside the diagnosis catalogue (:data:`OUTSIDE`), and its own
"other camera" (:func:`simgap.diagnosis.nuisance.draw_nuisance`: lights, exposure, pixel filter,
supersampling, texture filtering, sensor, transfer curve, vignetting, paint, poses, one or two
frames a pose). It renders a pseudo-real capture folder through that camera with the hidden
effects, ingests it like hardware data, diagnoses it without being told, and scores the answer
(:meth:`simgap.diagnosis.trial.Trial.score`): correct when the hidden effect is named (of a
pair at least one; the recall and the report's strict row count both) and nothing is named that
the capture does not have, magnitudes against the camera's truths, the
reduction on the measure split, and the nuisance bins of the trial's camera.

Thresholds of the diagnosis are fixed before a blind run; reports on a seed never used while
developing are the ones quoted.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simgap.core.atomic import atomic_write
from simgap.core.config import deep_merge
from simgap.core.rig import Rig
from simgap.diagnosis.camera_truth import lab_response, with_exposure
from simgap.diagnosis.diagnose import diagnose
from simgap.diagnosis.hidden_effects import (
    APPEARANCE,
    HIDDEN,
    OUTSIDE,
    Sampler,
    found,
    rendered_effects,
)
from simgap.diagnosis.nuisance import PIPELINE_SHARE, NuisanceCamera, draw_nuisance
from simgap.diagnosis.result_json import jsonable, write_json
from simgap.diagnosis.settings import DiagnoseSettings
from simgap.diagnosis.trial import Trial, crushed_black_share
from simgap.diagnosis.trial_score import TrialRecord
from simgap.diagnosis.validation_report import validation_json, validation_markdown
from simgap.diagnosis.validation_summary import ValidationSummary, confusion, summarize_scores
from simgap.pipeline.capture import ingest, write_capture
from simgap.pipeline.experiment import Configurations, Experiment, VariantSpec
from simgap.pipeline.simulator import Simulator

__all__ = [
    "APPEARANCE",
    "HIDDEN",
    "OUTSIDE",
    "Sampler",
    "ValidateSettings",
    "draw_hidden",
    "draw_trials",
    "pseudo_real_experiment",
    "render_capture",
    "run_validation",
    "summarize_scores",
    "confusion",
    "found",
    "validation_json",
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
        Seed of the draws (hidden effects, other cameras, render seeds).
    p : tuple of int or None
        Pin holes of every capture; None: drawn per trial with the other camera.
    theta_deg : tuple of float or None
        Turntable stops of every capture (deg); None: drawn per trial.
    frames_per_pose : int or None
        Frames a pose of every capture; None: drawn per trial (one or two).
    spp : int or None
        Samples per pixel of every capture; None: drawn per trial.
    p_none, p_pair, p_outside : float
        Probability of a trial with no hidden effect, with two, and with one effect outside the
        catalogue (:data:`OUTSIDE`).
    effects : tuple of str
        Hidden effects drawn from (default: all of :data:`HIDDEN`).
    shard : (int, int)
        ``(K, N)``: run only the trials whose index is K modulo N (processes side by side).
    converged_simulation : bool
        Diagnose with a converged simulation
        (:attr:`simgap.diagnosis.settings.DiagnoseSettings.converged_simulation`).
    camera_pipeline : bool
        Give every other camera its own image pipeline and some captures mostly frontal poses
        (:func:`simgap.diagnosis.nuisance.draw_pipeline`); False draws the cameras as before
        the pipeline stages existed (the same draws of a seed otherwise).
    stages : tuple of str
        Pipeline stages every other camera has (keys of
        :data:`simgap.diagnosis.nuisance.PIPELINE_SHARE`; default none): a validation targeted
        on a stage, e.g. a black level under JPEG. Needs ``camera_pipeline``.
    print_reflectance : bool
        Give every other camera its own tag print, ink and paper drawn
        (:func:`simgap.diagnosis.nuisance.draw_print`); False keeps the simulation's print (the
        same draws of a seed otherwise).
    measured_response : bool
        Ingest every capture with the response a lab measures of its camera from an exposure
        bracket (:func:`simgap.diagnosis.camera_truth.lab_response`; ``ingest --response``):
        the diagnosis reads the levels through it and simulates through it. False: as a capture
        without one, read with sRGB (the same draws of a seed either way).
    """

    trials: int = 30
    seed: int = 0
    p: tuple[int, ...] | None = None
    theta_deg: tuple[float, ...] | None = None
    frames_per_pose: int | None = None
    spp: int | None = None
    p_none: float = 0.15
    p_pair: float = 0.2
    p_outside: float = 0.1
    effects: tuple[str, ...] = tuple(HIDDEN)
    shard: tuple[int, int] = (0, 1)
    converged_simulation: bool = True
    camera_pipeline: bool = True
    stages: tuple[str, ...] = ()
    print_reflectance: bool = True
    measured_response: bool = False

    def __post_init__(self) -> None:
        k, n = self.shard
        if not (n >= 1 and 0 <= k < n):
            raise ValueError(f"shard: expected K/N with 0 <= K < N, got {k}/{n}")
        unknown_stages = [s for s in self.stages if s not in PIPELINE_SHARE]
        if unknown_stages:
            raise ValueError(
                f"stages: expected names among {', '.join(PIPELINE_SHARE)}, got "
                f"{', '.join(unknown_stages)}"
            )
        if self.stages and not self.camera_pipeline:
            raise ValueError("stages: only with the camera pipeline drawn")
        unknown = [e for e in self.effects if e not in HIDDEN]
        if unknown or not self.effects:
            raise ValueError(
                f"effects: expected names among {', '.join(HIDDEN)}, got {', '.join(unknown)}"
                if unknown
                else "effects: expected at least one hidden effect"
            )

    def camera(self, drawn: NuisanceCamera) -> NuisanceCamera:
        """The drawn camera with the poses, frames and samples these settings fix."""
        changes: dict[str, Any] = {}
        if self.p is not None:
            changes["p"] = tuple(self.p)
        if self.theta_deg is not None:
            changes["theta_deg"] = tuple(float(t) for t in self.theta_deg)
        if self.frames_per_pose is not None:
            changes["frames_per_pose"] = int(self.frames_per_pose)
        if self.spp is not None:
            changes["spp"] = int(self.spp)
        return dataclasses.replace(drawn, **changes)


def draw_hidden(rng: np.random.Generator, settings: ValidateSettings) -> dict[str, dict[str, Any]]:
    """Draw none, one or two hidden effects with magnitudes."""
    u = rng.uniform()
    if u < settings.p_outside:
        name = str(rng.choice(list(OUTSIDE)))
        return {name: OUTSIDE[name](rng)}
    u = rng.uniform()
    k = 0 if u < settings.p_none else (2 if u > 1 - settings.p_pair else 1)
    names: np.ndarray | list[str] = (
        rng.choice(list(settings.effects), size=k, replace=False) if k else []
    )
    return {str(n): HIDDEN[str(n)][0](rng) for n in names}


def draw_trials(
    settings: ValidateSettings, rig: Rig
) -> list[tuple[dict[str, dict[str, Any]], NuisanceCamera]]:
    """Every trial's hidden effects and other camera, in trial order (the same for any shard).

    The hidden draws, the cameras, the cameras' own image pipelines and their tag prints come
    from four streams of the seed, so that a change of one's ranges leaves the others' draws of a
    seed as they were. A hidden exposure sets the camera's total exposure
    (:func:`simgap.diagnosis.camera_truth.with_exposure`); a hidden sensor noise replaces the
    camera's sensor.
    """
    hidden_rng = np.random.default_rng(settings.seed)
    camera_rng = np.random.default_rng([settings.seed, 1])
    pipeline_rng = np.random.default_rng([settings.seed, 2]) if settings.camera_pipeline else None
    print_rng = np.random.default_rng([settings.seed, 3]) if settings.print_reflectance else None
    out = []
    for _ in range(settings.trials):
        hidden = draw_hidden(hidden_rng, settings)
        drawn = draw_nuisance(camera_rng, rig, pipeline_rng, settings.stages, print_rng)
        camera = settings.camera(drawn)
        if "exposure" in hidden:
            camera = with_exposure(camera, float(hidden["exposure"]["ev"]), rig)
        out.append((hidden, camera))
    return out


def pseudo_real_experiment(
    base: Experiment, hidden: dict, camera: NuisanceCamera, seed: int
) -> Experiment:
    """The experiment that renders a pseudo-real capture: the other camera, hidden effects, seed.

    The camera's effects with the hidden ones on top (a hidden sensor noise replaces the
    camera's; a hidden exposure is already the camera's total, :func:`draw_trials`), its scene
    overrides, samples per pixel (path traced), poses and frames a pose.
    """
    effects = {**camera.effects, **rendered_effects(hidden)}
    # path traced whatever the simulation's render mode: the other camera is another generator
    # (supersampled, not demodulated: nuisance.SPP_CHOICES)
    return dataclasses.replace(
        base.with_render(seed=seed, spp=camera.spp, mode="path"),
        name="pseudo_real",
        scene=deep_merge(base.scene, camera.scene),
        configurations=Configurations(tuple(camera.p), tuple(camera.theta_deg), ()),
        effects=effects,
        variants=(VariantSpec("baseline"),),
        grid={},
        repeats=camera.frames_per_pose,
    )


def render_capture(
    exp: Experiment,
    simulator: Simulator | Path,
    folder: Path,
    hidden: dict[str, dict[str, Any]] | None = None,
) -> Path:
    """Render ``exp``'s frames and write them as a capture folder (what a rig operator records).

    Parameters
    ----------
    exp : Experiment
        The pseudo-real experiment (:func:`pseudo_real_experiment`).
    simulator : Simulator or Path
        The simulator, or a cache folder to build one on.
    folder : Path
        Capture folder to write.
    hidden : dict, optional
        The trial's hidden effects: a ``faulty_calibration`` puts its distortion into the
        calibration file (``camera.yaml``), not into the lens.
    """
    if not isinstance(simulator, Simulator):
        simulator = Simulator(simulator, show_progress=False)
    frames = list(simulator.frames(exp))
    # the operator's calibration is the nominal camera, whatever the true one is ...
    calibration = exp.rig_model.camera
    claimed = (hidden or {}).get("faulty_calibration")
    if claimed is not None:  # ... or a file that claims a distortion the lens does not have
        calibration = calibration.replace(distortion=(float(claimed["k1"]), 0.0, 0.0, 0.0, 0.0))
    write_capture(folder, frames, calibration)
    return folder


def run_validation(
    base: Experiment,
    out_dir: Path,
    cache_dir: Path,
    settings: ValidateSettings,
    log: Callable[[str], object] = print,
    simulator: Simulator | None = None,
) -> ValidationSummary:
    """Run the trials and write ``validation.md`` and ``validation.json`` into ``out_dir``.

    Each finished trial is kept in ``out_dir/trials/trial_NNN.json`` (atomic write, a
    :class:`~simgap.diagnosis.trial_score.TrialRecord`; those of schema 1 are read): a run that is
    stopped resumes where it was, and processes given disjoint shards (``settings.shard``) may
    run side by side on one output folder and cache; the draws are the same whatever the shard,
    since every process draws all trials in order. The summary covers every trial finished by
    then, by any shard: the last shard to finish writes the complete one.

    ``simulator`` renders the captures and runs the diagnoses (default: one on ``cache_dir``).

    Raises
    ------
    ValueError
        When a kept trial file was made with other draws (another seed or settings).
    """
    simulator = simulator or Simulator(cache_dir)
    out_dir = Path(out_dir)
    rig = base.rig_model
    shard, shards = settings.shard
    draws = draw_trials(settings, rig)
    diagnose_settings = DiagnoseSettings(converged_simulation=settings.converged_simulation)
    mode = diagnose_settings.simulation(base).render.mode
    for i, (hidden, camera) in enumerate(draws):
        path = out_dir / "trials" / f"trial_{i:03d}.json"
        if i % shards != shard:
            continue
        if _kept_trial(path, hidden, camera, mode, settings.measured_response) is not None:
            continue
        t0 = time.perf_counter()
        folder = out_dir / "captures" / f"trial_{i:03d}"
        exp = pseudo_real_experiment(base, hidden, camera, 1000 + settings.seed * 1000 + i)
        render_capture(exp, simulator, folder, hidden)
        response = lab_response(camera) if settings.measured_response else None
        real = ingest(folder, rig, response=response)
        result, _ = diagnose(real, base, simulator, diagnose_settings)
        crushed = crushed_black_share(real)
        trial = Trial(i, hidden, camera, result, time.perf_counter() - t0, rig, crushed)
        record = trial.record()
        write_json(record, path)
        score = record.score
        log(
            f"trial {i}: hidden {list(score.hidden) or ['none']} -> "
            f"{list(score.selected) or ['-']} "
            f"({'ok' if score.correct else 'MISS'}, {trial.seconds:.0f} s)"
        )
    trials_dir = out_dir / "trials"
    kept = (
        _kept_trial(trials_dir / f"trial_{i:03d}.json", *d, mode, settings.measured_response)
        for i, d in enumerate(draws)
    )
    records = [r for r in kept if r is not None]  # every shard's trials finished so far
    summary = summarize_scores([r.score for r in records], settings.trials)
    write_json(validation_json(summary, records), out_dir / "validation.json")
    atomic_write(out_dir / "validation.md", validation_markdown(summary, records))
    return summary


def _kept_trial(
    path: Path,
    hidden: dict[str, Any],
    camera: NuisanceCamera,
    mode: str,
    measured_response: bool = False,
) -> TrialRecord | None:
    """The trial kept at ``path`` (None if there is none yet), checked against its draw.

    ``mode``: the render mode this run simulates with (``converged`` or ``path``);
    ``measured_response``: whether this run reads the captures through their cameras' measured
    responses. A trial diagnosed otherwise is refused, so that one summary never mixes them.

    Raises
    ------
    ValueError
        When the file does not fit the trial schema, or was made with another render mode,
        other hidden effects or another camera.
    """
    if not path.is_file():
        return None
    record = TrialRecord.from_json(json.loads(path.read_text()), str(path))
    kept_mode = record.result.simulation_mode
    if kept_mode and kept_mode != mode:
        raise ValueError(
            f"{path}: diagnosed with a {kept_mode} simulation, this run simulates {mode}; use "
            "another output folder, or --converged-simulation / --path-simulation as before"
        )
    if record.result.measured_response != measured_response:
        how = "with" if record.result.measured_response else "without"
        raise ValueError(
            f"{path}: diagnosed {how} its camera's measured response, this run "
            f"{'reads one' if measured_response else 'does not'}; use another output folder, "
            "or --measured-response / --no-measured-response as before"
        )
    drawn = jsonable(hidden)
    if jsonable(record.hidden_params) != drawn or jsonable(record.camera) != jsonable(camera):
        raise ValueError(
            f"{path}: made with other hidden effects or another camera "
            f"({jsonable(record.hidden_params)}, this run draws {drawn}); use another output "
            "folder for another seed or settings"
        )
    return record
