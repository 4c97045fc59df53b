"""Calibration effects the corners single out: beside a chosen model, or alone.

An effect with a corner signature of its own (a lens distortion: a radial pattern no pose,
exposure or softness change makes) is a finding wherever the cross-fitted corners single it out
(:func:`~simgap.analysis.search.seen_in_corners`), even when it moves no pose beyond the floor
(it is then minor, never silently dropped). The greedy search of
:meth:`simgap.analysis.search.ModelSearch.select` adds the effect that lowers the combined
misfit most, so a distortion that lowers only the corners can be crowded out by appearance
effects that lower the image statistics more and are then pruned (a calibration file's
distortion answered by exposure alone, although exposure + lens distortion was admissible and
lowered the corner gap). And where no evidence family differs significantly, a wrong distortion
in the calibration file that moves no pose significantly would never be looked for. Both seen on
blind captures: docs/results/design_evidence.md#corner_findings.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from simgap.analysis.candidates import Candidate, ProjectionCandidate
from simgap.analysis.search._admission import (
    admissible,
    at_bound,
    has_corner_signature,
    seen_in_corners,
)
from simgap.analysis.search._scored import Scored


def with_corner_effects(
    scored: Scored,
    pool: Sequence[Candidate],
    evaluate: Callable[[tuple[Candidate, ...]], Scored],
    max_effects: int,
) -> Scored:
    """``scored`` with every corner-signature effect of ``pool`` the corners single out beside it.

    One at a time, the one whose model explains the evidence best first, while the model may
    grow (``max_effects``): the effect may enter beside the model (:func:`admissible`) and
    the cross-fitted corners single it out (:func:`seen_in_corners`). A geometric effect of the
    model that could no longer enter beside it leaves (:func:`without_displaced`).
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
    rest (:func:`admissible` against the model without it) stood in for what ``added`` explains
    (a focal length let in on the tag centres a calibration file's wrong distortion had moved:
    beside the lens distortion its centres were no better than the lens's alone and its pose no
    closer, and it was still named; docs/results/design_evidence.md#corner_findings). Effects
    are questioned in the model's order (the projection effects by name); each one that leaves
    is questioned no further.
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

    ``ranking``: single-effect models (:meth:`~simgap.analysis.search.ModelSearch.rank`).
    For a capture where no evidence family differs significantly, or where the model search
    finds no effect to start from: only an effect with a corner signature of its own,
    admissible alone and seen in the cross-fitted corners, is a finding: a true lens can be seen
    clearly in the cross-fitted corners yet lower the evidence of a small choose split too little to
    start the search (docs/results/design_evidence.md#corner_findings).
    """
    seen = [
        s
        for s in ranking
        if has_corner_signature(s.fits[0][0]) and admissible(s, None) and seen_in_corners(s, None)
    ]
    return min(seen, key=lambda s: s.evidence_after) if seen else None
