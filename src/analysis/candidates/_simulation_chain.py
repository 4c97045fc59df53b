"""A model's simulation effects fitted one after another, each on the simulation with those before.

The simulation (appearance) effects of a model are not independent: a capture exposed a stop
brighter clips the paper, and a clipped edge reads narrower, so a blur fitted on the nominal
simulation's edge widths comes out too small, and the pose gap its softness leaves is then filled
by geometric effects (measured on a development capture: a blur a third too small alone, within
10 % on the exposed simulation; docs/results/design_evidence.md#simulation_chain).
Each effect is therefore fitted on the simulation that already holds the effects before it in
:data:`FIT_ORDER`, the order in which their evidence is least confounded by the others: the paper
level first (exposure; a blur or a noise barely moves a level measured over a tag's paper), then a
light the simulation lacks (a sun, read from the paper levels against the way the tags face), then
the crushed shadows (a black level: the share of a tag at 0 DN depends on the exposure), then the
edge widths (blur, defocus; clipping narrows them, a glint barely moves them), the edges' offset
(the markers' size change at zero size, which a softness through the pipeline's levels makes too),
the glint of a laminate (ink and paper levels against view angle; a soft edge bleeds paper into
small tags' ink cells), the noise (sensor noise, whose excess over the simulation depends on its
levels and softness) and last the compression (JPEG, whose blockiness depends on everything before
it). With the laminate before the softness, a defocus fitted on the glinting simulation moved its
focus and the poses away from the real ones (measured on a development capture, same page).
A model's prediction is the simulation with all its effects at once, as a camera forms its image.
The order is a fitting order, not the camera's: an effect of the camera's image stage fitted
before a softness (exposure, black level before a blur or a defocus) acts in the camera on the
soft image, so it is fitted once more on the simulation with every other effect of the model
(:func:`refitted`).

A single effect is fitted on the nominal simulation, as before, so the ranking of single effects
does not change; the conditioned fits of later effects are memoised on the effects before them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from simgap.analysis.candidates._fitting import Fit, SimulationCandidate
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.gap import NOISE_STATS, Items
from simgap.effects import EFFECTS
from simgap.effects.state import VariantState

#: Order in which a model's simulation effects are fitted, each on the simulation with the ones
#: before it (see module docstring); effects not named here come after, in catalogue order.
FIT_ORDER = (
    "exposure",
    "sun",
    "black_level",
    "blur",
    "defocus",
    "edge_offset",
    "tag_gloss",
    "sensor_noise",
    "jpeg",
)


#: The softness effects, fitted after the camera's image-stage effects (exposure, black level)
#: but acting before them in the camera (optics, then the pipeline): an image-stage effect fitted
#: before one of them is fitted again beside it (:func:`refitted`).
SOFTNESS_EFFECTS = frozenset({"blur", "defocus"})


def in_fit_order(candidates: tuple[SimulationCandidate, ...]) -> list[SimulationCandidate]:
    """``candidates`` sorted by :data:`FIT_ORDER` (stable for effects it does not name)."""
    rank = {name: i for i, name in enumerate(FIT_ORDER)}
    return sorted(candidates, key=lambda c: rank.get(c.effect, len(FIT_ORDER)))


def refitted(fits: list[tuple[SimulationCandidate, Fit]], k: int) -> bool:
    """Whether the ``k``-th of a model's fits is made again beside all the others.

    An effect of the camera's image stage is fitted again on the simulation with every other
    effect of the model, those after it in :data:`FIT_ORDER` included, where one after it is a
    softness the optics put before the camera's pipeline (``blur``, ``defocus``): the share of
    a tag crushed to 0 DN, the levels and the noise the pipeline acts on are those of the soft
    image, which the first fit did not see (measured on a blind capture: a black level fitted on
    the sharp simulation came out a third of the truth, and the defocus beside it lost to black
    level and noise alone; docs/results/design_evidence.md#simulation_chain).
    """
    cand = fits[k][0]
    later = {c.effect for c, _ in fits[k + 1 :]}
    return EFFECTS[cand.effect].stage == "image" and bool(later & SOFTNESS_EFFECTS)


def conditioned(runner: Runner, base: VariantState, state: VariantState, items: Items) -> Items:
    """``items`` whose simulated image evidence is that of ``state`` instead of ``base``.

    The change from ``base`` to ``state`` (both run through ``runner``) is added to the items'
    own simulated image statistics, detections and corners (the evidence simulation effects
    are fitted on), so that the simulation's render noise and its repeats cancel as in every
    other prediction of the search.
    """
    out = dataclasses.replace(items)
    change = runner.corners(state, items) - runner.corners(base, items)
    out.sim_corners = items.sim_corners + np.nan_to_num(change)
    if items.sim_stats is not None:
        change = runner.stats(state, items) - runner.stats(base, items)
        out.sim_stats = items.sim_stats + np.nan_to_num(change)
    if items.sim_detected is not None:
        change = runner.detected(state, items) - runner.detected(base, items)
        out.sim_detected = np.clip(items.sim_detected + np.nan_to_num(change), 0.0, 1.0)
    return out


@dataclass
class SimulationChain:
    """Fits and runs a model's simulation effects in :data:`FIT_ORDER` (see module docstring).

    Attributes
    ----------
    runner : Runner or None
        Runs a state through the cached pipeline; needed only where a model has simulation
        effects.
    base : VariantState
        The simulation's state, to which effects are added.
    items : Items
        The items the simulation effects are fitted on (the fit split's subsample).
    """

    runner: Runner | None
    base: VariantState
    items: Items
    _fits: dict[tuple[str, ...], Fit] = field(default_factory=dict, repr=False)

    def _runner(self) -> Runner:
        """The runner; ValueError without one (simulation effects run the pipeline)."""
        if self.runner is None:
            raise ValueError("simulation effects need a runner of the pipeline; none was given")
        return self.runner

    def fit(
        self, candidates: tuple[SimulationCandidate, ...]
    ) -> list[tuple[SimulationCandidate, Fit]]:
        """Each candidate fitted on the simulation with the fitted ones before it, in fit order."""
        out: list[tuple[SimulationCandidate, Fit]] = []
        state = self.base
        for cand in in_fit_order(candidates):
            key = tuple(c.effect for c, _ in out) + (cand.effect,)
            if key not in self._fits:
                items = (
                    conditioned(self._runner(), self.base, state, self.items) if out else self.items
                )
                self._fits[key] = cand.fit(self._runner(), state, items)
            out.append((cand, self._fits[key]))
            state = cand.apply(state, self._fits[key].params)
        return [self._refit(out, k) if refitted(out, k) else f for k, f in enumerate(out)]

    def _refit(
        self, fits: list[tuple[SimulationCandidate, Fit]], k: int
    ) -> tuple[SimulationCandidate, Fit]:
        """The ``k``-th fit made again on the simulation with every other fitted effect."""
        cand = fits[k][0]
        key = ("refit", *(c.effect for c, _ in fits[:k]), cand.effect, "given")
        key += tuple(c.effect for c, _ in fits[k + 1 :])
        if key not in self._fits:
            others = [f for j, f in enumerate(fits) if j != k]
            state, _ = self.states(others)
            items = conditioned(self._runner(), self.base, state, self.items)
            self._fits[key] = cand.fit(self._runner(), state, items)
        return cand, self._fits[key]

    def states(
        self, fits: list[tuple[SimulationCandidate, Fit]]
    ) -> tuple[VariantState, VariantState]:
        """The simulation with all the fitted effects, and with the deterministic ones only.

        A stochastic effect (sensor noise) leaves the expected corners and poses where they are;
        one noisy realisation is no prediction of them (its evidence is the noise).
        """
        full = deterministic = self.base
        for cand, fit in fits:
            full = cand.apply(full, fit.params)
            if not EFFECTS[cand.effect].stochastic:
                deterministic = cand.apply(deterministic, fit.params)
        return full, deterministic

    def changes(
        self, fits: list[tuple[SimulationCandidate, Fit]], items: Items
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Changes the fitted effects make together on ``items``.

        Returns the change of detected corners (N, 4, 2) (px), of image statistics (N, S) (None
        without statistics) and of the detection rate (N,). A deterministic effect does not
        change the camera's noise: on a path-traced simulation the change of the noise
        statistics it makes is its render noise being smoothed, so there the noise statistics
        change only with a stochastic effect, by what it adds to the deterministic ones. A
        converged simulation has next to no render noise to smooth (0.13-0.28 DN between two
        seeds; a sticker that fell back to path tracing keeps that of 4x the samples, and only
        there does a smoothing effect read as less noise): every change of its noise statistics
        counts as the effect's own (a JPEG's blocks read as spatial noise: on a development
        capture the path-traced rule dropped a compression's rise of the converged simulation's
        paper noise to the capture's level, so a sensor noise took the compression's noise and
        the JPEG was left out; docs/results/design_evidence.md#simulation_chain).
        """
        base = self.base
        corners = np.zeros((len(items), 4, 2))
        stats = None if items.sim_stats is None else np.zeros_like(items.sim_stats)
        detected = np.zeros(len(items))
        if not fits:
            return corners, stats, detected
        runner = self._runner()
        full, deterministic = self.states(fits)
        stochastic = any(EFFECTS[c.effect].stochastic for c, _ in fits)
        corners = np.nan_to_num(runner.corners(deterministic, items) - runner.corners(base, items))
        if stats is not None:
            full_stats = runner.stats(full, items)
            stats = np.nan_to_num(full_stats - runner.stats(base, items))
            if base.scene.quality.mode != "converged":  # the noise is partly Monte Carlo
                noise = 0.0
                if stochastic:
                    smoothed = runner.stats(deterministic, items)[:, NOISE_STATS]
                    noise = np.nan_to_num(full_stats[:, NOISE_STATS] - smoothed)
                stats[:, NOISE_STATS] = noise
            detected = np.nan_to_num(runner.detected(full, items) - runner.detected(base, items))
        return corners, stats, detected

    def pose_deltas(
        self, fits: list[tuple[SimulationCandidate, Fit]], items: Items
    ) -> dict[str, np.ndarray]:
        """Each deterministic effect's change of the simulated errors (N, 6) (m, rad).

        Effects are added in fit order, each changing the simulation with those before it, so the
        changes sum to the model's; a stochastic effect's is zero (expected pose unchanged).
        """
        out: dict[str, np.ndarray] = {}
        state = self.base
        for cand, fit in fits:
            if EFFECTS[cand.effect].stochastic:
                out[cand.effect] = np.zeros((len(items), 6))
                continue
            out[cand.effect] = np.nan_to_num(cand.delta(self._runner(), state, fit, items))
            state = cand.apply(state, fit.params)
        return out
