"""Whether an effect may enter a model: off its bounds; pose, corners or centres show it."""

from __future__ import annotations

import numpy as np

from simgap.analysis.candidates import Candidate, Fit, ProjectionCandidate
from simgap.analysis.search._scored import Scored
from simgap.analysis.search._scoring import (
    corner_gap_lower,
    corner_residuals,
    corners_clearly_lower,
    distinguishably_lower,
    worsens_pose,
)
from simgap.analysis.thresholds import (
    EQUIVALENT_REL,
    MIN_POSE_REDUCTION,
    SIZE_SLOPE_Z,
    SIZE_ZERO_SHARE,
)


def admissible(scored: Scored, reference: Scored | None) -> bool:
    """Whether the effect ``scored`` adds to ``reference`` (or to no effect) may enter a model.

    No fitted parameter on its bound (:func:`at_bound`: a joint refit that pushes one there is
    a proxy too); every effect's fit explains its own evidence beside the model's others
    (``supported``, as :meth:`~simgap.analysis.search.ModelSearch.rank` asks of every effect
    alone; an effect fitted after one that enters is fitted again: a laminate refitted beside
    an exposure found no light to mirror and was named on a blind capture,
    docs/results/design_evidence.md#admission); a new print-scale-like effect changes the
    tags' size in proportion to it (:func:`grows_with_size`); and a geometric effect must
    bring the pose :data:`~simgap.analysis.thresholds.MIN_POSE_REDUCTION` closer to the real
    one (:func:`~simgap.analysis.search.worsens_pose`), have its own pattern in the corners
    (:func:`seen_in_corners`) or move the tag centres as they moved (:func:`seen_in_centres`).
    Appearance effects are judged on their evidence alone.
    """
    if at_bound(scored):
        return False
    new = new_effects(scored, reference)
    if not all(f.extra.get("supported", True) for _, f in scored.fits):
        return False
    if not all(grows_with_size(f) for c, f in scored.fits if c in new):
        return False
    if not any(isinstance(c, ProjectionCandidate) for c in new):
        return True
    return (
        not worsens_pose(scored, reference, tolerance=-MIN_POSE_REDUCTION)
        or seen_in_corners(scored, reference)
        or seen_in_centres(scored, reference)
    )


def grows_with_size(fit: Fit) -> bool:
    """Whether a print-scale-like effect's corners change in size in proportion to the tag size.

    For a candidate with a size signature (``Fit.extra["size_changes"]``, set by
    :meth:`simgap.analysis.candidates.ProjectionCandidate.fit` on the fit split): the size change it
    has to explain grows with the tag's image size by at least
    :data:`~simgap.analysis.thresholds.SIZE_SLOPE_Z` standard errors, and an edge offset of the
    other sign does not cancel it before :data:`~simgap.analysis.thresholds.SIZE_ZERO_SHARE` of
    the smallest tag's size (:mod:`simgap.analysis.candidates._size_signature`). Other effects, and
    fits on too few tags to test, pass.
    """
    change = fit.extra.get("size_changes", {}).get(fit.effect)
    if change is None or not np.isfinite(change.slope_z):
        return True
    return abs(change.slope_z) >= SIZE_SLOPE_Z and not change.zero_share >= SIZE_ZERO_SHARE


def at_bound(scored: Scored) -> bool:
    """Whether some fitted parameter of a model lies on the end of its searched range.

    (``Fit.extra["at_bound"]``, :func:`simgap.analysis.candidates.on_bound`.) The fit wanted to
    go further than the effect's plausible range: the model stands in for something it cannot
    express, so it is not offered as a finding.
    """
    return any(fit.extra.get("at_bound") for _, fit in scored.fits)


def has_corner_signature(candidate: object) -> bool:
    """Whether a candidate's corners have a pattern of their own (``corner_signature``)."""
    return bool(getattr(candidate, "corner_signature", False))


def new_effects(scored: Scored, reference: Scored | None) -> list[Candidate]:
    """The candidates of ``scored`` that ``reference`` lacks (all of them without a reference)."""
    return [c for c, _ in scored.fits if reference is None or c.effect not in reference.effects]


def residuals_without(
    scored: Scored, reference: Scored | None, centres: bool = False
) -> np.ndarray | None:
    """Cross-fitted residuals (px^2) of the model ``scored`` is compared with.

    ``reference``'s with its effects, or, without a reference, the simulation's alone on
    ``scored``'s items (:func:`~simgap.analysis.search.corner_residuals`; of the tag centres
    with ``centres``).
    """
    if reference is None:
        return corner_residuals(scored, before=True, cross_fitted=True, centres=centres)
    return corner_residuals(reference, cross_fitted=True, centres=centres)


