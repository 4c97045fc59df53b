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
from scipy.stats import wilcoxon

from simgap.analysis.appearance import RESIDUAL_CAP
from simgap.analysis.evidence import IMAGE_FLOORS, compare_stat
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
from simgap.core.rig import Rig
from simgap.effects import EFFECTS
from simgap.effects.state import VariantState
from simgap.pose.image_stats import STAT_INDEX

#: Noise statistics: only stochastic effects change them (see :meth:`ModelSearch.evaluate`).
NOISE_STATS = [
    STAT_INDEX[s]
    for s in ("noise_ink_dn", "noise_paper_dn", "noise_ink_linear", "noise_paper_linear")
]
#: Image statistics with a floor, in the order of :attr:`Scored.image_after`.
SCORED_STATS = tuple(s for s, (_, floor) in IMAGE_FLOORS.items() if floor is not None)


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
    #: the joint projection candidate, its fit and the held-out items it was applied to
    projection: tuple[Any, Fit, Items] | None = None
    #: held-out change of error (N, 6) of each simulation effect of the model (m, rad)
    simulation_deltas: dict[str, np.ndarray] = field(default_factory=dict)
    #: held-out image-evidence misfit per statistic before / after (floors, :func:`image_misfits`)
    image_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    image_after: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: held-out detection mismatch before / after (in units of DETECTION_UNIT)
    detection_before: float = 0.0
    detection_after: float = 0.0
    #: the scored items and the model's predictions for them: corners (N, 4, 2) px, image
    #: statistics (N, S), detection rate (N,)
    items: Items | None = None
    corner_unit_px: float = 0.2
    corners_pred: np.ndarray | None = None
    stats_pred: np.ndarray | None = None
    detected_pred: np.ndarray | None = None

    @property
    def channels_after(self) -> np.ndarray:
        """Held-out misfit per evidence channel, in its units.

        Corners (:attr:`corner_unit_px`), pose over all axes (:func:`gap_score`, noise or
        practical floor), detection (:data:`DETECTION_UNIT`), then each image statistic (floors).
        """
        return self._channels(self.corner_after, self.after_all, self.detection_after, True)

    @property
    def channels_before(self) -> np.ndarray:
        """Held-out misfit per evidence channel without the model's effects."""
        return self._channels(self.corner_before, self.before_all, self.detection_before, False)

    def _channels(self, corner_px: float, pose: float, detection: float, after: bool) -> np.ndarray:
        head = [_finite(corner_px) / self.corner_unit_px, _finite(pose), detection]
        return np.concatenate([head, self.image_after if after else self.image_before])

    @property
    def evidence_after(self) -> float:
        """Combined held-out misfit of all evidence (root sum of squared channels)."""
        return float(np.sqrt(np.sum(self.channels_after**2)))

    @property
    def evidence_before(self) -> float:
        """Combined held-out misfit without the model's effects."""
        return float(np.sqrt(np.sum(self.channels_before**2)))

    @property
    def evidence_reduction(self) -> float:
        """Relative fall of the combined held-out misfit."""
        b = self.evidence_before
        return 1.0 - self.evidence_after / b if b > 0 else 0.0

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
            "heldout_image_misfit_before": _rss(self.image_before),
            "heldout_image_misfit_after": _rss(self.image_after),
            "heldout_detection_mismatch_before": self.detection_before,
            "heldout_detection_mismatch_after": self.detection_after,
            "heldout_evidence_before": self.evidence_before,
            "heldout_evidence_after": self.evidence_after,
            "n_params": cand.n_params,
            "fit_seconds": fit.seconds,
            "stage": cand.kind,
        }


#: Held-out corner residuals closer than this are indistinguishable (px): a quarter of the
#: ArUco detector's own corner bias (~0.2 px, measured on ideal renders, issue 2), ...
EQUIVALENT_PX = 0.05
#: ... or than this share of the smaller residual.
EQUIVALENT_REL = 0.1


#: Unit of the corner channel (px): the ArUco detector's own corner bias on ideal renders, so
#: that :data:`EQUIVALENT_PX` is a quarter unit, like the other channels' tolerance.
CORNER_UNIT_PX = 0.2
#: Unit of the detection channel: this share of held-out tags detected differently.
DETECTION_UNIT = 0.05
#: Paired test of per-item corner residuals (:func:`corners_clearly_lower`): false-alarm rate
#: and the smallest median improvement, as a share of the other model's median residual.
PAIRED_ALPHA = 0.01
PAIRED_MIN_SHARE = 0.05
#: Channel misfits (in channel units) closer than this are indistinguishable.
EQUIVALENT_UNITS = EQUIVALENT_PX / CORNER_UNIT_PX


