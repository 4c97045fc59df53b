"""Pruning a chosen model: effects that move no pose by a relevant amount leave it.

:meth:`simgap.analysis.search.ModelSearch.select` grows a model greedily; once it stops, every
effect whose pose contribution (:meth:`~simgap.analysis.search.ModelSearch.contributions`) is
below :data:`~simgap.analysis.thresholds.MINOR_CONTRIBUTION` is questioned here.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from simgap.analysis.candidates import Candidate, ProjectionCandidate
from simgap.analysis.gap import corner_score
from simgap.analysis.search._scored import Scored
from simgap.analysis.search._scoring import as_good, corner_gap_lower
from simgap.analysis.thresholds import MINOR_CONTRIBUTION, MINOR_CORNER_SHIFT_PX
from simgap.effects import EFFECTS


def pruned(
    scored: Scored,
    evaluate: Callable[[tuple[Candidate, ...]], Scored],
    contributions: Callable[[Scored], dict[str, float]],
) -> Scored:
    """``scored`` without the effects that move no pose beyond the floor and are not clearly seen.

    A change of the fixture's transform tree (an effect of the ``geometry`` stage: camera mount,
    turntable offset, carriage pitch, tag offset) that moves no pose beyond the floor is dropped
    first unless the corners without it are worse beyond the corner channel's tolerance
    (:func:`~simgap.analysis.search._scoring.corner_gap_lower`). The item-by-item paired test and
    the other channels do not keep it:
    such a change moves the tag rigidly against the camera, and a consistent corner improvement
    of a few hundredths of a pixel beside an appearance effect is what the modelled appearance
    leaves of another camera's image formation. Measured on validation captures: every such
    minor finding was an effect not in the capture (its corners, where measured, a few hundredths
    of a pixel better), while true carriage pitches that were minor beside the camera's blur (the
    poses of a one-frame capture noisy) lowered the corners by half or more alone. The camera's
    intrinsics are not questioned so: a focal length the capture's calibration file knows moves
    the corners and no pose (a true one beside a camera mount: pose contribution 0.01, corners a
    quarter lower). Measurements: docs/results/design_evidence.md#pruning.

    Next, a projection effect (geometry or calibration) that moves no pose beyond the floor is
    dropped where it moves the predicted corners by less than
    :data:`~simgap.analysis.thresholds.MINOR_CORNER_SHIFT_PX` (:func:`corner_shift_px`): the
    detector's own corner bias, which another camera's image formation changes by as much, so
    the corners cannot single such an effect out (a principal point of a tenth of a pixel is
    no calibration finding, however consistently it lowers the corner gap).

    Any other effect below :data:`~simgap.analysis.thresholds.MINOR_CONTRIBUTION` is dropped only
    when the model without it still explains the evidence as well (:func:`as_good`); otherwise
    it stays as a *minor* effect (seen in the corners or images, no pose impact beyond the floor).
    Comparing the evidence, never letting the pose criterion alone swap the explanation, is what
    keeps a refitted look-alike (a tag print scale soaking up a focal-length change) from
    replacing the effect that the corners single out.

    Parameters
    ----------
    scored : Scored
        The chosen model.
    evaluate : callable
        Fits and scores a model of candidates (memoised by the search).
    contributions : callable
        A model's pose contribution per effect (units of the floor).
    """
    while len(scored.fits) > 1:
        weight = contributions(scored)
        # the model without each projection effect that moves no pose beyond the floor
        without = {
            c.effect: evaluate(tuple(m for m, _ in scored.fits if m is not c))
            for c, _ in scored.fits
            if isinstance(c, ProjectionCandidate) and weight[c.effect] < MINOR_CONTRIBUTION
        }
        after, unit = scored.corner_gap_after_px, scored.corner_unit_px
        unseen = [
            e
            for e, r in without.items()
            if EFFECTS[e].stage == "geometry"
            and not corner_gap_lower(after, r.corner_gap_after_px, unit)
        ]
        faint = [
            e for e, r in without.items() if corner_shift_px(scored, r) < MINOR_CORNER_SHIFT_PX
        ]
        dropped = unseen or faint  # the rigid changes' own rule first
        if dropped:
            scored = without[min(dropped, key=weight.__getitem__)]
            continue
        options = []
        for effect in (e for e, w in weight.items() if w < MINOR_CONTRIBUTION):
            reduced = evaluate(tuple(c for c, _ in scored.fits if c.effect != effect))
            if as_good(reduced, scored):
                options.append(reduced)
        if not options:
            return scored
        scored = min(options, key=lambda o: o.evidence_after)
    return scored


def corner_shift_px(a: Scored, b: Scored) -> float:
    """How far two models' predicted corners lie apart on the same items (px).

    The robust RMS distance (:func:`~simgap.analysis.gap.corner_score`) between the corners of
    ``a``'s and ``b``'s predictions; infinite where either carries none (nothing to compare,
    nothing dropped for it).
    """
    if a.prediction is None or b.prediction is None:
        return float("inf")
    shift = corner_score(a.prediction.corners, b.prediction.corners)
    return float(shift) if np.isfinite(shift) else float("inf")
