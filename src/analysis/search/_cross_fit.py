"""Two-fold cross-fitting of a model's corners: each fold predicted by a fit on the other.

Models are fitted on the fit split and scored on the choose split
(:mod:`simgap.analysis.search._selection`). For the corner evidence the folds are also swapped: the
model's projection effects are refitted on the choose split and predict the corners of the fit
split's items that the simulation effects were fitted on (its subsample, ``sim_fit_index``: rendered
already), so that the paired corner tests (:func:`simgap.analysis.search.corner_residuals`, on
the corners or on the tag centres) see every such item predicted by geometry that did not fit
it. The simulation (appearance) effects are not refitted: their fits were made on the fit split's
image statistics, not on corners.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from simgap.analysis.candidates import ProjectionCandidate
from simgap.analysis.gap import Items
from simgap.analysis.search._scored import Scored
from simgap.core.rig import Rig
from simgap.effects.state import VariantState

if TYPE_CHECKING:
    from simgap.analysis.candidates import SimulationChain


def cross_fit_difference(
    scored: Scored, rig: Rig, base: VariantState, chain: SimulationChain, fit_items: Items
) -> np.ndarray:
    """Corners of ``fit_items``, real - predicted (N, 4, 2) (px), by ``scored`` refitted on its own.

    The model's joint projection effect (``scored.projection``: the candidate, and the scored
    items with the simulation effects' corner changes it was applied to) is refitted on those
    items, on top of the simulation effects (as
    :meth:`~simgap.analysis.search.ModelSearch.evaluate` fits it on the fit split), and
    predicts the corners of ``fit_items``. The simulation effects keep their fits (made on image
    statistics, not on corners).
    """
    simulation = [(c, f) for c, f in scored.fits if not isinstance(c, ProjectionCandidate)]
    predicted = fit_items.sim_corners + chain.changes(simulation, fit_items)[0]
    if scored.projection is not None:
        joint, _, shifted = scored.projection
        refit = joint.fit(rig, base, shifted)
        shift = joint.corner_shift(rig, base, refit.extra["x"], fit_items)
        predicted = predicted + np.nan_to_num(shift)
    return fit_items.real_corners - predicted


def cross_fitted(scored: Scored, rig: Rig, base: VariantState, chain: SimulationChain) -> Scored:
    """``scored`` (scored on its own items, the choose split) with the other fold added.

    The other fold is the items the simulation effects were fitted on (``chain.items``, the fit
    split's subsample: already rendered with them). Sets
    :attr:`~simgap.analysis.search.Scored.cross_fit_difference` (:func:`cross_fit_difference`)
    and the simulation's own corner differences on those items.
    """
    fit_items = chain.items
    return dataclasses.replace(
        scored,
        cross_fit_difference=cross_fit_difference(scored, rig, base, chain, fit_items),
        cross_fit_difference_before=fit_items.real_corners - fit_items.sim_corners,
    )
