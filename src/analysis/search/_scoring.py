"""When one model explains the evidence better than another: the decision rules of the search.

A :class:`~simgap.analysis.search.Scored` model carries its misfit per evidence channel on the
items it was scored on (the choose split while models are searched). The rules here decide when
a model explains the evidence distinguishably better than another (:func:`improves`), when two
are equivalent, and which of several equivalent models is the simplest (:func:`parsimonious`);
:mod:`simgap.analysis.search._selection` searches with them. Their tolerances are
:mod:`simgap.analysis.thresholds`.
"""

from __future__ import annotations

import numpy as np

from simgap.analysis.candidates import ProjectionCandidate
from simgap.analysis.gap import clearly_lower, item_centre_residuals_px2, item_residuals_px2
from simgap.analysis.search._scored import Scored
from simgap.analysis.thresholds import EQUIVALENT_REL, EQUIVALENT_UNITS


def equivalent_models(a: Scored, b: Scored) -> bool:
    """Whether two models explain every evidence channel equally well.

    Per channel (corners, pose, detection, image statistics) neither misfit is lower than the
    other's beyond the tolerance (:func:`distinguishably_lower`: a quarter channel unit or 10 %
    of the smaller; for the corner channel 0.05 px or 10 %), and neither model has consistently
    better corners (:func:`corners_clearly_lower`).
    """
    return not (improves(a, b) or improves(b, a))


def stands_in_for(alternative: Scored, chosen: Scored) -> bool:
    """Whether ``alternative`` explains the evidence as well as ``chosen``: a look-alike.

    Equivalent on every channel of the choose split (:func:`equivalent_models`), and
    ``chosen``'s geometry does not predict the cross-fit folds' corners consistently better
    (:func:`generalises_better`): the tie the search breaks the same way
    (:func:`parsimonious`). A choose split of a few items ties a lens distortion with a focal
    length or a print scale whose cross-fitted corners are clearly worse on every item of both
    folds (measured on blind captures: docs/results/design_evidence.md#corner_findings).
    """
    return equivalent_models(alternative, chosen) and not generalises_better(chosen, alternative)


