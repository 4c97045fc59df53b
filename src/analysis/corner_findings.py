"""Calibration effects the corners single out: beside a chosen model, or alone.

An effect with a corner signature of its own (a lens distortion: a radial pattern no pose,
exposure or softness change makes) is a finding wherever the held-out corners single it out
(:func:`~simgap.analysis.admission.seen_in_corners`), even when it moves no pose beyond the floor
(it is then minor, never silently dropped). The greedy search of
:meth:`simgap.analysis.selection.ModelSearch.select` adds the effect that lowers the combined
misfit most, so a distortion that lowers only the corners was crowded out by appearance effects
that lowered the image statistics more and were then pruned (blind seed 37 trials 40 and 69: a
calibration file's distortion answered by exposure alone, although exposure + lens distortion was
admissible and lowered the corner gap 0.244 -> 0.213 and 0.156 -> 0.098 px). And where no
evidence family differs significantly, a wrong distortion in the calibration file that moves no
pose significantly was never looked for (trial 45: corner gap 0.336 -> 0.172 px with the lens).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from simgap.analysis.admission import (
    admissible,
    at_bound,
    has_corner_signature,
    seen_in_corners,
)
from simgap.analysis.fitting import Candidate, ProjectionCandidate
from simgap.analysis.scored import Scored


def with_corner_effects(
    scored: Scored,
    pool: Sequence[Candidate],
    evaluate: Callable[[tuple[Candidate, ...]], Scored],
    max_effects: int,
) -> Scored:
    """``scored`` with every corner-signature effect of ``pool`` the corners single out beside it.

    One at a time, the one whose model explains the evidence best first, while the model may
    grow (``max_effects``): the effect may enter beside the model (:func:`admissible`) and
    the held-out corners single it out (:func:`seen_in_corners`). A geometric effect of the model
    that could no longer enter beside it leaves (:func:`without_displaced`).
    """
    while len(scored.fits) < max_effects:
        model = tuple(c for c, _ in scored.fits)
        options = []
        for c in pool:
            if not has_corner_signature(c) or c in model:
                continue
            option = evaluate(model + (c,))
            if admissible(option, scored) and seen_in_corners(option, scored):
                options.append((option, c))
        if not options:
            return scored
        best, added = min(options, key=lambda oc: oc[0].evidence_after)
        scored = without_displaced(best, evaluate, added)
    return scored


def without_displaced(
    scored: Scored, evaluate: Callable[[tuple[Candidate, ...]], Scored], added: Candidate
) -> Scored:
    """``scored`` without the projection effects that ``added`` has displaced.

    A projection effect of the model other than ``added`` that may no longer enter beside the
    rest (:func:`admissible` against the model without it) stood in for what ``added`` explains:
    blind seed 45 trial 69, a calibration file's wrong distortion, the search let a focal length
    of -0.01 % in beside exposure on the tag centres the distortion had moved; with the lens
    distortion beside it, its centres were no better than the lens's alone (p = 0.67) and its
    pose no closer, and it was still named. Effects are questioned in the model's order (the
    projection effects by name); each one that leaves is questioned no further.
    """
    for c, _ in scored.fits:
        if c is added or not isinstance(c, ProjectionCandidate):
            continue
        rest = evaluate(tuple(m for m, _ in scored.fits if m is not c))
        # a rest refitted onto a bound needs ``c`` to stay off it: not displaced
        if not at_bound(rest) and not admissible(scored, rest):
            return without_displaced(rest, evaluate, added)
    return scored


def corner_effect_alone(ranking: Sequence[Scored]) -> Scored | None:
    """The best corner-signature effect of ``ranking`` the corners single out (None: none).

    ``ranking``: single-effect models (:meth:`~simgap.analysis.selection.ModelSearch.rank`).
    For a capture where no evidence family differs significantly, or where the model search
    finds no effect to start from: only an effect with a corner signature of its own,
    admissible alone and seen in the held-out corners, is a finding (blind seed 46 trial 33: a
    D435-like lens, k1 fitted 0.074 for 0.082, seen at p = 0.0004 on 27 held-out items, lowered
    the evidence 1.80 -> 1.71 on a 9-item choose split: too little to start the search).
    """
    seen = [
        s
        for s in ranking
        if has_corner_signature(s.fits[0][0]) and admissible(s, None) and seen_in_corners(s, None)
    ]
    return min(seen, key=lambda s: s.evidence_after) if seen else None
