"""Which effects explain a gap: fit models of one or more effects, score them, choose one.

A *model* is a set of catalogue effects. Simulation (appearance) effects are fitted one by one on
the image evidence of the fit split, projection effects jointly on its corners on top. Every
model is scored on the choose split on all evidence channels (:mod:`simgap.analysis.gap._channels`),
its corners also cross-fitted (:mod:`simgap.analysis.search._cross_fit`). The search ranks single
effects, then adds effects greedily while the combined misfit falls and some channel improves
distinguishably (:mod:`simgap.analysis.search._scoring`), and after every step simplifies the model:
effects are dropped or swapped for ones with fewer parameters while the model stays *as good*
(the data cannot tell the models apart, so the simpler explanation is reported and the others are
listed). The measure split is scored only for the chosen model. Whether an effect may enter a
model at all is :mod:`simgap.analysis.search._admission`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from simgap.analysis.candidates import (
    Candidate,
    Fit,
    ProjectionCandidate,
    ProjectionSet,
    Runner,
    SimulationChain,
)
from simgap.analysis.gap import Items, Prediction
from simgap.analysis.search._admission import admissible, at_bound
from simgap.analysis.search._contributions import pose_contributions
from simgap.analysis.search._corner_findings import (
    corner_effect_alone,
    corner_look_alikes,
    with_corner_effects,
)
from simgap.analysis.search._cross_fit import cross_fitted
from simgap.analysis.search._pair_step import pair_start, pair_step
from simgap.analysis.search._pruning import pruned
from simgap.analysis.search._scored import Scored
from simgap.analysis.search._scoring import (
    as_good_cross_fitted,
    improves,
    improves_on_nothing,
    parsimonious,
)
from simgap.analysis.thresholds import (
    CORNER_UNIT_PX,
    GEOMETRY_CORNER_GAP_PX,
    MAX_EFFECTS,
    MINOR_CONTRIBUTION,
    MODEL_SEARCH_STARTS,
)
from simgap.core.progress import Steps
from simgap.core.rig import Rig
from simgap.effects import EFFECTS
from simgap.effects.state import VariantState


@dataclass
class ModelSearch:
    """Fits, scores and chooses models of effects on a fit / choose split of items.

    Attributes
    ----------
    rig : Rig
        The fixture (nominal geometry).
    base : VariantState
        The simulation's state, to which effects are added.
    items : Items
        Comparable items with their real and simulated errors and corners.
    fit_index, choose_index, sim_fit_index : ndarray of int
        Item indices: the fit split, the choose split (models are scored and chosen on it) and
        the subsample of the fit split used for simulation fits.
    significant_axes : ndarray of bool (6,)
        Axes on which the pose gap is scored (those with a significant gap).
    runner : Runner or None
        Runs a state through the cached pipeline; needed by simulation effects.
    corner_unit_px : float
        Unit of the corner channel (px): :data:`~simgap.analysis.thresholds.CORNER_UNIT_PX` or
        the capture's own corner noise when larger
        (:func:`simgap.analysis.gap.corner_unit`).
    steps : Steps
        Where fits are counted: one unit of work per model fitted (not per memoised one), in
        the steps ``fitting candidates`` (:meth:`rank`) and ``model search`` (:meth:`select`);
        default: silent.
    """

    rig: Rig
    base: VariantState
    items: Items
    fit_index: np.ndarray
    choose_index: np.ndarray
    sim_fit_index: np.ndarray
    significant_axes: np.ndarray
    runner: Runner | None = None
    corner_unit_px: float = CORNER_UNIT_PX
    steps: Steps = field(default_factory=Steps, repr=False)
    _evaluated: dict[tuple[str, ...], Scored] = field(default_factory=dict, repr=False)
    _chain: SimulationChain | None = field(default=None, repr=False)
    #: single-effect models left out of the ranking because a fitted parameter lies on the end
    #: of its searched range (:func:`at_bound`)
    on_bound: list[Scored] = field(default_factory=list, repr=False)
    #: the model with geometry that :meth:`select` refused because it left the corners more
    #: than :data:`~simgap.analysis.thresholds.GEOMETRY_CORNER_GAP_PX` off (None: none refused)
    refused_geometry: Scored | None = field(default=None, repr=False)

    @property
    def chain(self) -> SimulationChain:
        """Fits and runs the models' simulation effects (on the fit split's subsample)."""
        if self._chain is None:
            self._chain = SimulationChain(
                self.runner, self.base, self.items.subset(self.sim_fit_index)
            )
        return self._chain

    def _key(self, model: tuple[Candidate, ...]) -> tuple[str, ...]:
        proj = sorted(c.effect for c in model if isinstance(c, ProjectionCandidate))
        return tuple(proj) + tuple(c.effect for c in model if c.effect not in proj)

    def evaluate(self, model: tuple[Candidate, ...]) -> Scored:
        """Fit a model on the fit split and score it on the choose split (memoised).

        Simulation (appearance) effects are fitted first on the image evidence of the fit
        split's subsample, each on the simulation with the ones before it
        (:class:`~simgap.analysis.candidates.SimulationChain`); their change of the
        detected corners is then added to the simulated corners, and the projection effects are
        fitted jointly on the fit split's corners on top
        (geometry is what the corners show once the image formation is modelled; fitting it
        first would let, say, a print scale soak up a blur's edge bias and then count it twice).
        Predictions add the simulation effects' joint change of error (m, rad), corners (px),
        image statistics and detections to the projection effects' changes.
        """
        key = self._key(model)
        if key in self._evaluated:
            return self._evaluated[key]
        rig, base = self.rig, self.base
        tr = self.items.subset(self.fit_index)
        simulation = self.chain.fit(
            tuple(c for c in model if not isinstance(c, ProjectionCandidate))
        )
        fits: list[tuple[Candidate, Fit]] = list(simulation)
        proj = sorted(
            (c for c in model if isinstance(c, ProjectionCandidate)), key=lambda c: c.effect
        )
        projection = None
        if proj:
            joint = proj[0] if len(proj) == 1 else ProjectionSet(proj)
            shift_tr, _, _ = self.chain.changes(simulation, tr)
            fit = joint.fit(
                rig, base, dataclasses.replace(tr, sim_corners=tr.sim_corners + shift_tr)
            )
            projection = (joint, fit)
            members = joint.member_fits(fit) if isinstance(joint, ProjectionSet) else [fit]
            fits = list(zip(proj, members, strict=True)) + fits
        scored = self.score(fits, projection, self.choose_index)
        scored = self._evaluated[key] = cross_fitted(scored, rig, base, self.chain)
        self.steps.advance()
        return scored

    def score(
        self,
        fits: list[tuple[Candidate, Fit]],
        projection: tuple[ProjectionCandidate, Fit] | None,
        index: np.ndarray,
    ) -> Scored:
        """Score fitted effects (no refit) on the items at ``index``."""
        rig, base = self.rig, self.base
        h = self.items.subset(index)
        simulation = [(c, f) for c, f in fits if not isinstance(c, ProjectionCandidate)]
        simulation_deltas = self.chain.pose_deltas(simulation, h)
        off_h = sum(simulation_deltas.values(), np.zeros((len(h), 6)))
        corner_h, stats_h, det_h = self.chain.changes(simulation, h)
        proj_record = None
        if projection is not None:
            joint, fit = projection
            h_shifted = dataclasses.replace(h, sim_corners=h.sim_corners + corner_h)
            proj_record = (joint, fit, h_shifted)
            off_h += np.nan_to_num(joint.delta(rig, base, fit, h_shifted))
            corner_h = corner_h + np.nan_to_num(joint.corner_shift(rig, base, fit.extra["x"], h))
        stats = detected = None
        if h.real_stats is not None and stats_h is not None:  # None where h.sim_stats is
            stats = h.required("sim_stats") + stats_h
            detected = np.clip(h.required("sim_detected") + det_h, 0.0, 1.0)
        prediction = Prediction(
            error=h.sim_err + off_h,
            corners=h.sim_corners + corner_h,
            stats=stats,
            detected=detected,
        )
        return Scored.measured(
            fits,
            h,
            prediction,
            self.significant_axes,
            self.corner_unit_px,
            projection=proj_record,
            simulation_deltas=simulation_deltas,
        )

    def rank(self, candidates: list[Candidate], significant: bool) -> list[Scored]:
        """Fit and score every candidate alone; appearance ones only when some evidence is.

        ``significant``: some evidence differs significantly (the where step). Appearance
        effects whose fit does not explain their own statistics on the fit split
        (``supported`` false, :data:`simgap.analysis.thresholds.SIGNATURE_MIN_GAIN`) are left
        out, and so are effects a supported one ``excludes`` (a depth-dependent widening of the
        edges is a lens, not a blur). Ranked on the combined misfit of all evidence on the
        choose split (:attr:`Scored.evidence_after`: detected corners, pose, detections, image
        statistics, each in units of its smallest relevant difference); among indistinguishable
        ones (:func:`simgap.analysis.search.equivalent_models`) the simpler first. A model with
        a parameter on its search bound is no finding (:func:`at_bound`): it is kept in
        :attr:`on_bound` for the report.
        """
        todo = [c for c in candidates if significant or isinstance(c, ProjectionCandidate)]
        self.steps.start("fitting candidates", len(todo))
        rest = [
            scored
            for scored in (self.evaluate((c,)) for c in todo)
            if scored.fits[0][1].extra.get("supported", True)
        ]
        self.on_bound = [s for s in rest if at_bound(s)]
        rest = [s for s in rest if not at_bound(s)]
        excluded = {e for s in rest for e in s.fits[0][1].extra.get("excludes", ())}
        rest = [s for s in rest if s.fits[0][1].effect not in excluded]
        out = []
        while rest:
            out.append(parsimonious(rest))
            rest.remove(out[-1])
        return out

    def simplify(self, scored: Scored, pool: list) -> Scored:
        """Simplify a model while it explains the evidence as well.

        Effects are dropped, or projection effects swapped for ones with fewer parameters that
        could enter the model in their place (:func:`admissible`: a carriage pitch of -0.2 %
        that moved no pose replaced a lens distortion whose corners it nearly matched on 13
        items), while the model stays as good as ``scored`` (:func:`as_good_cross_fitted`).
        Where nothing simpler is as good, a projection effect is swapped for one with as many
        parameters that explains the evidence distinguishably better (:func:`improves`): the
        greedy search keeps the effect it started with, and a look-alike that led alone stays
        in the model once the effect beside it is found (measured on a blind capture: a print
        scale led a focal length's capture alone and stayed beside the defocus that joined it,
        where the focal length with the defocus explained the evidence better;
        docs/results/design_evidence.md#selection).
        """
        reference = scored
        while True:
            model = [c for c, _ in scored.fits]
            options, better = [], []
            for i, member in enumerate(model):
                rest = model[:i] + model[i + 1 :]
                if rest:
                    options.append(self.evaluate(tuple(rest)))
                if not isinstance(member, ProjectionCandidate):
                    continue
                for alt in pool:
                    if (
                        not isinstance(alt, ProjectionCandidate)
                        or alt in model
                        or alt.n_params > member.n_params
                    ):
                        continue
                    swapped = self.evaluate(tuple(rest) + (alt,))
                    # the other effect must be one that could enter on its own
                    if not admissible(swapped, self.evaluate(tuple(rest)) if rest else None):
                        continue
                    if alt.n_params < member.n_params:
                        options.append(swapped)
                    elif swapped.evidence_after < scored.evidence_after and improves(
                        swapped, scored
                    ):
                        better.append(swapped)
            ok = [o for o in options if as_good_cross_fitted(o, reference)]
            if ok:
                scored = min(ok, key=lambda s: (s.n_params, s.evidence_after))
            elif better:
                scored = reference = min(better, key=lambda s: s.evidence_after)
            else:
                return scored

    def select(
        self, ranking: list[Scored], max_effects: int = MAX_EFFECTS, geometry: bool = True
    ) -> Scored | None:
        """Greedy forward search with joint refits, simplified after every step.

        A geometric effect enters a model (starts the search, or is added to it) only when it
        brings the pose at least :data:`~simgap.analysis.thresholds.MIN_POSE_REDUCTION` closer
        to the real one than the model without it (:func:`worsens_pose`), when the cross-fitted
        corners single out an effect with a corner signature of its own (a lens distortion), or
        when the cross-fitted tag centres show it
        (:func:`~simgap.analysis.search._admission.admissible`; a lens that moved no pose beyond the
        floor, or carriage pitches whose depth another camera's edges hid, were left out). One that
        follows the corners without moving the poses closer or the centres is a look-alike of an
        image effect (measured on development captures: a tag print scale following the corners of a
        motion blur moved the pose gap by 6 % or less either way, every true geometric effect that
        started a model lowered it by 19 % or more; docs/results/design_evidence.md#selection).

        The search starts from the best single effect, and again from each of the next geometric
        ones among the first :data:`~simgap.analysis.thresholds.MODEL_SEARCH_STARTS` of the
        ranking; the best of its answers is kept (:func:`parsimonious`). From each start, an
        effect is added while the combined misfit falls and some evidence channel
        improves distinguishably (:func:`improves`); where no single one does (or none starts
        the search) and the model leaves the geometry unexplained, two projection effects may
        enter at once (:mod:`simgap.analysis.search._pair_step`); the model is then simplified
        (:meth:`simplify`) and pruned (:meth:`prune`); last, effects with a corner signature
        that the corners single out beside it join it
        (:mod:`~simgap.analysis.search._corner_findings`; where nothing starts the search, such an
        effect alone is the answer). Effects are returned most important first: by how much their
        removal worsens the combined evidence (an effect may matter most for the image evidence and
        move no pose: it is then also :meth:`minor`), stochastic effects (sensor noise) after the
        others: they explain noise and scatter, not the systematic gap, and every real camera has
        some, so they lead only when alone.

        A model with a geometric or calibration effect that leaves the corners more than
        :data:`~simgap.analysis.thresholds.GEOMETRY_CORNER_GAP_PX` off has fitted the geometry to
        corners something else moved: it is kept in :attr:`refused_geometry` and the search is
        repeated without geometry (``geometry`` false: projection effects are left out).
        """
        if not geometry:
            ranking = [s for s in ranking if not isinstance(s.fits[0][0], ProjectionCandidate)]
        # a projection effect whose fit alone ran onto a bound may still join a model: alone it
        # stood in for another effect too (a calibration file's distortion beside a focal-length
        # change fitted k2 on its bound alone and was never tried beside the focal length;
        # docs/results/design_evidence.md#selection); refitted jointly, every parameter must
        # then be off its bound (:func:`admissible`).
        # An appearance effect on a bound alone stays out: it named no value of its own
        # (refitted beside others it must be off its bound too, :func:`admissible`).
        pool = self._pool(ranking, geometry)
        # the search starts from the best single effect that explains something: a geometric
        # effect that alone is not admissible explains nothing (with another effect it may)
        starts = [s for s in ranking if admissible(s, None)]
        self.steps.start("model search")
        if not starts or not improves_on_nothing(starts[0]):
            # nothing alone: perhaps two geometric effects that hide each other (pair_step)
            starts = pair_start(ranking, pool, self, max_effects)
            if not starts or not improves_on_nothing(starts[0]):
                # as where nothing differs: a lens seen only in the cross-fitted corners
                return corner_effect_alone(ranking)
        # greedy from the best start and from the next geometric ones: a look-alike that leads
        # alone can take the search down a path the true pair never joins (MODEL_SEARCH_STARTS)
        more = [
            st
            for st in starts[1:MODEL_SEARCH_STARTS]
            if isinstance(st.fits[0][0], ProjectionCandidate) and improves_on_nothing(st)
        ]
        grown = [self._grow(start, pool, max_effects) for start in [starts[0], *more]]
        current = parsimonious(grown) if len(grown) > 1 else grown[0]
        if len(current.fits) > 1:
            model = tuple(c for c, _ in current.fits)
            loss = {
                c.effect: self.evaluate(tuple(m for m in model if m is not c)).evidence_after
                for c in model
            }
            current = dataclasses.replace(
                current,
                fits=sorted(
                    current.fits,
                    key=lambda cf: (EFFECTS[cf[1].effect].stochastic, -loss[cf[1].effect]),
                ),
            )
        projection = any(isinstance(c, ProjectionCandidate) for c, _ in current.fits)
        if projection and current.corner_gap_after_px > GEOMETRY_CORNER_GAP_PX:
            self.refused_geometry = current
            return self.select(ranking, max_effects, geometry=False)
        return current

    def _grow(self, start: Scored, pool: list[Candidate], max_effects: int) -> Scored:
        """The greedy forward search from ``start``, simplified, pruned, with corner findings.

        (:meth:`select`'s search from one start.)
        """
        current = self.simplify(start, pool)
        seen = {frozenset(current.effects)}
        while len(current.fits) < max_effects:
            model = tuple(c for c, _ in current.fits)
            options = []
            for c in (c for c in pool if c not in model):
                option = self.evaluate(model + (c,))
                if admissible(option, current):
                    options.append(option)
            best = parsimonious(options) if options else None
            if best is None or not self._gains(best, current):
                # two geometric effects that hide each other from the single step (pair_step)
                best = pair_step(current, pool, self, max_effects)
                if best is None or not self._gains(best, current):
                    break  # no distinguishable improvement
            simpler = self.simplify(best, pool)
            if frozenset(simpler.effects) in seen:
                break  # simplified back to a model already visited
            current = simpler
            seen.add(frozenset(current.effects))
        current = self.prune(current)
        current = with_corner_effects(current, pool, self.evaluate, max_effects)
        return current

    def _pool(self, ranking: list[Scored], geometry: bool) -> list[Candidate]:
        """The ranked effects and, with ``geometry``, the projection effects on a bound alone."""
        return [s.fits[0][0] for s in ranking] + [
            s.fits[0][0]
            for s in self.on_bound
            if geometry and isinstance(s.fits[0][0], ProjectionCandidate)
        ]

    @staticmethod
    def _gains(model: Scored, current: Scored) -> bool:
        """Whether ``model`` lowers the combined misfit and improves some channel clearly."""
        return model.evidence_after < current.evidence_after and improves(model, current)

    def prune(self, scored: Scored) -> Scored:
        """Drop effects that move no pose by a relevant amount and are not clearly seen.

        (:func:`simgap.analysis.search.pruned`, with this search's fits and contributions.)
        """
        return pruned(scored, self.evaluate, self.contributions)

    @property
    def tried(self) -> list[Scored]:
        """Every model scored so far (the alternatives a report may list)."""
        return list(self._evaluated.values())

    def look_alikes(self, scored: Scored, ranking: list[Scored]) -> dict[str, tuple[str, ...]]:
        """Per minor projection effect of a model, the effects as good in its place.

        (:func:`~simgap.analysis.search.corner_look_alikes`, from the ranked effects and the
        projection effects on a bound alone, as :meth:`select` draws from: projection effects
        and the camera's own edge offset.)
        """
        pool = self._pool(ranking, geometry=True)
        return corner_look_alikes(scored, self.minor(scored), pool, self.evaluate)

    def minor(self, scored: Scored) -> list[str]:
        """Effects of a model seen in the evidence that move no pose beyond the floor."""
        return [e for e, w in self.contributions(scored).items() if w < MINOR_CONTRIBUTION]

    def contributions(self, scored: Scored) -> dict[str, float]:
        """How much each effect of a model moves its pose predictions (:func:`pose_contributions`).

        Below :data:`~simgap.analysis.thresholds.MINOR_CONTRIBUTION` an effect changes no pose by
        a relevant amount.
        """
        return pose_contributions(scored, self.rig, self.base, self.significant_axes)