def seen_in_centres(scored: Scored, reference: Scored | None) -> bool:
    """Whether a model's one new geometric effect moves the tag centres as they moved.

    The cross-fitted centre residuals (the mean of each tag's four corners, every searched item
    predicted by a fit on the other cross-fit fold: :func:`~simgap.analysis.search.corner_residuals`
    with ``centres``) of ``scored`` are consistently lower item by item than ``reference``'s (or the
    simulation's) (:func:`~simgap.analysis.search._scoring.corners_clearly_lower`).

    Why the pose does not decide here: a single tag's depth comes from its apparent size, and
    a camera whose edges differ from the simulation's (exposure, softness) moves every side of
    the tag in or out and so the depth; the centre is the mean of the four corners and stays
    where the geometry put it. Measured on development captures: true carriage pitches, fitted
    right, lowered the median centre residual by 75-99 % (p <= 1e-4) while raising the pose
    gap; beside motion blur or on a capture with no effect no geometric candidate lowered the
    centres (p >= 0.09). A print scale moves a centre only by its perspective (a hair), so it
    does not enter this way (docs/results/design_evidence.md#admission).
    """
    new = new_effects(scored, reference)
    if len(new) != 1 or not isinstance(new[0], ProjectionCandidate):
        return False
    after = corner_residuals(scored, cross_fitted=True, centres=True)
    return corners_clearly_lower(after, residuals_without(scored, reference, centres=True))


def clearly_smaller(after: np.ndarray | None, before: np.ndarray | None) -> bool:
    """Whether per-item corner residuals (px^2) fall by the corner channel's relative tolerance.

    The RMS over the items falls by at least :data:`~simgap.analysis.thresholds.EQUIVALENT_REL`
    (the relative part of every channel's tolerance): a consistent improvement smaller than
    that is what a camera's unmodelled image formation (a softer edge, a tone curve, a darker
    print) leaves in the corners, not a lens.
    """
    if after is None or before is None or not np.isfinite(after).any():
        return False
    rms_after = float(np.sqrt(np.nanmean(after)))
    rms_before = float(np.sqrt(np.nanmean(before)))
    return rms_after <= (1.0 - EQUIVALENT_REL) * rms_before


def seen_in_corners(scored: Scored, reference: Scored | None) -> bool:
    """Whether a model's newest effect has a corner signature of its own and the corners show it.

    The effect of ``scored`` that ``reference`` lacks (its only one without a reference) has a
    corner signature (:attr:`~simgap.analysis.candidates.ProjectionCandidate.corner_signature`);
    its corners are distinguishably better than ``reference``'s (or than no effect): the corner
    channel beyond its tolerance (:func:`~simgap.analysis.search._scoring.distinguishably_lower`) or
    item by item over both folds of a cross-fit
    (:func:`~simgap.analysis.search._scoring.corners_clearly_lower`,
    :func:`~simgap.analysis.search.corner_residuals`) by at least the channel's relative
    tolerance (:func:`clearly_smaller`); and the pose gap is not
    distinguishably larger, by the tolerance of every channel
    (:func:`~simgap.analysis.search._scoring.distinguishably_lower` on the pose channel: a quarter
    unit and 10 %). Within its noise the pose gap tells nothing either way: a lens distortion whose
    poses lie within their noise on both sides scored 0.649 -> 0.664, pure noise ~0.67; a true
    lens that lowered the corner gap by a third was rejected under a 10 % pose rule on a blind
    capture (docs/results/design_evidence.md#admission). Such an effect is a finding even when
    it moves no pose beyond the floor: it is then reported as minor.
    """
    new = new_effects(scored, reference)
    if len(new) != 1 or not has_corner_signature(new[0]):
        return False
    before_px = scored.corner_gap_before_px if reference is None else reference.corner_gap_after_px
    after, without = (
        corner_residuals(scored, cross_fitted=True),
        residuals_without(scored, reference),
    )
    lower = corner_gap_lower(scored.corner_gap_after_px, before_px, scored.corner_unit_px) or (
        corners_clearly_lower(after, without) and clearly_smaller(after, without)
    )
    pose_before = (
        scored.pose_gap_all_axes_before if reference is None else reference.pose_gap_all_axes_after
    )
    pose_after = scored.pose_gap_all_axes_after
    pose_worse = distinguishably_lower(np.array([pose_before]), np.array([pose_after]))
    return lower and not pose_worse
