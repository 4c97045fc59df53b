"""A blind validation trial's score and the trial as its file keeps it, as typed records.

:class:`TrialScore` is what :meth:`simgap.diagnosis.trial.Trial.score` returns: how the
diagnosis answered the trial's hidden effects. :class:`TrialRecord` is a finished trial as
``OUTPUT/trials/trial_NNN.json`` keeps it (so that a stopped run resumes) and ``validation.json``
lists it: the hidden draws, the other camera, the score, the diagnosis and the seconds
(:meth:`TrialRecord.to_json`, :meth:`TrialRecord.from_json`; docs/validation.md documents the
schema).

Schema versions: 2 (this one); 1 (no ``schema_version`` key: the score's keys at the top level
beside the record's, ``reduction``, ``reduction_interval_90``, ``bins``, ``crushed_black`` and
``params`` under older names) is still read (:func:`upgrade_v1`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from simgap.diagnosis.hidden_effects import hides_catalogue_effects
from simgap.diagnosis.nuisance import NuisanceCamera
from simgap.diagnosis.result import DiagnosisResult
from simgap.diagnosis.result_json import VersionedRecord

#: Version of the trial file schema written (``trial_NNN.json`` and ``validation.json``'s trials).
TRIAL_SCHEMA_VERSION = 2
#: A trial's top-1 answer where the diagnosis named nothing but findings it left undecided
#: between look-alikes (:attr:`TrialScore.undecided`).
UNDECIDED = "undecided"


@dataclass(frozen=True, kw_only=True)
class TrialScore:
    """How a diagnosis answered one trial's hidden effects (:meth:`Trial.score`).

    A trial hides catalogue effects (one or two, :data:`~simgap.diagnosis.hidden_effects.HIDDEN`),
    one effect outside the catalogue (:data:`~simgap.diagnosis.hidden_effects.OUTSIDE`), or
    nothing. The camera's own effects are those it may always be said to have
    (:func:`simgap.diagnosis.trial.camera_named`: its exposure, sensor noise and softness, its
    black level where its shadows are crushed, a light from another direction where its lights
    light the tags unevenly).

    Attributes
    ----------
    hidden : tuple of str
        The hidden effects, in the order drawn (empty: none).
    selected : tuple of str
        The effects the diagnosis selected, most important first.
    top1 : str
        The diagnosis' answer: the first selected effect that is hidden (or names a hidden one)
        or is not one of the camera's own; else the first selected; ``"none"`` when nothing is
        selected.
    unexplained : bool
        The diagnosis left some significant evidence unexplained.
    geometric_selected : tuple of str
        The selected geometric and calibration effects.
    spurious : tuple of str
        The selected effects the capture does not have: neither hidden (nor naming a hidden
        one) nor the camera's own.
    on_bound : tuple of str
        ``effect.parameter`` of every selected parameter fitted on the end of its searched
        range.
    nuisance_bins : dict of str to str
        The trial's camera's bin in each nuisance dimension
        (:func:`simgap.diagnosis.trial.nuisance_bins`: exposure, softness, noise, frames, poses,
        the stages of its image pipeline, crushed blacks); empty without a camera.
    correct : bool
        With hidden catalogue effects: each named (of a pair: at least one) and nothing
        spurious. With an effect outside the catalogue: evidence left unexplained and no
        geometric or calibration effect selected. With nothing hidden: nothing spurious.
    recall : float or None
        Share of the hidden catalogue effects named (0-1); None without one.
    magnitude_error : dict of str to float
        Per scored parameter of a named hidden effect (``effect.parameter``): the distance
        between the fitted and the true value relative to the truth's scale (a fraction;
        :meth:`simgap.diagnosis.trial.Trial.truth`). Empty without a hidden catalogue effect.
    pose_gap_reduction : float or None
        Relative fall of the pose gap on the measure split (1: closed): re-rendered with the
        fitted effects where the diagnosis confirmed them, else predicted by the combined
        model. None without a hidden catalogue effect or without a combined model.
    pose_gap_reduction_interval_90 : (float, float) or None
        90 % bootstrap interval ([low, high]) of the combined model's pose-gap reduction on the
        measure split; None without a hidden catalogue effect or without a combined model.
    crushed_black_share : float or None
        The largest share of a tag's pixels at 0 DN over the capture's frames (0-1,
        :func:`simgap.diagnosis.trial.crushed_black_share`), against which the camera's own
        black level was judged; None where the capture has no such statistic.
    undecided : dict of str to tuple of str
        The selected effects the diagnosis left undecided, each with its look-alikes
        (:attr:`simgap.diagnosis.result.Finding.look_alikes`): named neither way, and spurious
        only where no look-alike is in the capture either. Empty in trial files written before
        findings could be undecided.
    """

    hidden: tuple[str, ...]
    selected: tuple[str, ...]
    top1: str
    unexplained: bool
    geometric_selected: tuple[str, ...]
    spurious: tuple[str, ...]
    on_bound: tuple[str, ...] = ()
    nuisance_bins: dict[str, str] = field(default_factory=dict)
    correct: bool
    recall: float | None = None
    magnitude_error: dict[str, float] = field(default_factory=dict)
    pose_gap_reduction: float | None = None
    pose_gap_reduction_interval_90: tuple[float, float] | None = None
    crushed_black_share: float | None = None
    undecided: dict[str, tuple[str, ...]] = field(default_factory=dict)

    @property
    def decided(self) -> tuple[str, ...]:
        """The selected effects the diagnosis named (those it left undecided are not)."""
        return tuple(e for e in self.selected if e not in self.undecided)

    @property
    def catalogue(self) -> bool:
        """The trial hides catalogue effects (:func:`hides_catalogue_effects`)."""
        return hides_catalogue_effects(self.hidden)

    @property
    def outside(self) -> bool:
        """The trial hides only effects outside the catalogue."""
        return bool(self.hidden) and not self.catalogue


#: Schema 1 keys renamed in schema 2 (the score's and the record's keys of a trial file).
_V1_RENAMED = {
    "reduction": "pose_gap_reduction",
    "reduction_interval_90": "pose_gap_reduction_interval_90",
    "bins": "nuisance_bins",
    "crushed_black": "crushed_black_share",
    "params": "hidden_params",
}
#: Schema 1 keys of a trial file that are the record's, not the score's.
_V1_RECORD = ("index", "params", "camera", "result", "seconds")


def upgrade_v1(data: dict[str, Any]) -> dict[str, Any]:
    """A schema-1 trial file's data in the schema-2 layout.

    Schema 1 kept the score's keys beside the record's (``index``, ``params``, ``camera``,
    ``result``, ``seconds``); schema 2 keeps them under ``score``. Renamed:
    :data:`_V1_RENAMED`; ``crushed_black`` moves into the score. Keys a schema-1 score left out
    (``recall``, ``magnitude_error``, the reductions without a hidden catalogue effect;
    ``on_bound``, ``crushed_black`` in files older than them) take their defaults.
    """
    score = {_V1_RENAMED.get(k, k): v for k, v in data.items() if k not in _V1_RECORD}
    record = {_V1_RENAMED.get(k, k): data[k] for k in _V1_RECORD if k in data}
    return {"schema_version": TRIAL_SCHEMA_VERSION, **record, "score": score}


@dataclass(frozen=True, kw_only=True)
class TrialRecord(VersionedRecord):
    """A finished trial as ``trial_NNN.json`` keeps it; see the module docstring.

    :meth:`to_json` and :meth:`from_json` write and read trial files of schema 2, and read
    schema 1 (:func:`upgrade_v1`).

    Attributes
    ----------
    schema_version : int
        Version of the schema (:data:`TRIAL_SCHEMA_VERSION`).
    index : int
        The trial's place in the run's draws (from 0).
    hidden_params : dict
        The hidden effects with their drawn parameters, in the units their effects declare.
    camera : NuisanceCamera or None
        The trial's other camera (:func:`simgap.diagnosis.nuisance.draw_nuisance`); None where
        no camera was drawn.
    score : TrialScore
        How the diagnosis answered.
    result : DiagnosisResult
        The diagnosis (``result.json``'s record).
    seconds : float
        Wall time of the trial (s): render, ingest, diagnosis.
    """

    json_schema = TRIAL_SCHEMA_VERSION
    json_upgrades = {1: upgrade_v1}
    json_source = "trial file"

    schema_version: int = TRIAL_SCHEMA_VERSION
    index: int
    hidden_params: dict[str, dict[str, Any]]
    camera: NuisanceCamera | None
    score: TrialScore
    result: DiagnosisResult
    seconds: float
