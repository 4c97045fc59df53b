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

The other way round, a minor geometric or calibration finding that the corners do not single
out from another projection effect in its place is left undecided between them
(:func:`corner_look_alikes`).
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
from simgap.analysis.search._scoring import stands_in_for


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


def stands_in_corners(candidate: Candidate) -> bool:
    """Whether a candidate may stand in for a minor projection effect: it moves the corners.

    The projection effects, and the camera's own effects whose evidence is the corners
    (``moves_corners``: the pipeline's edge offset, which moves every marker's corners by the
    same pixels, :class:`~simgap.analysis.candidates.EdgeOffsetCandidate`).
    """
    return isinstance(candidate, ProjectionCandidate) or bool(
        getattr(candidate, "moves_corners", False)
    )


def corner_look_alikes(
    scored: Scored,
    minor: Sequence[str],
    pool: Sequence[Candidate],
    evaluate: Callable[[tuple[Candidate, ...]], Scored],
) -> dict[str, tuple[str, ...]]:
    """Per minor projection effect of ``scored``: the effects as good in its place.

    A projection effect that moves no pose beyond the floor (``minor``) is seen in the corners
    alone, and is a finding only where the corners single it out. Where another projection
    effect of ``pool`` in its place explains every evidence channel indistinguishably from
    ``scored`` (:func:`~simgap.analysis.search.stands_in_for`: the search's own tolerances,
    0.05 px or 10 % on the corners and no consistent item-by-item difference, on the choose
    split and, for the geometry, on both cross-fit folds), and could enter
    the rest of the model on its own (:func:`admissible`, which also keeps it off its bounds
    and asks every fit there, the camera's own edge offset's included
    (:func:`stands_in_corners`), to explain its own evidence),
    the corners do not single the effect out: the capture's poses cannot tell the two apart (a
    calibration file's wrong distortion and a focal length of a tenth of a percent, both
    lowering the corners of central tags alike, seen on a blind capture:
    docs/results/design_evidence.md#corner_findings).

    Returns
    -------
    dict of str to tuple of str
        For each minor projection effect with look-alikes, their effect names (in ``pool``'s
        order); effects without any are left out.
    """
    model = tuple(c for c, _ in scored.fits)
    out: dict[str, tuple[str, ...]] = {}
    for member in model:
        if member.effect not in minor or not isinstance(member, ProjectionCandidate):
            continue
        rest = tuple(c for c in model if c is not member)
        reference = evaluate(rest) if rest else None
        alikes = tuple(
            alt.effect
            for alt in pool
            if stands_in_corners(alt)
            and alt not in model
            and admissible(swapped := evaluate((*rest, alt)), reference)
            and stands_in_for(swapped, scored)
        )
        if alikes:
            out[member.effect] = alikes
    return out
