"""How much each effect of a model moves the model's pose predictions, the others held fixed.

An effect of a model whose contribution is below
:data:`~simgap.analysis.thresholds.MINOR_CONTRIBUTION` moves no pose by a relevant amount: the
search prunes it when the model without it explains the evidence as well, and otherwise reports it
as *minor* (:class:`simgap.analysis.search.ModelSearch`).
"""

from __future__ import annotations

import numpy as np

from simgap.analysis.candidates import Fit, ProjectionSet
from simgap.analysis.search._scored import Scored
from simgap.core.rig import Rig
from simgap.effects.state import VariantState


def member_deltas(scored: Scored, rig: Rig, base: VariantState) -> dict[str, np.ndarray]:
    """Change of error (N, 6) of the scored items due to each effect, the others held fixed.

    For a projection effect: the model's projection prediction minus the same prediction with
    that effect's parameters set to zero (no refit). For a simulation effect: its own change of
    error (m, rad).
    """
    out = dict(scored.simulation_deltas)
    if scored.projection is None:
        return out
    joint, fit, shifted = scored.projection
    full = np.nan_to_num(joint.delta(rig, base, fit, shifted))
    members = joint.members if isinstance(joint, ProjectionSet) else [joint]
    if len(members) == 1:
        out[members[0].effect] = full
        return out
    cuts = np.cumsum([m.n_params for m in members])[:-1]
    for k, (m, xm) in enumerate(zip(members, np.split(fit.extra["x"], cuts), strict=True)):
        x = fit.extra["x"].copy()
        start = 0 if k == 0 else cuts[k - 1]
        x[start : start + len(xm)] = 0.0
        without = Fit(fit.effect, fit.params, fit.seconds, {"x": x})
        out[m.effect] = full - np.nan_to_num(joint.delta(rig, base, without, shifted))
    return out


def pose_contributions(
    scored: Scored, rig: Rig, base: VariantState, significant_axes: np.ndarray
) -> dict[str, float]:
    """How much each effect of a model moves its pose predictions (dimensionless), by effect.

    Per effect: the change of the model's pose predictions on the scored items that this effect
    makes with the others held at their fitted values (:func:`member_deltas`, no refit: a refit
    would let a look-alike take over its share and make both look irrelevant); per axis the
    median over items of the absolute change over the item's noise (or the practical floor, the
    larger), the largest over ``significant_axes`` (bool (6,); all axes when none is).
    """
    axes = significant_axes if np.any(significant_axes) else np.ones(6, bool)
    return {
        effect: float(
            np.max(np.nanmedian(np.abs(d) / scored.items_and_prediction()[0].scale, axis=0)[axes])
        )
        for effect, d in member_deltas(scored, rig, base).items()
    }