def distinguishably_lower(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether some channel misfit of ``a`` is lower than ``b``'s beyond the tolerance.

    Lower by more than :data:`~simgap.analysis.thresholds.EQUIVALENT_UNITS` channel units and
    :data:`~simgap.analysis.thresholds.EQUIVALENT_REL` of the
    smaller misfit (for the corner channel: 0.05 px and 10 %).
    """
    return bool(np.any(b - a > np.maximum(EQUIVALENT_UNITS, EQUIVALENT_REL * np.minimum(a, b))))


def corner_gap_lower(after_px: float, before_px: float, unit_px: float) -> bool:
    """Whether a corner gap ``after_px`` is below ``before_px`` beyond the corner tolerance.

    :func:`distinguishably_lower` on the corner channel alone, in units of ``unit_px`` (the
    capture's corner unit): a quarter unit and 10 %.
    """
    return distinguishably_lower(np.array([after_px / unit_px]), np.array([before_px / unit_px]))


def corner_residuals(
    scored: Scored, before: bool = False, cross_fitted: bool = False, centres: bool = False
) -> np.ndarray | None:
    """Per scored item, the mean squared corner distance real - predicted (px^2).

    The scored items, each predicted by the model fitted on the other split; with
    ``cross_fitted``, followed by the other split's items predicted by the model refitted on the
    scored ones (:attr:`~simgap.analysis.search.Scored.cross_fit_difference`; a ValueError for a
    model that was not cross-fitted): the two splits are then the two cross-fit folds, every item
    predicted by a fit on the other fold (two-fold cross-fitting).
    A choose split of 6-10 items alone could not show a lens distortion that moves the
    corners by a tenth of a pixel (the paired test missed correctly fitted lenses on blind
    captures: docs/results/design_evidence.md#scoring). Only the admission of a geometric effect
    (:func:`~simgap.analysis.search.seen_in_corners`,
    :func:`~simgap.analysis.search.seen_in_centres`) and ties between other geometries
    (:func:`generalises_better`) use the cross-fitted residuals: the model search's other
    comparisons keep the choose split (pooled, a tiny focal length joined a principal point on a
    development capture, its corners on the choose split worse; same page).

    With ``centres``, the squared distance of the tag centres (the mean of the four corners,
    :func:`~simgap.analysis.gap.item_centre_residuals_px2`) instead.
    """
    h = scored.items
    if h is None or scored.prediction is None:
        return None
    residuals = item_centre_residuals_px2 if centres else item_residuals_px2
    pred = h.sim_corners if before else scored.prediction.corners
    own = residuals(h.real_corners - pred)
    if not cross_fitted:
        return own
    cross = scored.cross_fit_difference_before if before else scored.cross_fit_difference
    if cross is None:  # two models compared on other items would be no paired test
        raise ValueError("corner_residuals: the model was not cross-fitted (ModelSearch.evaluate)")
    return np.concatenate([own, residuals(cross)])


def corners_clearly_lower(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Whether per-item corner residuals ``a`` are lower than ``b`` on the same items.

    :func:`simgap.analysis.gap.clearly_lower`: a consistent improvement over the items is
    evidence even when it is smaller than the fixed tolerance (a lens distortion moves the
    central tags' corners by tenths of a pixel).
    """
    if a is None or b is None:
        return False
    return clearly_lower(a, b)


def improves(a: Scored, b: Scored) -> bool:
    """Whether ``a`` explains some evidence channel distinguishably better than ``b``.

    Beyond the tolerance on some channel (:func:`distinguishably_lower`), or consistently
    better corners item by item (:func:`corners_clearly_lower`).
    """
    return distinguishably_lower(a.channels_after, b.channels_after) or corners_clearly_lower(
        corner_residuals(a), corner_residuals(b)
    )


def as_good(a: Scored, b: Scored) -> bool:
    """``a`` explains the evidence at least as well as ``b`` (or indistinguishably)."""
    return a.evidence_after <= b.evidence_after or equivalent_models(a, b)


def as_good_cross_fitted(a: Scored, b: Scored) -> bool:
    """:func:`as_good`, and ``b``'s geometry no better cross-fitted (:func:`generalises_better`).

    What a simpler model must be to replace ``b``
    (:meth:`~simgap.analysis.search.ModelSearch.simplify`): a tag offset that explained a
    choose split of six items as well as a camera mount replaced it by parsimony
    (measured on a blind capture: docs/results/design_evidence.md#scoring).
    """
    return as_good(a, b) and not generalises_better(b, a)


def parsimonious(options: list[Scored]) -> Scored:
    """The model with the fewest parameters among those as good as the best.

    Ties within :func:`equivalent_models` are not evidence: a richer effect (a 6-DOF camera
    mount) reproduces a simpler one (a principal-point shift is a small camera rotation) and also
    soaks up unrelated nuisance, so it wins by a hair unless parsimony decides. A tied model
    whose geometry another tied one predicts distinguishably better on the cross-fit folds
    (:func:`generalises_better`) is not tied.
    """
    best = min(options, key=lambda s: s.evidence_after)
    tied = [s for s in options if as_good(s, best)]
    tied = [s for s in tied if not any(generalises_better(o, s) for o in tied)] or tied
    return min(tied, key=lambda s: (s.n_params, s.evidence_after))


def worsens_pose(
    scored: Scored, reference: Scored | None = None, tolerance: float = EQUIVALENT_REL
) -> bool:
    """Whether ``scored`` leaves a larger pose gap than ``reference`` (or no effect).

    Larger by more than ``tolerance`` (relative; all axes,
    :attr:`~simgap.analysis.search.Scored.pose_gap_all_axes_after`). A geometric
    effect that does so, and that neither the cross-fitted corners nor the tag centres single out
    (:func:`~simgap.analysis.search._admission.admissible`), is no explanation of the gap: it is
    a look-alike absorbing an image effect outside the catalogue (motion blur shifts the corners
    the detector finds; a tag print scale follows them and moves every pose further away).
    """
    if reference is None:
        ref = scored.pose_gap_all_axes_before
    else:
        ref = reference.pose_gap_all_axes_after
    return bool(scored.pose_gap_all_axes_after > (1.0 + tolerance) * ref)


def improves_on_nothing(scored: Scored) -> bool:
    """Whether a model explains the evidence distinguishably better than no effect."""
    return scored.evidence_after < scored.evidence_before and (
        distinguishably_lower(scored.channels_after, scored.channels_before)
        or corners_clearly_lower(corner_residuals(scored), corner_residuals(scored, before=True))
    )


def generalises_better(a: Scored, b: Scored) -> bool:
    """Whether ``a``'s geometry predicts cross-fitted corners consistently better than ``b``'s.

    Two models with the same appearance effects and other projection effects, both
    cross-fitted: ``a``'s cross-fitted corner residuals are clearly lower item by item
    (:func:`corners_clearly_lower`). A choose split of a few items cannot tell a
    camera mount from a tag offset (their evidence tied and parsimony named the offset); the
    offset refitted on those few items did not predict the others, where the mount's did
    (measured on a blind capture: docs/results/design_evidence.md#scoring).
    """
    if _geometry(a) == _geometry(b) or _appearance(a) != _appearance(b):
        return False
    if a.cross_fit_difference is None or b.cross_fit_difference is None:
        return False
    return corners_clearly_lower(
        corner_residuals(a, cross_fitted=True), corner_residuals(b, cross_fitted=True)
    )


def _geometry(scored: Scored) -> set[str]:
    """The model's projection (geometric and calibration) effects."""
    return {c.effect for c, _ in scored.fits if isinstance(c, ProjectionCandidate)}


def _appearance(scored: Scored) -> set[str]:
    """The model's simulation (appearance) effects."""
    return set(scored.effects) - _geometry(scored)