def corner_unit(reproj_px: np.ndarray) -> float:
    """Unit of the corner channel (px) for a capture with these PnP reprojection errors.

    The RMS reprojection error of four corners fitted by a 6-parameter pose keeps 2 of 8 degrees
    of freedom, so a corner's noise is about twice the median reprojection error; a residual of
    real against simulated corners carries it from both sides (sqrt 2). The unit is that, or
    :data:`CORNER_UNIT_PX` (the detector's own bias on ideal renders) when larger: on a blurred
    or noisy capture corner residuals of a pixel are noise, not evidence.
    """
    r = np.asarray(reproj_px, float)
    r = r[np.isfinite(r)]
    noise = 2.0 * np.sqrt(2.0) * float(np.median(r)) if r.size else 0.0
    return max(CORNER_UNIT_PX, noise)


def _finite(v: float) -> float:
    return float(v) if np.isfinite(v) else 0.0


def _rss(v: np.ndarray) -> float:
    """Root sum of squares."""
    return float(np.sqrt(np.sum(np.square(v))))


def equivalent(a: float, b: float) -> bool:
    """Whether two held-out corner residuals (px) are too close to prefer one explanation."""
    return abs(a - b) <= max(EQUIVALENT_PX, EQUIVALENT_REL * min(a, b))


def equivalent_models(a: Scored, b: Scored) -> bool:
    """Whether two models explain every held-out evidence channel equally well.

    Per channel (corners, image statistics, detection) the misfits must be within
    :data:`EQUIVALENT_UNITS` channel units or :data:`EQUIVALENT_REL` of the smaller; for the
    corner channel this is :func:`equivalent` (0.05 px or 10 %).
    """
    return not (improves(a, b) or improves(b, a))


