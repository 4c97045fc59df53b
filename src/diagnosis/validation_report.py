"""The blind validation's report: ``validation.md`` and ``validation.json`` from its summary.

Renders a :class:`~simgap.diagnosis.validation_summary.ValidationSummary` (computed by
:func:`~simgap.diagnosis.validation_summary.summarize_scores`) and the finished trials
(:class:`~simgap.diagnosis.trial_score.TrialRecord`): :func:`validation_markdown` writes the
report, :func:`validation_json` the plain-JSON ``validation.json`` (schema
:data:`VALIDATION_SCHEMA_VERSION`; docs/validation.md documents it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from simgap.diagnosis.nuisance import INK_DENSITY, PAPER_REFLECTANCE
from simgap.diagnosis.result_json import jsonable
from simgap.diagnosis.trial import CRUSHED_BLACK_SHARE
from simgap.diagnosis.trial_score import TrialRecord, TrialScore
from simgap.diagnosis.validation_summary import Proportion, ValidationSummary

#: Version of the ``validation.json`` schema written; 2 had its shares of trials as bare
#: fractions (now :class:`~simgap.diagnosis.validation_summary.Proportion` records), 1 (no
#: ``schema_version`` key) the trials' schema-1 records and the summary keys before the typed
#: summary (docs/validation.md).
VALIDATION_SCHEMA_VERSION = 3


def validation_json(summary: ValidationSummary, trials: Sequence[TrialRecord]) -> dict[str, Any]:
    """``validation.json``: schema version, summary, and the trials as their files keep them."""
    return {
        "schema_version": VALIDATION_SCHEMA_VERSION,
        "summary": jsonable(summary),
        "trials": [t.to_json() for t in trials],
    }


def _camera_text(bins: dict[str, str]) -> str:
    """A trial's camera in the trials table: its bins, those of absent stages left out."""
    return "; ".join(f"{k}: {v}" for k, v in bins.items() if v != "none") or "-"


def _percent(share: float | None) -> str:
    """A share as a whole percentage (``n/a`` for None)."""
    return "n/a" if share is None else f"{share:.0%}"


def _share_of(proportion: Proportion | None) -> str:
    """A proportion's share as a whole percentage (``n/a`` for None)."""
    return _percent(None if proportion is None else proportion.share)


def _trials(proportion: Proportion | None) -> int:
    """The trials a proportion is over (0 for None)."""
    return 0 if proportion is None else proportion.trials


def _interval(proportion: Proportion) -> str:
    """A proportion's 90 % interval in whole percent: ``66-96%``."""
    low, high = proportion.interval_90
    return f"{100.0 * low:.0f}-{high:.0%}"


def _row(score: str, proportion: Proportion | None) -> str:
    """A score table row: the share, ``count of trials`` and its 90 % interval."""
    if proportion is None:
        return f"| {score} | n/a | 0 | |"
    return (
        f"| {score} | {proportion.share:.0%} | {proportion.count} of {proportion.trials} | "
        f"{_interval(proportion)} |"
    )


def proportion_text(proportion: Proportion | None) -> str:
    """``17 of 20 (85%; 90% interval 66-96%)``; ``n/a`` where no trial counts."""
    if proportion is None:
        return "n/a"
    return (
        f"{proportion.count} of {proportion.trials} ({proportion.share:.0%}; "
        f"90% interval {_interval(proportion)})"
    )


def _percent_1(value: float | None) -> str:
    """A fraction as a percentage with one decimal (``n/a`` for None)."""
    return "n/a" if value is None else f"{value:.1%}"


def _print_ranges() -> str:
    """The drawn ranges of the tags' print, in % reflectance (:mod:`simgap.diagnosis.nuisance`)."""
    ink = sorted(100.0 * 10.0 ** -np.asarray(INK_DENSITY))
    paper = [100.0 * x for x in PAPER_REFLECTANCE]
    return f"ink {ink[0]:.1f}-{ink[1]:.0f} %, paper {paper[0]:.0f}-{paper[1]:.0f} % reflectance"


