"""A step of two geometric effects at once, where no single one explains what the model leaves.

:meth:`simgap.analysis.search.ModelSearch.select` adds effects one at a time. Two geometric
effects that are in the capture together can hide each other from that search: each one alone
fails its admission test because the other one's share of the gap stays in the corners. A print
scale beside a carriage pitch: the print scale alone is refused because the carriage's depth
change, not in the model, leaves an edge offset against its size change
(:data:`~simgap.analysis.thresholds.SIZE_ZERO_SHARE`), and the carriage pitch alone moves the
poses away; with both, the size change stands out and the pose gap closes. A print scale beside a
turntable offset: the offset alone barely moves the pose gap, the print scale's size change does
not stand out beside the rotation, and a look-alike enters instead (its model then refused).
Measured on blind captures where both pairs went unnamed
(docs/results/design_evidence.md#pair_step).

So where the greedy step finds nothing and the model leaves the geometry unexplained
(:func:`geometry_unexplained`), pairs of projection effects are tried as one step, under the same
admission (:func:`~simgap.analysis.search._admission.admissible`, every new effect tested) and gain
rules as single ones. Only projection effects: their joint fit is on the corners alone (no render).
"""

from __future__ import annotations

from itertools import combinations
from typing import Protocol

import numpy as np

from simgap.analysis.candidates import Candidate, ProjectionCandidate
from simgap.analysis.search._admission import admissible
from simgap.analysis.search._scored import Scored
from simgap.analysis.search._scoring import parsimonious
from simgap.analysis.thresholds import EXPLAINED_REDUCTION, GEOMETRY_CORNER_GAP_PX


class Search(Protocol):
    """What a pair step needs of :class:`~simgap.analysis.search.ModelSearch`."""

    significant_axes: np.ndarray

    def evaluate(self, model: tuple[Candidate, ...]) -> Scored:
        """Fit a model and score it (memoised)."""
        ...


def geometry_unexplained(
    corner_gap_px: float, pose_gap_reduction: float, significant_axes: np.ndarray
) -> bool:
    """Whether a model that leaves these gaps leaves the geometry unexplained.

    Its corners stay more than :data:`~simgap.analysis.thresholds.GEOMETRY_CORNER_GAP_PX` off
    (what :meth:`~simgap.analysis.search.ModelSearch.select` refuses in a model with
    geometry), or a significant pose gap falls by less than
    :data:`~simgap.analysis.thresholds.EXPLAINED_REDUCTION` (what the diagnosis reports as an
    unexplained pose gap).

    Parameters
    ----------
    corner_gap_px : float
        The corner gap the model leaves (px, RMS over the choose split's items).
    pose_gap_reduction : float
        Share of the pose gap it explains (0: none).
    significant_axes : ndarray of bool (6,)
        Axes with a significant pose gap.
    """
    if corner_gap_px > GEOMETRY_CORNER_GAP_PX:
        return True
    return bool(np.any(significant_axes)) and pose_gap_reduction < EXPLAINED_REDUCTION


def pair_step(
    current: Scored, pool: list[Candidate], search: Search, max_effects: int
) -> Scored | None:
    """The best model of ``current`` with two more projection effects, where it needs them.

    None unless ``current`` leaves the geometry unexplained (:func:`geometry_unexplained`) and
    some pair may enter (:func:`pair_options`); the caller applies the gain rule.
    """
    if not geometry_unexplained(
        current.corner_gap_after_px, current.pose_gap_reduction, search.significant_axes
    ):
        return None
    options = pair_options(current, pool, search, max_effects)
    return parsimonious(options) if options else None


def pair_start(
    ranking: list[Scored], pool: list[Candidate], search: Search, max_effects: int
) -> list[Scored]:
    """Where no single effect starts the search: the best pair of projection effects, if any.

    Tried where the gaps without any effect (``ranking[0]``'s before values) leave the geometry
    unexplained (:func:`geometry_unexplained`); a list of at most one start.
    """
    if not ranking or not geometry_unexplained(
        ranking[0].corner_gap_before_px, 0.0, search.significant_axes
    ):
        return []
    options = pair_options(None, pool, search, max_effects)
    return [parsimonious(options)] if options else []


def pair_options(
    current: Scored | None, pool: list[Candidate], search: Search, max_effects: int
) -> list[Scored]:
    """Models of ``current`` (or of nothing) with two more projection effects that may enter.

    Each pair from ``pool`` is fitted jointly with the model's projection effects
    (:meth:`~simgap.analysis.search.ModelSearch.evaluate`); a pair is kept when it is
    :func:`~simgap.analysis.search._admission.admissible` beside ``current``. Empty when the model
    has no room for two more effects, or ``pool`` no two projection effects (a search without
    geometry).
    """
    model = () if current is None else tuple(c for c, _ in current.fits)
    if len(model) + 2 > max_effects:
        return []
    free = [c for c in pool if isinstance(c, ProjectionCandidate) and c not in model]
    options = []
    for a, b in combinations(free, 2):
        option = search.evaluate(model + (a, b))
        if admissible(option, current):
            options.append(option)
    return options
