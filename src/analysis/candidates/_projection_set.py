"""Several projection effects fitted jointly: :class:`ProjectionSet`."""

from __future__ import annotations

from typing import Any

import numpy as np

from simgap.analysis.candidates._fitting import Fit, ProjectionCandidate, on_bound
from simgap.effects.state import VariantState


class ProjectionSet(ProjectionCandidate):
    """Several projection effects fitted jointly (their parameters at once, on the same corners).

    Effects that move the corners in similar ways (a principal-point shift and a small camera
    rotation, a focal change and a camera moved along its axis) cannot be told apart when fitted
    one after the other: the first absorbs part of the second. Fitting them together lets each
    take its own share.

    Parameters
    ----------
    members : list of ProjectionCandidate
        The effects, applied in this order.
    """

    def __init__(self, members: list[ProjectionCandidate]) -> None:
        self.members = list(members)
        self.corner_signature = False
        self.effect = "+".join(m.effect for m in self.members)
        self.names = [f"{m.effect}.{n}" for m in self.members for n in m.names]
        self.x_scale = np.concatenate([m.x_scale for m in self.members])
        self.bound = np.concatenate([m.bound for m in self.members])
        self.x0 = np.zeros(len(self.names))
        self._cuts = np.cumsum([m.n_params for m in self.members])[:-1]

    def low_order(self) -> np.ndarray:
        """The members' nested first parameters, side by side (bool (n_params,))."""
        return np.concatenate([m.low_order() for m in self.members])

    def effect_params(self, x: np.ndarray) -> dict[str, Any]:
        """Effect parameter mappings, one per member effect."""
        return {
            m.effect: m.effect_params(xm)
            for m, xm in zip(self.members, np.split(x, self._cuts), strict=True)
        }

    def _state(self, base: VariantState, x: np.ndarray) -> VariantState:
        for m, xm in zip(self.members, np.split(x, self._cuts), strict=True):
            base = m._state(base, xm)
        return base

    def without(self, x: np.ndarray, effect: str) -> np.ndarray:
        """The parameter vector ``x`` with member ``effect``'s parameters set to zero."""
        parts = np.split(np.array(x, float), self._cuts)
        return np.concatenate(
            [m.without(xm, effect) for m, xm in zip(self.members, parts, strict=True)]
        )

    def parts(self) -> tuple[ProjectionCandidate, ...]:
        """The member effects, in order."""
        return tuple(self.members)

    def member_fits(self, fit: Fit) -> list[Fit]:
        """The joint fit split into one :class:`Fit` per member (same order)."""
        out = []
        for m, xm in zip(self.members, np.split(fit.extra["x"], self._cuts), strict=True):
            at_bound = tuple(
                n for n, v, b in zip(m.names, xm, m.bound, strict=True) if on_bound(v, -b, b)
            )
            extra = {"x": xm, "at_bound": at_bound, "size_changes": fit.extra["size_changes"]}
            out.append(Fit(m.effect, m.effect_params(xm), fit.seconds, extra))
        return out
