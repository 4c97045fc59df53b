"""The blind validation's scores over trials, computed from the trials' scores.

:func:`summarize_scores` turns the :class:`~simgap.diagnosis.trial_score.TrialScore` of every
finished trial into a :class:`ValidationSummary`: the headline scores (top-1 accuracy overall,
strict, single, appearance; recall for pairs; no-effect, blur-only, JPEG-behind-crushed-blacks
and outside-the-catalogue rows; magnitude errors; pose-gap reductions; spurious and on-bound
shares), per effect (:class:`EffectScores`), per nuisance bin (:class:`BinScores`) and the
confusion table (:func:`confusion`). :mod:`simgap.diagnosis.validation_report` renders it.

Shares of trials are :class:`Proportion` records (how many of how many trials, the share and
its exact 90 % interval), None where no trial counts; magnitude errors are relative to the
truth's scale (fractions).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import stats

from simgap.diagnosis.hidden_effects import APPEARANCE, OUTSIDE, REPORTED_AS, found
from simgap.diagnosis.trial import CRUSHED_BLACK_SHARE
from simgap.diagnosis.trial_score import TrialScore

#: Confidence of a share's interval (:attr:`Proportion.interval_90`), as the pose-gap
#: reduction's bootstrap interval (:attr:`~simgap.diagnosis.trial_score.TrialScore.
#: pose_gap_reduction_interval_90`).
INTERVAL_CONFIDENCE = 0.9


@dataclass(frozen=True, kw_only=True)
class Proportion:
    """How many of some trials have a property: the share and the interval it is known to.

    A validation run of a few dozen trials measures an accuracy to within several tens of
    percent: 17 correct of 20 is 85 %, and the exact 90 % interval is 66-96 %; even 20 of 20
    leaves 86-100 %. The interval says what a run can and cannot tell apart (one run at 85 %
    and one at 90 % are the same product). ``share`` and ``interval_90`` follow from the
    counts (written to ``validation.json`` for readers).
    """

    json_derived: ClassVar[tuple[str, ...]] = ("share", "interval_90")

    #: trials with the property
    count: int
    #: trials counted (at least one)
    trials: int

    @property
    def share(self) -> float:
        """``count / trials`` (0-1)."""
        return self.count / self.trials

    @property
    def interval_90(self) -> tuple[float, float]:
        """The exact (Clopper-Pearson) :data:`INTERVAL_CONFIDENCE` interval of the share (0-1).

        ``scipy.stats.binomtest(count, trials).proportion_ci(method="exact")``: the trials
        are taken as independent draws of one success rate (each validation trial draws its
        effect and its camera afresh).
        """
        ci = stats.binomtest(self.count, self.trials).proportion_ci(
            confidence_level=INTERVAL_CONFIDENCE, method="exact"
        )
        return float(ci.low), float(ci.high)


@dataclass(frozen=True, kw_only=True)
class EffectScores:
    """One hidden catalogue effect's scores over the trials that hid it.

    Attributes
    ----------
    top1_accuracy_single : Proportion or None
        The trials that hid it alone, and those of them that are correct
        (:attr:`TrialScore.correct`).
    trials : int
        Trials that hid it, alone or in a pair.
    recall : float or None
        Share of those in which it was named (itself or the effect that names it).
    magnitude_error_median, magnitude_error_p90 : float or None
        Median and 90th percentile of its scored parameters' relative magnitude errors over
        those trials (:attr:`TrialScore.magnitude_error`); None where none was scored.
    """

    top1_accuracy_single: Proportion | None
    trials: int
    recall: float | None
    magnitude_error_median: float | None
    magnitude_error_p90: float | None


@dataclass(frozen=True, kw_only=True)
class BinScores:
    """The trials whose other camera is in one bin of a nuisance dimension, and how many are right.

    ``share_correct`` follows from the others (written to ``validation.json`` for readers).
    """

    json_derived: ClassVar[tuple[str, ...]] = ("share_correct",)

    #: trials in the bin
    trials: int
    #: of those, the correct ones (:attr:`TrialScore.correct`)
    correct_trials: int

    @property
    def share_correct(self) -> float:
        """Share of the bin's trials that are correct (0-1)."""
        return self.correct_trials / self.trials


