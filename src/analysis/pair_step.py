"""A step of two geometric effects at once, where no single one explains what the model leaves.

:meth:`simgap.analysis.selection.ModelSearch.select` adds effects one at a time. Two geometric
effects that are in the capture together can hide each other from that search: each one alone
fails its admission test because the other one's share of the gap stays in the corners. Blind
seed 42 (80 trials, code a77e9e0), both pairs with a print scale:

- trial 51, print scale -1.5 % beside a carriage pitch of -1.3 %: the print scale alone was refused
  because the carriage's depth change, not in the model, left an edge offset against its size
  change (zero at 0.58 of the smallest tag's size, :data:`~simgap.analysis.thresholds.
  SIZE_ZERO_SHARE` 0.5); the carriage pitch alone moved the poses away. With both, the size
  change stood 11.7 standard errors out and crossed zero at 0.26; the diagnosis named only the
  camera's exposure and left a pose gap of 3.8 units.
- trial 70, print scale -2.1 % beside a turntable offset of -21 mrad: the turntable offset alone
  moved the pose gap (dominated by the print's ty) by 2 %; the print scale's size change was 2.8
  standard errors out beside the rotation. A carriage pitch, a look-alike of the print, entered
  instead; its model left the corners 1.25 px off and was refused. Both together: 9.8 standard
  errors, pose gap 3.71 -> 0.47, corners 0.29 px.

So where the greedy step finds nothing and the model leaves the geometry unexplained
(:func:`geometry_unexplained`), pairs of projection effects are tried as one step, under the same
admission (:func:`~simgap.analysis.admission.admissible`, every new effect tested) and gain rules
as single ones. Only projection effects: their joint fit is on the corners alone (no render).
"""

from __future__ import annotations

from itertools import combinations
from typing import Protocol

import numpy as np

from simgap.analysis.admission import admissible
from simgap.analysis.fitting import Candidate, ProjectionCandidate
from simgap.analysis.scored import Scored
from simgap.analysis.scoring import parsimonious
from simgap.analysis.thresholds import EXPLAINED_REDUCTION, GEOMETRY_CORNER_GAP_PX


class Search(Protocol):
    """What a pair step needs of :class:`~simgap.analysis.selection.ModelSearch`."""

    significant_axes: np.ndarray

    def evaluate(self, model: tuple[Candidate, ...]) -> Scored:
        """Fit a model and score it (memoised)."""
        ...


def geometry_unexplained(
    corner_gap_px: float, pose_gap_reduction: float, significant_axes: np.ndarray
) -> bool:
    """Whether a model that leaves these gaps leaves the geometry unexplained.

    Its corners stay more than :data:`~simgap.analysis.thresholds.GEOMETRY_CORNER_GAP_PX` off
    (what :meth:`~simgap.analysis.selection.ModelSearch.select` refuses in a model with
    geometry), or a significant pose gap falls by less than
    :data:`~simgap.analysis.thresholds.EXPLAINED_REDUCTION` (what the diagnosis reports as an
    unexplained pose gap).

    Parameters
    ----------
    corner_gap_px : float
        The corner gap the model leaves (px, RMS over the choose split's configurations).
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
    (:meth:`~simgap.analysis.selection.ModelSearch.evaluate`); a pair is kept when it is
    :func:`~simgap.analysis.admission.admissible` beside ``current``. Empty when the model has
    no room for two more effects, or ``pool`` no two projection effects (a search without
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