def validation_markdown(
    summary: ValidationSummary,
    trials: Sequence[TrialRecord],
    labels: Sequence[str] | None = None,
) -> str:
    """``validation.md``: the scores, per nuisance bin, per effect, the confusion table, trials.

    ``trials`` are the finished trials the summary is over, in the table's order; ``labels``
    name them in the trials table (default: their indices; pooled runs:
    :func:`simgap.diagnosis.validation_pool.write_pooled_report`).
    """
    if labels is None:
        labels = [str(t.index) for t in trials]
    pct, num = _percent, _percent_1

    lines = [
        "# Blind validation of the gap diagnosis",
        "",
        f"{summary.trials} trials. Each pseudo-real capture is rendered through its own "
        "other camera, drawn per trial (simgap.diagnosis.nuisance: key light type, place, power "
        "and colour; ambient; total exposure -1.5 to +1.5 EV; box, tent or Gaussian pixel "
        "filter; 49-81 spp; nearest or bilinear texture filtering; full well 1000-20000 e-, read "
        "noise 1-10 e-; sRGB or gamma 1.8-2.4; vignetting; node and table paint; where drawn, the "
        f"tags' print ({_print_ranges()}); 4-6 pin holes x 6-8 stops, "
        "both frontal stops among them; one or two frames a pose; where drawn, the "
        "camera's own image pipeline, each stage in some cameras: gain changes per frame, a "
        "black level crushing the shadows, Bayer demosaicing, bilateral denoising, an S-shaped "
        "tone curve, sharpening, lateral colour, and mostly frontal poses in a quarter of the "
        "captures), with hidden effects drawn per trial. Correct: "
        "the hidden effect named (of a pair: at least one; the strict row asks for both, and the "
        "recall for pairs counts them) and nothing named that the capture does not have (the "
        "camera's own exposure, sensor noise and softness may always be named, its black "
        "level where at least 2 % of a tag is at 0 DN, a light the simulation lacks where its "
        "own lights light the tags unevenly, and an edge offset where its pipeline or print "
        "moves soft edges).",
        "",
        "The trials column counts those a score is over; the interval is the exact 90 % "
        "interval of the share (a run of a few dozen trials measures an accuracy to within "
        "tens of percent: simgap.diagnosis.validation_summary.Proportion).",
        "",
        "| score | value | trials | 90 % interval |",
        "|---|---|---|---|",
        _row("top-1 accuracy (trials with a catalogue effect)", summary.top1_accuracy),
        _row(
            "every hidden effect named, nothing spurious (strict; trials with a catalogue effect)",
            summary.every_effect_accuracy,
        ),
        _row("top-1 accuracy (single effect)", summary.top1_accuracy_single),
        _row("top-1 accuracy (single appearance effect)", summary.top1_accuracy_appearance_single),
        f"| recall for pairs | {pct(summary.pair_recall)} | | |",
        _row(
            "no-effect trials correct (nothing named but the camera's own effects)",
            summary.no_effect_correct,
        ),
        _row(
            "no-effect trials free of geometric and calibration effects",
            summary.no_effect_free_of_geometry,
        ),
        _row(
            "blur-only trials free of geometric and calibration effects",
            summary.blur_only_free_of_geometry,
        ),
        _row(
            f"JPEG named where the capture's blacks are crushed (>= {CRUSHED_BLACK_SHARE:.0%} of "
            "a tag at 0 DN)",
            summary.jpeg_crushed_recall,
        ),
        _row("effect outside the catalogue reported unexplained", summary.outside_unexplained),
        f"| fitted magnitude within 25 % | {pct(summary.magnitude_within_25pct)} | | |",
        f"| magnitude error, median / 90th percentile | {num(summary.magnitude_error_median)} / "
        f"{num(summary.magnitude_error_p90)} | | |",
        "| pose-gap reduction on the measure split, median (correct trials) | "
        f"{pct(summary.pose_gap_reduction_median)} | | |",
        f"| reduced >= 70 % | {pct(summary.pose_gap_reduction_at_least_70pct)} | | |",
        _row("trials naming something the capture does not have", summary.spurious_share),
        _row(
            "trials with a selected parameter on the end of its searched range",
            summary.on_bound_share,
        ),
    ]
    if summary.undecided_trials:  # a row only where a diagnosis left a finding undecided
        lines.append(
            "| trials with a finding undecided between look-alikes (a hidden effect among "
            f"them) | {summary.undecided_trials} ({summary.undecided_holding_hidden}) | | |"
        )
    lines += [
        "",
        "## Per nuisance bin (share of trials correct)",
        "",
        "| nuisance | bin | trials | correct |",
        "|---|---|---|---|",
    ]
    for dimension, cells in summary.per_nuisance_bin.items():
        for label, cell in sorted(cells.items()):
            lines.append(f"| {dimension} | {label} | {cell.trials} | {pct(cell.share_correct)} |")
    lines += [
        "",
        "## Per effect",
        "",
        "| effect | single trials | correct (single) | trials | recall | magnitude error "
        "(median / 90th pct) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {name} | {_trials(e.top1_accuracy_single)} | {_share_of(e.top1_accuracy_single)} | "
        f"{e.trials} | "
        f"{pct(e.recall)} | {num(e.magnitude_error_median)} / {num(e.magnitude_error_p90)} |"
        for name, e in summary.per_effect.items()
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
    answers = sorted({a for row in summary.confusion.values() for a in row})
    lines.append("| hidden \\ answer | " + " | ".join(answers) + " |")
    lines.append("|---|" + "---|" * len(answers))
    for hidden, row in sorted(summary.confusion.items()):
        lines.append(f"| {hidden} | " + " | ".join(str(row.get(a, "")) for a in answers) + " |")
    lines += [
        "",
        "## Trials",
        "",
        "| # | hidden | selected | unexplained | correct | magnitude error | camera | seconds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, t in zip(labels, trials, strict=True):
        score = t.score
        mags = ", ".join(f"{k} {v:.1%}" for k, v in score.magnitude_error.items())
        left = ", ".join(t.result.unexplained_evidence) or "-"
        lines.append(
            f"| {label} | {', '.join(score.hidden) or 'none'} | "
            f"{_selected_text(score)} | {left} | {'yes' if score.correct else 'no'} | "
            f"{mags or '-'} | {_camera_text(score.nuisance_bins)} | {t.seconds:.0f} |"
        )
    return "\n".join(lines) + "\n"


def _selected_text(score: TrialScore) -> str:
    """The selected effects, each undecided one with its look-alikes (``-`` for none)."""
    names = [
        f"{e} (undecided: or {' or '.join(score.undecided[e])})" if e in score.undecided else e
        for e in score.selected
    ]
    return ", ".join(names) or "-"