@dataclass(frozen=True, kw_only=True)
class ValidationSummary:
    """The blind validation's scores over its finished trials; see the module docstring.

    Attributes
    ----------
    trials : int
        Trials summarised (finished so far, by every shard).
    top1_accuracy : Proportion or None
        The trials with hidden catalogue effects that are correct.
    every_effect_accuracy : Proportion or None
        The strict row: those trials with every hidden effect named (recall 1) and nothing
        spurious.
    top1_accuracy_single : Proportion or None
        The trials with one hidden catalogue effect that are correct.
    top1_accuracy_appearance_single : Proportion or None
        The same over the trials with one hidden appearance effect (:data:`APPEARANCE`).
    pair_recall : float or None
        Mean recall of the trials with two hidden catalogue effects.
    no_effect_correct : Proportion or None
        The trials without a hidden effect that are correct (nothing named but the camera's
        own effects).
    no_effect_free_of_geometry : Proportion or None
        Those with no geometric or calibration effect selected.
    blur_only_free_of_geometry : Proportion or None
        The trials hiding blur alone with no geometric or calibration effect selected.
    jpeg_crushed_recall : Proportion or None
        The trials hiding a JPEG on a capture whose blacks are crushed (at least
        :data:`~simgap.diagnosis.trial.CRUSHED_BLACK_SHARE` of a tag at 0 DN) that name it.
    outside_unexplained : Proportion or None
        The trials hiding an effect outside the catalogue that are correct (reported
        unexplained, no geometric or calibration effect).
    magnitude_within_25pct : float or None
        Share of the scored parameters (of every trial with hidden catalogue effects) whose
        relative magnitude error is at most 0.25.
    magnitude_error_median, magnitude_error_p90 : float or None
        Median and 90th percentile of those relative magnitude errors.
    pose_gap_reduction_median : float or None
        Median pose-gap reduction on the measure split (:attr:`TrialScore.pose_gap_reduction`)
        over the correct trials with hidden catalogue effects that measured one.
    pose_gap_reduction_at_least_70pct : float or None
        Share of those reductions that are at least 0.7.
    spurious_share : Proportion or None
        The trials naming something the capture does not have.
    on_bound_share : Proportion or None
        The trials with a selected parameter on the end of its searched range.
    undecided_trials : int
        Trials whose diagnosis left a finding undecided between look-alikes
        (:attr:`~simgap.diagnosis.trial_score.TrialScore.undecided`).
    undecided_holding_hidden : int
        Of those, the trials where a hidden effect is among an undecided finding and its
        look-alikes.
    per_effect : dict of str to EffectScores
        Per hidden catalogue effect, by name (sorted).
    per_nuisance_bin : dict of str to dict of str to BinScores
        Per nuisance dimension (in the order the trials give them) and bin label.
    confusion : dict of str to dict of str to int
        Counts of hidden effect -> answer (:func:`confusion`).
    trials_planned : int or None
        Trials the run was asked for (None: not given).
    """

    trials: int
    top1_accuracy: Proportion | None
    every_effect_accuracy: Proportion | None
    top1_accuracy_single: Proportion | None
    top1_accuracy_appearance_single: Proportion | None
    pair_recall: float | None
    no_effect_correct: Proportion | None
    no_effect_free_of_geometry: Proportion | None
    blur_only_free_of_geometry: Proportion | None
    jpeg_crushed_recall: Proportion | None
    outside_unexplained: Proportion | None
    magnitude_within_25pct: float | None
    magnitude_error_median: float | None
    magnitude_error_p90: float | None
    pose_gap_reduction_median: float | None
    pose_gap_reduction_at_least_70pct: float | None
    spurious_share: Proportion | None
    on_bound_share: Proportion | None
    undecided_trials: int
    undecided_holding_hidden: int
    per_effect: dict[str, EffectScores]
    per_nuisance_bin: dict[str, dict[str, BinScores]]
    confusion: dict[str, dict[str, int]]
    trials_planned: int | None = None


def _share(values: Sequence[float]) -> float | None:
    """The mean of ``values`` (a share of fractions, as recalls); None when there is none."""
    return float(np.mean(values)) if values else None


def _proportion(flags: Sequence[bool]) -> Proportion | None:
    """How many of ``flags`` are true, of how many; None when there is none."""
    return Proportion(count=int(sum(flags)), trials=len(flags)) if flags else None


def _median(values: Sequence[float]) -> float | None:
    return float(np.median(values)) if values else None


def _p90(values: Sequence[float]) -> float | None:
    return float(np.percentile(values, 90)) if values else None


