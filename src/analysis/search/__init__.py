"""The model search: which candidate effects explain a gap, scored on the choose split, and chosen.

``ModelSearch`` (``_selection``) fits models of one or more candidates, scores each on the evidence
of a set of items (``Scored``, ``_scored``) and chooses one by the decision rules of ``_scoring``:
an effect enters only where it may (``_admission``), two geometric effects at once where no single
one explains what the model leaves (``_pair_step``), corners cross-fitted in two folds
(``_cross_fit``), effects that move no pose pruned (``_pruning``), each effect's share of the pose
predictions (``_contributions``) and the calibration effects the corners single out
(``_corner_findings``). The candidates and the ``Runner`` come from
:mod:`simgap.analysis.candidates`, the items and their evidence channels from
:mod:`simgap.analysis.gap`.

The modules are private; other packages import the names of ``__all__`` from here.
"""

from __future__ import annotations

from simgap.analysis.search._admission import (
    admissible,
    at_bound,
    clearly_smaller,
    grows_with_size,
    seen_in_centres,
    seen_in_corners,
)
from simgap.analysis.search._corner_findings import (
    corner_effect_alone,
    corner_look_alikes,
    with_corner_effects,
    without_displaced,
)
from simgap.analysis.search._pruning import pruned
from simgap.analysis.search._scored import Scored, bootstrap_reductions
from simgap.analysis.search._scoring import (
    as_good,
    as_good_cross_fitted,
    corner_residuals,
    equivalent_models,
    generalises_better,
    improves_on_nothing,
    parsimonious,
    stands_in_for,
    worsens_pose,
)
from simgap.analysis.search._selection import ModelSearch

__all__ = [
    "ModelSearch",
    "Scored",
    "admissible",
    "as_good",
    "as_good_cross_fitted",
    "at_bound",
    "bootstrap_reductions",
    "clearly_smaller",
    "corner_effect_alone",
    "corner_look_alikes",
    "corner_residuals",
    "equivalent_models",
    "generalises_better",
    "grows_with_size",
    "improves_on_nothing",
    "parsimonious",
    "pruned",
    "seen_in_centres",
    "seen_in_corners",
    "stands_in_for",
    "with_corner_effects",
    "without_displaced",
    "worsens_pose",
]
