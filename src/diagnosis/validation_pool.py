"""Finished validation runs pooled into one report: one accuracy measured on more trials.

A run of a few dozen trials measures an accuracy to within tens of percent (its
:class:`~simgap.diagnosis.validation_summary.Proportion` intervals); runs on other seeds draw
other trials, and their trials pooled narrow the interval. :func:`pooled_trials` reads every
run's kept trial files (``RUN/trials/trial_NNN.json``, as ``simgap validate`` writes them) and
:func:`write_pooled_report` writes the ``validation.md`` and ``validation.json`` of them all
(``simgap report-validation``).

Pool runs of one simgap version only (a trial file does not say which code diagnosed it). Trials
diagnosed another way (with a converged or a path-traced simulation, with or without their
camera's measured response) are refused, and so is a draw kept twice (two runs of one seed).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from simgap.core.atomic import atomic_write
from simgap.diagnosis.result_json import jsonable, write_json
from simgap.diagnosis.trial_score import TrialRecord
from simgap.diagnosis.validation_report import validation_json, validation_markdown
from simgap.diagnosis.validation_summary import ValidationSummary, summarize_scores


@dataclass(frozen=True)
class PooledTrial:
    """One kept trial of a pooled run, and the run it was kept by.

    Attributes
    ----------
    run : str
        The run's folder, as given.
    record : TrialRecord
        The trial as its file keeps it.
    """

    run: str
    record: TrialRecord

    @property
    def label(self) -> str:
        """``RUN/index``: the trial's name in the pooled report."""
        return f"{self.run}/{self.record.index}"


def _how_diagnosed(record: TrialRecord) -> tuple[str, bool]:
    """The render mode of the trial's simulation and whether it read a measured response."""
    return record.result.simulation_mode, record.result.measured_response


def run_trials(run: Path) -> list[TrialRecord]:
    """The kept trials of one validation run, in index order.

    Raises
    ------
    ValueError
        Naming the folder when it holds no ``trials/trial_NNN.json``, or naming the file that
        does not fit the trial schema.
    """
    files = sorted((Path(run) / "trials").glob("trial_*.json"))
    if not files:
        raise ValueError(
            f"{run}: no trials/trial_NNN.json; expected the output folder of simgap validate"
        )
    return [TrialRecord.from_json(json.loads(f.read_text()), str(f)) for f in files]


def pooled_trials(runs: Sequence[Path]) -> list[PooledTrial]:
    """Every kept trial of ``runs``, run by run (see the module docstring).

    Raises
    ------
    ValueError
        When a run holds no trials, when a trial was diagnosed another way than the first
        one, or when a draw (hidden effects and camera) is kept by two trials.
    """
    pooled: list[PooledTrial] = []
    seen: dict[str, PooledTrial] = {}
    for run in runs:
        for record in run_trials(run):
            trial = PooledTrial(str(run), record)
            if pooled and _how_diagnosed(record) != _how_diagnosed(pooled[0].record):
                mode, response = _how_diagnosed(pooled[0].record)
                raise ValueError(
                    f"{trial.label}: diagnosed otherwise than {pooled[0].label} (a {mode} "
                    f"simulation, {'with' if response else 'without'} a measured response); "
                    "expected runs made alike"
                )
            draw = json.dumps(jsonable([record.hidden_params, record.camera]), sort_keys=True)
            if draw in seen:
                raise ValueError(
                    f"{trial.label}: the same draw as {seen[draw].label} (two runs of one seed?); "
                    "expected runs on different seeds"
                )
            seen[draw] = trial
            pooled.append(trial)
    return pooled


def write_pooled_report(runs: Sequence[Path], out_dir: Path) -> ValidationSummary:
    """Write ``validation.md`` and ``validation.json`` of every kept trial of ``runs``.

    ``validation.json`` is a run's (docs/validation.md) with ``runs``: the folders pooled, in
    the order their trials are listed.
    """
    trials = pooled_trials(runs)
    records = [t.record for t in trials]
    summary = summarize_scores([r.score for r in records])
    out_dir = Path(out_dir)
    data = validation_json(summary, records) | {"runs": [str(run) for run in runs]}
    write_json(data, out_dir / "validation.json")
    labels = [t.label for t in trials]
    atomic_write(out_dir / "validation.md", validation_markdown(summary, records, labels))
    return summary


__all__ = ["PooledTrial", "pooled_trials", "run_trials", "write_pooled_report"]
