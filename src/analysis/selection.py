"""Which effects explain a gap: fit models of one or more effects, score them held out, choose.

A *model* is a set of catalogue effects. Projection effects in a model are fitted jointly on the
training corners; simulation effects one by one on top. Every model is scored on held-out
configurations by the residual of the detected corners (px) and by the pose gap. The search
ranks single effects, then adds effects greedily while the held-out corner residual falls, and
after every step simplifies the model: effects are dropped or swapped for ones with fewer
parameters while the residual stays *equivalent* (the data cannot tell the models apart, so the
simpler explanation is reported and the others are listed).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simgap.analysis.fitting import (
    Fit,
    Items,
    ProjectionCandidate,
    ProjectionSet,
    corner_score,
    gap_rms_per_axis,
    gap_score,
)
from simgap.analysis.gap import AXES
from simgap.effects import make_effect
from simgap.effects.state import VariantState
from simgap.rig import Rig


@dataclass
class Scored:
    """A model (one or more fitted effects) and its held-out scores."""

    fits: list[tuple[Any, Fit]]
    before: float
    after: float
    before_axes: np.ndarray
    after_axes: np.ndarray
    before_all: float = float("nan")
    after_all: float = float("nan")
    corner_before: float = float("nan")
    corner_after: float = float("nan")
    prediction: np.ndarray | None = None
    #: the joint projection fit of the model's projection effects and its parameter vector
    projection: tuple[Any, np.ndarray] | None = None
    #: held-out change of error (N, 6) of each simulation effect of the model (m, rad)
    simulation_deltas: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def effects(self) -> list[str]:
        """Names of the model's effects."""
        return [fit.effect for _, fit in self.fits]

    @property
    def n_params(self) -> int:
        """Number of fitted parameters of the model."""
        return sum(cand.n_params for cand, _ in self.fits)

    @property
    def reduction(self) -> float:
        """Relative fall of the held-out gap."""
        return 1.0 - self.after / self.before if self.before > 0 else 0.0

    def record(self) -> dict[str, Any]:
        """JSON record of a single-effect model (ranking entry)."""
        cand, fit = self.fits[0]
        return {
            "effect": fit.effect,
            "params": fit.params,
            "heldout_gap_before": self.before,
            "heldout_gap_after": self.after,
            "reduction": self.reduction,
            "heldout_gap_all_axes_before": self.before_all,
            "heldout_gap_all_axes_after": self.after_all,
            "heldout_corner_gap_before_px": self.corner_before,
            "heldout_corner_gap_after_px": self.corner_after,
            "heldout_gap_before_per_axis": dict(
                zip(AXES, map(float, self.before_axes), strict=True)
            ),
            "heldout_gap_after_per_axis": dict(zip(AXES, map(float, self.after_axes), strict=True)),
            "n_params": cand.n_params,
            "fit_seconds": fit.seconds,
            "stage": cand.kind,
        }


#: Held-out corner residuals closer than this are indistinguishable (px): a quarter of the
#: ArUco detector's own corner bias (~0.2 px, measured on ideal renders, issue 2), ...
EQUIVALENT_PX = 0.05
#: ... or than this share of the smaller residual.
EQUIVALENT_REL = 0.1


def equivalent(a: float, b: float) -> bool:
    """Whether two held-out corner residuals (px) are too close to prefer one explanation."""
    return abs(a - b) <= max(EQUIVALENT_PX, EQUIVALENT_REL * min(a, b))


def parsimonious(options: list[Scored]) -> Scored:
    """The model with the fewest parameters among those as good as the best.

    Ties within :func:`equivalent` are not evidence: a richer effect (a 6-DOF camera mount)
    reproduces a simpler one (a principal-point shift is a small camera rotation) and also
    soaks up unrelated nuisance, so it wins by a hair unless parsimony decides.
    """
    best = min(s.corner_after for s in options)
    tied = [s for s in options if s.corner_after <= best or equivalent(s.corner_after, best)]
    return min(tied, key=lambda s: (s.n_params, s.corner_after))