def summarize_scores(
    scores: Sequence[TrialScore], trials_planned: int | None = None
) -> ValidationSummary:
    """The validation's scores over the trials' scores (see :class:`ValidationSummary`)."""
    outside = [s for s in scores if s.outside]
    inside = [s for s in scores if s.catalogue]
    single = [s for s in inside if len(s.hidden) == 1]
    pairs = [s for s in inside if len(s.hidden) == 2]
    none = [s for s in scores if not s.hidden]
    mags = [v for s in inside for v in s.magnitude_error.values()]
    red = [s.pose_gap_reduction for s in inside if s.correct and s.pose_gap_reduction is not None]
    appearance = [s for s in single if s.hidden[0] in APPEARANCE]
    blur_only = [s for s in single if s.hidden == ("blur",)]
    crushed_jpeg = [
        s
        for s in inside
        if "jpeg" in s.hidden and (s.crushed_black_share or 0.0) >= CRUSHED_BLACK_SHARE
    ]
    return ValidationSummary(
        trials=len(scores),
        top1_accuracy=_proportion([s.correct for s in inside]),
        every_effect_accuracy=_proportion([s.recall == 1.0 and not s.spurious for s in inside]),
        top1_accuracy_single=_proportion([s.correct for s in single]),
        top1_accuracy_appearance_single=_proportion([s.correct for s in appearance]),
        pair_recall=_share([s.recall for s in pairs if s.recall is not None]),
        no_effect_correct=_proportion([s.correct for s in none]),
        no_effect_free_of_geometry=_proportion([not s.geometric_selected for s in none]),
        blur_only_free_of_geometry=_proportion([not s.geometric_selected for s in blur_only]),
        jpeg_crushed_recall=_proportion([found("jpeg", s.decided) for s in crushed_jpeg]),
        outside_unexplained=_proportion([s.correct for s in outside]),
        magnitude_within_25pct=_share([m <= 0.25 for m in mags]),
        magnitude_error_median=_median(mags),
        magnitude_error_p90=_p90(mags),
        pose_gap_reduction_median=_median(red),
        pose_gap_reduction_at_least_70pct=_share([r >= 0.7 for r in red]),
        spurious_share=_proportion([bool(s.spurious) for s in scores]),
        on_bound_share=_proportion([bool(s.on_bound) for s in scores]),
        undecided_trials=sum(bool(s.undecided) for s in scores),
        undecided_holding_hidden=sum(_undecided_holds_hidden(s) for s in scores),
        per_effect=_per_effect(inside),
        per_nuisance_bin=_per_nuisance_bin(scores),
        confusion=confusion(scores),
        trials_planned=trials_planned,
    )


def _undecided_holds_hidden(score: TrialScore) -> bool:
    """Whether a hidden effect is among an undecided finding of the trial and its look-alikes."""
    return any(
        found(h, (effect, *alikes))
        for effect, alikes in score.undecided.items()
        for h in score.hidden
    )


def _per_effect(inside: Sequence[TrialScore]) -> dict[str, EffectScores]:
    """Per hidden catalogue effect (sorted by name), over the trials with catalogue effects."""
    out = {}
    for name in sorted({h for s in inside for h in s.hidden}):
        alone = [s for s in inside if s.hidden == (name,)]
        anywhere = [s for s in inside if name in s.hidden]
        errors = [
            v
            for s in anywhere
            for k, v in s.magnitude_error.items()
            if k.split(".")[0] in (name, REPORTED_AS.get(name))
        ]
        out[name] = EffectScores(
            top1_accuracy_single=_proportion([s.correct for s in alone]),
            trials=len(anywhere),
            recall=_share([found(name, s.decided) for s in anywhere]),
            magnitude_error_median=_median(errors),
            magnitude_error_p90=_p90(errors),
        )
    return out


def _per_nuisance_bin(scores: Sequence[TrialScore]) -> dict[str, dict[str, BinScores]]:
    """Trials and correct ones per nuisance dimension and bin (dimensions as first given)."""
    counts: dict[str, dict[str, list[int]]] = {}
    for s in scores:
        for dimension, label in s.nuisance_bins.items():
            cell = counts.setdefault(dimension, {}).setdefault(label, [0, 0])
            cell[0] += 1
            cell[1] += int(s.correct)
    return {
        dimension: {label: BinScores(trials=n, correct_trials=k) for label, (n, k) in cells.items()}
        for dimension, cells in counts.items()
    }


def confusion(scores: Sequence[TrialScore]) -> dict[str, dict[str, int]]:
    """Counts of (hidden effect -> answer), one count per hidden effect of each trial.

    The answer is the hidden effect itself when the diagnosis selected it (a hit, on the
    diagonal), else the diagnosis' top-1 (or ``none``). For an effect-free trial the answer is
    ``none`` unless something the capture does not have was named (then the first of those);
    for an effect outside the catalogue it is ``unexplained`` when reported so.
    """
    table: dict[str, dict[str, int]] = {}
    for s in scores:
        for h in s.hidden or ("none",):
            if h == "none":
                answer = s.spurious[0] if s.spurious else "none"
            elif h in OUTSIDE:
                answer = "unexplained" if s.correct else s.top1
            else:
                answer = h if found(h, s.decided) else s.top1
            row = table.setdefault(h, {})
            row[answer] = row.get(answer, 0) + 1
    return table