def distinguishably_lower(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether some channel misfit of ``a`` is lower than ``b``'s beyond the tolerance.

    Lower by more than :data:`EQUIVALENT_UNITS` channel units and :data:`EQUIVALENT_REL` of the
    smaller misfit (for the corner channel: 0.05 px and 10 %, the rule of issue 4).
    """
    return bool(np.any(b - a > np.maximum(EQUIVALENT_UNITS, EQUIVALENT_REL * np.minimum(a, b))))


def corner_residuals(scored: Scored, before: bool = False) -> np.ndarray | None:
    """Per held-out item, the mean squared corner distance real - predicted (px^2)."""
    h = scored.items
    if h is None or scored.corners_pred is None:
        return None
    pred = h.sim_corners if before else scored.corners_pred
    return np.sum((h.real_corners - pred) ** 2, axis=-1).mean(axis=-1)


def corners_clearly_lower(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Whether per-item corner residuals ``a`` are lower than ``b`` on the same items.

    A paired one-sided Wilcoxon signed-rank test at :data:`PAIRED_ALPHA`, with a median
    improvement of at least :data:`PAIRED_MIN_SHARE` of ``b``'s: a consistent improvement over
    the held-out items is evidence even when it is smaller than the fixed tolerance (a lens
    distortion moves the central tags' corners by tenths of a pixel).
    """
    if a is None or b is None or a.shape != b.shape:
        return False
    ok = np.isfinite(a) & np.isfinite(b)
    d = b[ok] - a[ok]
    if d.size < 6 or np.all(d == 0) or np.median(d) <= PAIRED_MIN_SHARE * np.median(b[ok]):
        return False
    return bool(wilcoxon(d, alternative="greater").pvalue < PAIRED_ALPHA)


def improves(a: Scored, b: Scored) -> bool:
    """Whether ``a`` explains some held-out evidence channel distinguishably better than ``b``.

    Beyond the tolerance on some channel (:func:`distinguishably_lower`), or consistently
    better corners item by item (:func:`corners_clearly_lower`).
    """
    return distinguishably_lower(a.channels_after, b.channels_after) or corners_clearly_lower(
        corner_residuals(a), corner_residuals(b)
    )


def as_good(a: Scored, b: Scored) -> bool:
    """``a`` explains the held-out evidence at least as well as ``b`` (or indistinguishably)."""
    return a.evidence_after <= b.evidence_after or equivalent_models(a, b)


def parsimonious(options: list[Scored]) -> Scored:
    """The model with the fewest parameters among those as good as the best.

    Ties within :func:`equivalent_models` are not evidence: a richer effect (a 6-DOF camera
    mount) reproduces a simpler one (a principal-point shift is a small camera rotation) and also
    soaks up unrelated nuisance, so it wins by a hair unless parsimony decides.
    """
    best = min(options, key=lambda s: s.evidence_after)
    tied = [s for s in options if as_good(s, best)]
    return min(tied, key=lambda s: (s.n_params, s.evidence_after))


def improves_on_nothing(scored: Scored) -> bool:
    """Whether a model explains the held-out evidence distinguishably better than no effect."""
    return scored.evidence_after < scored.evidence_before and (
        distinguishably_lower(scored.channels_after, scored.channels_before)
        or corners_clearly_lower(corner_residuals(scored), corner_residuals(scored, before=True))
    )


def image_misfits(real: np.ndarray | None, pred: np.ndarray | None) -> np.ndarray:
    """Held-out image-evidence misfit per statistic (floors), capped at RESIDUAL_CAP.

    Per statistic of :data:`simgap.analysis.evidence.IMAGE_FLOORS` that has a floor, the
    absolute median over tags of ``compare_stat(real, pred) / floor`` (a bias, robust to
    per-tag noise). Misfits beyond the cap mean "not modelled" and count as the cap, so that an
    effect is not credited or blamed for a difference nothing in the catalogue explains (a print
    whose ink is blacker than the simulation's, say). Zeros when nothing is measured.
    """
    out = np.zeros(len(SCORED_STATS))
    if real is None or pred is None:
        return out
    for k, stat in enumerate(SCORED_STATS):
        floor = IMAGE_FLOORS[stat][1]
        i = STAT_INDEX[stat]
        d = compare_stat(stat, real[:, i], pred[:, i])
        d = d[np.isfinite(d)]
        if d.size:
            out[k] = min(abs(float(np.median(d))) / floor, RESIDUAL_CAP)
    return out


def detection_score(real: np.ndarray, pred: np.ndarray) -> float:
    """Share of held-out tags whose detection rate differs, in units of DETECTION_UNIT."""
    ok = np.isfinite(real) & np.isfinite(pred)
    return float(np.mean(np.abs(real[ok] - pred[ok])) / DETECTION_UNIT) if ok.any() else 0.0


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
    corner_unit_px : float
        Unit of the corner channel (px): :data:`CORNER_UNIT_PX` or the capture's own corner
        noise when larger (:func:`corner_unit`).
    """

    rig: Rig
    base: VariantState
    items: Items
    train: np.ndarray
    held: np.ndarray
    sim_train: np.ndarray
    axes: np.ndarray
    runner: Any = None
    corner_unit_px: float = 0.2
    _evaluated: dict[tuple[str, ...], Scored] = field(default_factory=dict, repr=False)

    def _key(self, model: tuple) -> tuple[str, ...]:
        proj = sorted(c.effect for c in model if isinstance(c, ProjectionCandidate))
        return tuple(proj) + tuple(c.effect for c in model if c.effect not in proj)

    def evaluate(self, model: tuple) -> Scored:
        """Fit a model on the training items and score it on the held-out ones (memoised).

        Simulation (appearance) effects are fitted first, each on the image evidence of the
        training subsample; their change of the detected corners is then added to the simulated
        corners, and the projection effects are fitted jointly on the training corners on top
        (geometry is what the corners show once the image formation is modelled; fitting it
        first would let, say, a print scale soak up a blur's edge bias and then count it twice).
        Predictions add each effect's change of error (m, rad), corners (px), image statistics
        and detections.
        """
        key = self._key(model)
        if key in self._evaluated:
            return self._evaluated[key]
        rig, base, runner = self.rig, self.base, self.runner
        tr, st = self.items.subset(self.train), self.items.subset(self.sim_train)
        fits: list[tuple[Any, Fit]] = []
        for cand in model:
            if not isinstance(cand, ProjectionCandidate):
                fits.append((cand, cand.fit(runner, base, st, st.real_err, self.axes)))
        proj = sorted(
            (c for c in model if isinstance(c, ProjectionCandidate)), key=lambda c: c.effect
        )
        projection = None
        if proj:
            joint = proj[0] if len(proj) == 1 else ProjectionSet(proj)
            shift_tr, _, _ = self._simulation_changes(fits, tr)
            fit = joint.fit(
                rig, base, dataclasses.replace(tr, sim_corners=tr.sim_corners + shift_tr)
            )
            projection = (joint, fit)
            members = joint.member_fits(fit) if len(proj) > 1 else [fit]
            fits = list(zip(proj, members, strict=True)) + fits
        scored = self.score(fits, projection, self.held)
        self._evaluated[key] = scored
        return scored

    def _simulation_changes(
        self, fits: list[tuple[Any, Fit]], items: Items
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Changes the simulation effects of ``fits`` make on ``items``, summed over effects.

        Returns the change of detected corners (N, 4, 2) (px), of image statistics (N, S) (None
        without statistics) and of the detection rate (N,).
        """
        runner, base = self.runner, self.base
        corners = np.zeros((len(items), 4, 2))
        has_stats = items.sim_stats is not None
        stats = np.zeros_like(items.sim_stats) if has_stats else None
        detected = np.zeros(len(items))
        for cand, fit in fits:
            if isinstance(cand, ProjectionCandidate):
                continue
            state = cand.apply(base, fit.params)
            stochastic = EFFECTS[cand.effect].stochastic
            if not stochastic:
                # a stochastic effect (sensor noise) leaves the expected corners where they are;
                # one noisy realisation is no prediction of them (its evidence is the noise)
                corners += np.nan_to_num(
                    runner.corners(state, items) - runner.corners(base, items)
                )
            if has_stats:
                change = np.nan_to_num(runner.stats(state, items) - runner.stats(base, items))
                if not stochastic:
                    # a deterministic effect does not change the camera's noise; the change of
                    # the simulation's noise statistics is its render noise being smoothed
                    change[:, NOISE_STATS] = 0.0
                stats += change
                detected += np.nan_to_num(
                    runner.detected(state, items) - runner.detected(base, items)
                )
        return corners, stats, detected

    def score(
        self, fits: list[tuple[Any, Fit]], projection: tuple[Any, Fit] | None, index: np.ndarray
    ) -> Scored:
        """Score fitted effects (no refit) on the items at ``index``."""
        rig, base, runner = self.rig, self.base, self.runner
        h = self.items.subset(index)
        off_h = np.zeros((len(h), 6))
        simulation_deltas: dict[str, np.ndarray] = {}
        for cand, fit in fits:
            if isinstance(cand, ProjectionCandidate):
                continue
            delta = np.nan_to_num(cand.delta(runner, base, fit, h))
            if EFFECTS[cand.effect].stochastic:
                delta[:] = 0.0  # expected pose unchanged, as for the corners
            simulation_deltas[cand.effect] = delta
            off_h += delta
        corner_h, stats_h, det_h = self._simulation_changes(fits, h)
        proj_record = None
        if projection is not None:
            joint, fit = projection
            h_shifted = dataclasses.replace(h, sim_corners=h.sim_corners + corner_h)
            proj_record = (joint, fit, h_shifted)
            off_h += np.nan_to_num(joint.delta(rig, base, fit, h_shifted))
            corner_h = corner_h + np.nan_to_num(joint.corner_shift(rig, base, fit.extra["x"], h))
        pred = h.sim_err + off_h
        has_evidence = h.real_stats is not None and stats_h is not None
        return Scored(
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
            proj_record,
            simulation_deltas,
            image_misfits(h.real_stats, h.sim_stats),
            image_misfits(h.real_stats, h.sim_stats + stats_h if has_evidence else None),
            detection_score(h.real_detected, h.sim_detected) if has_evidence else 0.0,
            detection_score(h.real_detected, np.clip(h.sim_detected + det_h, 0.0, 1.0))
            if has_evidence
            else 0.0,
            h,
            self.corner_unit_px,
            h.sim_corners + corner_h,
            h.sim_stats + stats_h if has_evidence else None,
            np.clip(h.sim_detected + det_h, 0.0, 1.0) if has_evidence else None,
        )

    def rank(self, candidates, significant: bool) -> list[Scored]:
        """Fit and score every candidate alone; projection ones only when no gap is significant.

        Ranked on the combined held-out misfit of all evidence (:attr:`Scored.evidence_after`:
        detected corners, image statistics, detections, each in units of its smallest relevant
        difference); among indistinguishable ones (:func:`equivalent_models`) the simpler first.
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
        """Simplify a model while it explains the held-out evidence as well.

        Effects are dropped, or projection effects swapped for ones with fewer parameters, while
        the model stays :func:`as_good` as ``scored`` on every evidence channel.
        """
        reference = scored
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
            ok = [o for o in options if as_good(o, reference)]
            if not ok:
                return scored
            scored = min(ok, key=lambda s: (s.n_params, s.evidence_after))

    def select(self, ranking: list[Scored], max_effects: int = 3) -> Scored | None:
        """Greedy forward search with joint refits, simplified after every step.

        An effect is added while the combined held-out misfit falls and some evidence channel
        improves distinguishably (:func:`improves`); the model is then simplified
        (:meth:`simplify`) and pruned (:meth:`prune`). Effects are returned most important
        first: by how much their removal worsens the combined held-out evidence (an effect may
        matter most for the image evidence and move no pose: it is then also :meth:`minor`).
        """
        if not ranking or not improves_on_nothing(ranking[0]):
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
            gain = best.evidence_after < current.evidence_after and improves(best, current)
            if not gain:
                break  # no distinguishable improvement
            simpler = self.simplify(best, pool)
            if frozenset(simpler.effects) in seen:
                break  # simplified back to a model already visited
            current = simpler
            seen.add(frozenset(current.effects))
        current = self.prune(current)
        if len(current.fits) > 1:
            model = [c for c, _ in current.fits]
            loss = {
                c.effect: self.evaluate(tuple(m for m in model if m is not c)).evidence_after
                for c in model
            }
            current = dataclasses.replace(
                current, fits=sorted(current.fits, key=lambda cf: -loss[cf[1].effect])
            )
        return current

    def prune(self, scored: Scored) -> Scored:
        """Drop effects that move no pose by a relevant amount and are not clearly seen.

        An effect whose :meth:`contributions` is below 1 is dropped only when the model without
        it still explains the held-out evidence as well (:func:`as_good`); otherwise it stays
        as a *minor* effect (seen in the corners or images, no pose impact beyond the floor).
        Comparing the evidence, never letting the pose criterion alone swap the explanation, is
        what
        keeps a refitted look-alike (a tag print scale soaking up a focal-length change) from
        replacing the effect that the corners single out.
        """
        while len(scored.fits) > 1:
            weight = self.contributions(scored)
            options = []
            for effect in (e for e, w in weight.items() if w < 1.0):
                reduced = self.evaluate(tuple(c for c, _ in scored.fits if c.effect != effect))
                if as_good(reduced, scored):
                    options.append(reduced)
            if not options:
                return scored
            scored = min(options, key=lambda o: o.evidence_after)
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
        out = dict(scored.simulation_deltas)
        if scored.projection is not None:
            joint, fit, held = scored.projection
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
        """Other models tried that explain the held-out evidence indistinguishably from ``chosen``.

        Only models within :func:`equivalent_models` on every channel are listed (a model that is
        clearly better or worse is not a look-alike). Supersets of ``chosen`` are left out: that
        an extra effect changes nothing is no news.
        """
        same = [
            s
            for s in self._evaluated.values()
            if not set(chosen.effects) <= set(s.effects)  # not the choice plus extras
            and equivalent_models(s, chosen)
        ]
        return [
            {
                "effects": s.effects,
                "n_params": s.n_params,
                "heldout_corner_gap_after_px": s.corner_after,
                "heldout_evidence_after": s.evidence_after,
                "heldout_gap_after": s.after,
            }
            for s in sorted(same, key=lambda s: (s.n_params, s.evidence_after))[:limit]
        ]


def bootstrap_reductions(
    scored: Scored, axes: np.ndarray, resamples: int = 1000, seed: int = 0, level: float = 0.9
) -> dict[str, list[float]]:
    """Bootstrap intervals of a scored model's pose-gap and evidence reductions.

    The scored items are resampled with replacement ``resamples`` times; each time the pose gap
    (:func:`gap_score` on ``axes``) and the combined evidence misfit are recomputed before and
    after. Returns the central ``level`` interval of each relative reduction.
    """
    h = scored.items
    rng = np.random.default_rng(seed)
    pose, evidence = [], []
    for _ in range(resamples):
        i = rng.integers(0, len(h), len(h))
        before = gap_score(h.real_err[i], h.sim_err[i], h.scale, axes)
        after = gap_score(h.real_err[i], scored.prediction[i], h.scale, axes)
        pose.append(1.0 - after / before if before > 0 else 0.0)
        channels = []
        for pred_c, pred_s, pred_d in (
            (h.sim_corners, h.sim_stats, h.sim_detected),
            (scored.corners_pred, scored.stats_pred, scored.detected_pred),
        ):
            pred_e = h.sim_err if pred_c is h.sim_corners else scored.prediction
            head = [
                _finite(corner_score(h.real_corners[i], pred_c[i])) / scored.corner_unit_px,
                _finite(gap_score(h.real_err[i], pred_e[i], h.scale)),
            ]
            if pred_s is not None and h.real_stats is not None:
                head.append(detection_score(h.real_detected[i], pred_d[i]))
                head += list(image_misfits(h.real_stats[i], pred_s[i]))
            channels.append(_rss(np.asarray(head)))
        evidence.append(1.0 - channels[1] / channels[0] if channels[0] > 0 else 0.0)
    q = [(1 - level) / 2 * 100, (1 + level) / 2 * 100]
    return {
        "pose_reduction": [float(v) for v in np.nanpercentile(pose, q)],
        "evidence_reduction": [float(v) for v in np.nanpercentile(evidence, q)],
    }