@dataclass
class ModelSearch:
    """Fits, scores and chooses models of effects on a train / held-out split of items.

    Attributes
    ----------
    rig : Rig
        The fixture (nominal geometry).
    base : VariantState
        The simulation's state, to which effects are added.
    items : Items
        Comparable configurations with their real and simulated errors and corners.
    train, held, sim_train : ndarray of int
        Item indices: training, held-out, and the training subsample used for simulation fits.
    axes : ndarray of bool (6,)
        Axes on which the pose gap is scored (those with a significant gap).
    runner : callable or None
        Runs a state through the cached pipeline (``SimRunner``); needed by simulation effects.
    min_gain : float
        Relative fall of the held-out corner residual needed to add another effect.
    """

    rig: Rig
    base: VariantState
    items: Items
    train: np.ndarray
    held: np.ndarray
    sim_train: np.ndarray
    axes: np.ndarray
    runner: Any = None
    min_gain: float = 0.1
    _evaluated: dict[tuple[str, ...], Scored] = field(default_factory=dict, repr=False)

    def _key(self, model: tuple) -> tuple[str, ...]:
        proj = sorted(c.effect for c in model if isinstance(c, ProjectionCandidate))
        return tuple(proj) + tuple(c.effect for c in model if c.effect not in proj)

    def evaluate(self, model: tuple) -> Scored:
        """Fit a model and score it on the held-out configurations (memoised).

        Projection effects are fitted jointly on the training corners; simulation effects then
        one by one on the training subsample, on top of what is already modelled. Predictions
        add each effect's change of error (m, rad) and of detected corners (px).
        """
        key = self._key(model)
        if key in self._evaluated:
            return self._evaluated[key]
        rig, base, runner, items = self.rig, self.base, self.runner, self.items
        tr, st, h = (items.subset(i) for i in (self.train, self.sim_train, self.held))
        off_st, off_h = np.zeros((len(st), 6)), np.zeros((len(h), 6))
        corner_h = np.zeros((len(h), 4, 2))
        proj = sorted(
            (c for c in model if isinstance(c, ProjectionCandidate)), key=lambda c: c.effect
        )
        fits: list[tuple[Any, Fit]] = []
        projection = None
        simulation_deltas: dict[str, np.ndarray] = {}
        if proj:
            joint = proj[0] if len(proj) == 1 else ProjectionSet(proj)
            fit = joint.fit(rig, base, tr)
            projection = (joint, fit)
            if len(proj) < len(model):
                off_st += np.nan_to_num(joint.delta(rig, base, fit, st))
            off_h += np.nan_to_num(joint.delta(rig, base, fit, h))
            corner_h += np.nan_to_num(joint.corner_shift(rig, base, fit.extra["x"], h))
            fits += zip(proj, joint.member_fits(fit) if len(proj) > 1 else [fit], strict=True)
        for cand in model:
            if isinstance(cand, ProjectionCandidate):
                continue
            fit = cand.fit(runner, base, st, st.real_err - off_st, self.axes)
            off_st += np.nan_to_num(cand.delta(runner, base, fit, st))
            simulation_deltas[cand.effect] = np.nan_to_num(cand.delta(runner, base, fit, h))
            off_h += simulation_deltas[cand.effect]
            state = make_effect(cand.effect, fit.params).apply(base)
            corner_h += np.nan_to_num(runner.corners(state, h) - runner.corners(base, h))
            fits.append((cand, fit))
        pred = h.sim_err + off_h
        scored = Scored(
            fits,
            gap_score(h.real_err, h.sim_err, h.scale, self.axes),
            gap_score(h.real_err, pred, h.scale, self.axes),
            gap_rms_per_axis(h.real_err, h.sim_err),
            gap_rms_per_axis(h.real_err, pred),
            gap_score(h.real_err, h.sim_err, h.scale),
            gap_score(h.real_err, pred, h.scale),
            corner_score(h.real_corners, h.sim_corners),
            corner_score(h.real_corners, h.sim_corners + corner_h),
            pred,
            projection,
            simulation_deltas,
        )
        self._evaluated[key] = scored
        return scored

    def rank(self, candidates, significant: bool) -> list[Scored]:
        """Fit and score every candidate alone; projection ones only when no gap is significant.

        Ranked on the held-out detected corners (the most direct evidence, in one unit, px,
        free of the planar pose ambiguity); among indistinguishable ones the simpler first.
        """
        rest = [
            self.evaluate((c,))
            for c in candidates
            if significant or isinstance(c, ProjectionCandidate)
        ]
        out = []
        while rest:
            out.append(parsimonious(rest))
            rest.remove(out[-1])
        return out

    def simplify(self, scored: Scored, pool: list) -> Scored:
        """Simplify a model while it explains the held-out corners as well.

        Effects are dropped, or projection effects swapped for ones with fewer parameters, while
        the held-out corner residual stays equivalent to ``scored``'s.
        """
        reference = scored.corner_after
        while True:
            model = [c for c, _ in scored.fits]
            options = []
            for i, member in enumerate(model):
                rest = model[:i] + model[i + 1 :]
                if rest:
                    options.append(self.evaluate(tuple(rest)))
                if not isinstance(member, ProjectionCandidate):
                    continue
                for alt in pool:
                    if (
                        isinstance(alt, ProjectionCandidate)
                        and alt not in model
                        and alt.n_params < member.n_params
                    ):
                        options.append(self.evaluate(tuple(rest) + (alt,)))
            ok = [
                o
                for o in options
                if o.corner_after <= reference or equivalent(o.corner_after, reference)
            ]
            if not ok:
                return scored
            scored = min(ok, key=lambda s: (s.n_params, s.corner_after))

    def select(self, ranking: list[Scored], max_effects: int = 3) -> Scored | None:
        """Greedy forward search with joint refits, simplified after every step.

        An effect is added while the held-out corner residual falls by ``min_gain`` or more and
        the fall is distinguishable (not :func:`equivalent`); the model is then simplified
        (:meth:`simplify`) and pruned (:meth:`prune`). Effects are returned most important
        first: effects that move the pose beyond the floor before minor ones (:meth:`minor`),
        each group by how much its removal hurts the held-out residual.
        """
        if not ranking:
            return None
        pool = [s.fits[0][0] for s in ranking]
        current = self.simplify(ranking[0], pool)
        seen = {frozenset(current.effects)}
        while len(current.fits) < max_effects:
            model = tuple(c for c, _ in current.fits)
            options = [self.evaluate(model + (c,)) for c in pool if c not in model]
            if not options:
                break
            best = parsimonious(options)
            gain = best.corner_after <= current.corner_after * (1.0 - self.min_gain)
            if not gain or equivalent(best.corner_after, current.corner_after):
                break  # no distinguishable improvement
            simpler = self.simplify(best, pool)
            if frozenset(simpler.effects) in seen:
                break  # simplified back to a model already visited
            current = simpler
            seen.add(frozenset(current.effects))
        current = self.prune(current)
        if len(current.fits) > 1:
            model = [c for c, _ in current.fits]
            minor = set(self.minor(current))
            loss = {
                c.effect: self.evaluate(tuple(m for m in model if m is not c)).corner_after
                for c in model
            }
            current = dataclasses.replace(
                current,
                fits=sorted(
                    current.fits, key=lambda cf: (cf[1].effect in minor, -loss[cf[1].effect])
                ),
            )
        return current

    def prune(self, scored: Scored) -> Scored:
        """Drop effects that move no pose by a relevant amount and are not clearly seen.

        An effect whose :meth:`contributions` is below 1 is dropped only when the model without
        it still explains the held-out corners as well (:func:`equivalent`); otherwise it stays
        as a *minor* effect (seen in the corners, no pose impact beyond the floor). Comparing
        corner residuals, never letting the pose criterion alone swap the explanation, is what
        keeps a refitted look-alike (a tag print scale soaking up a focal-length change) from
        replacing the effect that the corners single out.
        """
        while len(scored.fits) > 1:
            weight = self.contributions(scored)
            options = []
            for effect in (e for e, w in weight.items() if w < 1.0):
                reduced = self.evaluate(tuple(c for c, _ in scored.fits if c.effect != effect))
                if reduced.corner_after <= scored.corner_after or equivalent(
                    reduced.corner_after, scored.corner_after
                ):
                    options.append(reduced)
            if not options:
                return scored
            scored = min(options, key=lambda o: o.corner_after)
        return scored

    def minor(self, scored: Scored) -> list[str]:
        """Effects of a model seen in the evidence that move no pose beyond the floor."""
        return [e for e, w in self.contributions(scored).items() if w < 1.0]

    def member_deltas(self, scored: Scored) -> dict[str, np.ndarray]:
        """Held-out change of error (N, 6) due to each effect of a model, the others held fixed.

        For a projection effect: the model's projection prediction minus the same prediction
        with that effect's parameters set to zero (no refit). For a simulation effect: its own
        change of error.
        """
        held = self.items.subset(self.held)
        out = dict(scored.simulation_deltas)
        if scored.projection is not None:
            joint, fit = scored.projection
            full = np.nan_to_num(joint.delta(self.rig, self.base, fit, held))
            members = joint.members if isinstance(joint, ProjectionSet) else [joint]
            if len(members) == 1:
                out[members[0].effect] = full
            else:
                cuts = np.cumsum([m.n_params for m in members])[:-1]
                for k, (m, xm) in enumerate(
                    zip(members, np.split(fit.extra["x"], cuts), strict=True)
                ):
                    x = fit.extra["x"].copy()
                    start = 0 if k == 0 else cuts[k - 1]
                    x[start : start + len(xm)] = 0.0
                    without = Fit(fit.effect, fit.params, fit.seconds, {"x": x})
                    out[m.effect] = full - np.nan_to_num(
                        joint.delta(self.rig, self.base, without, held)
                    )
        return out

    def contributions(self, scored: Scored) -> dict[str, float]:
        """How much each effect of a model moves its held-out pose predictions (dimensionless).

        Per effect: the change of the model's held-out pose predictions that this effect makes
        with the others held at their fitted values (:meth:`member_deltas`, no refit: a refit
        would let a look-alike take over its share and make both look irrelevant); the median
        absolute change per axis over the noise (or the practical floor, the larger), the
        largest over the axes with a significant gap. Below 1 the effect changes no pose by a
        relevant amount.
        """
        held = self.items.subset(self.held)
        axes = self.axes if np.any(self.axes) else np.ones(6, bool)
        return {
            effect: float(np.max((np.nanmedian(np.abs(d), axis=0) / held.scale)[axes]))
            for effect, d in self.member_deltas(scored).items()
        }

    def alternatives(self, chosen: Scored, limit: int = 5) -> list[dict[str, Any]]:
        """Other models tried that explain the held-out corners as well as ``chosen``.

        Supersets of ``chosen`` are left out: that an extra effect changes nothing is no news.
        """
        same = [
            s
            for s in self._evaluated.values()
            if not set(chosen.effects) <= set(s.effects)  # not the choice plus extras
            and (
                s.corner_after <= chosen.corner_after
                or equivalent(s.corner_after, chosen.corner_after)
            )
        ]
        return [
            {
                "effects": s.effects,
                "n_params": s.n_params,
                "heldout_corner_gap_after_px": s.corner_after,
                "heldout_gap_after": s.after,
            }
            for s in sorted(same, key=lambda s: (s.n_params, s.corner_after))[:limit]
        ]
