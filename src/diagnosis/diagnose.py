"""Diagnose the sim-to-real gap: where it lies, which effect causes it, how far it shrinks.

Steps (docs/conventions.md §5):

1. simulate the real dataset's configurations with the experiment (cached), camera = the real
   calibration (:mod:`simgap.diagnosis.items`);
2. **where**: the gap field with its noise, per-axis significance, regions, and the scatter,
   detection and image-evidence tests (:mod:`simgap.diagnosis.where`);
3. **which**: the comparable items are split into fit, choose and measure splits; every
   candidate effect is fitted on the fit split and scored on the choose split on all evidence;
   a ranking; a greedy combination while some evidence channel improves distinguishably, with
   the model simplified and pruned after every step (:class:`simgap.analysis.search._selection.
   ModelSearch`); ``unexplained`` evidence when the chosen model leaves it;
4. **how far**: the chosen model's gap before and after on the measure split, per axis, with a
   bootstrap interval, confirmed by re-running the full pipeline (re-render) with the fitted
   effects.

The pipeline is reached only through a :class:`simgap.pipeline.simulator.Simulator` given by the
caller (the CLI, the blind validation); the result is a
:class:`simgap.diagnosis.result.DiagnosisResult` (``result.json``), and what the report draws beyond
it a :class:`simgap.diagnosis.diagnosis_files.DiagnosisEvidence` (:meth:`Diagnosis.evidence`,
``evidence.nc``).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import xarray as xr

from simgap.analysis import gap as gapmod
from simgap.analysis.candidates import CANDIDATES, Candidate, SimulationCandidate
from simgap.analysis.gap import corner_unit, gap_score, median_abs_gap
from simgap.analysis.search import (
    ModelSearch,
    Scored,
    bootstrap_reductions,
    corner_effect_alone,
    stands_in_for,
)
from simgap.core.axes import AXES
from simgap.core.progress import ProgressCallback, Steps
from simgap.diagnosis.camera_signatures import edge_offset, pipeline_signatures
from simgap.diagnosis.diagnosis_files import (
    SPLITS,
    DiagnosisEvidence,
    GapEvidence,
    ImageStatEvidence,
    ItemEvidence,
)
from simgap.diagnosis.items import (
    NoiseShift,
    build_items,
    demosaicing_from_attrs,
    item_distances,
    repeats_of_simulation,
    response_from_attrs,
    simulation_experiment,
    split_items,
    subsample,
    with_noise_shift,
    with_propagated_noise,
    with_render_seeds,
)
from simgap.diagnosis.result import (
    Combined,
    Confirmed,
    Demosaicing,
    DiagnosisResult,
    EquivalentModel,
    Finding,
    RankedEffect,
    Scores,
    Selection,
    Split,
    per_axis,
)
from simgap.diagnosis.settings import DiagnoseSettings
from simgap.diagnosis.sim_runner import SimRunner
from simgap.diagnosis.telling_poses import corner_difference_px, telling_poses
from simgap.diagnosis.where import unexplained_evidence, where_summary
from simgap.pipeline.experiment import Experiment
from simgap.pipeline.simulator import Simulator
from simgap.results.contract import check_dataset


def demosaicing_result(real: xr.Dataset) -> Demosaicing | None:
    """The capture's demosaicing as the result records it (None where its frames show none)."""
    cfa = demosaicing_from_attrs(real)
    if cfa is None or cfa.layout is None or cfa.method is None:
        return None
    return Demosaicing(
        layout=cfa.layout,
        method=cfa.method,
        residual_ratio=cfa.ratio,
        transfer_gamma=cfa.transfer_gamma,
    )


class Diagnosis:
    """State of one diagnosis run (see module docstring).

    Parameters
    ----------
    real : xarray.Dataset
        The real dataset.
    sim : xarray.Dataset
        Its simulation under ``exp`` (same configurations).
    exp : Experiment
        The simulation experiment (:func:`simgap.diagnosis.items.simulation_experiment`).
    simulator : Simulator
        Re-runs variant states of ``exp`` for candidate fits and the confirmation.
    settings : DiagnoseSettings
        Splits, subsample sizes and thresholds.
    progress : ProgressCallback, optional
        Told the progress of the fits, the model search and the confirmation (default: silent).
    """

    def __init__(
        self,
        real: xr.Dataset,
        sim: xr.Dataset,
        exp: Experiment,
        simulator: Simulator,
        settings: DiagnoseSettings,
        progress: ProgressCallback | None = None,
    ) -> None:
        self.settings = settings
        real = repeats_of_simulation(real, sim)
        self.base = exp.variant_states()[0][1]
        self.rig = exp.rig_model
        converged = self.base.scene.quality.mode == "converged"  # its repeats measure no noise
        #: the pose shift the capture's corner noise gives the converged simulation (None: path
        #: traced, whose own render noise shifts its poses)
        self.noise_shift: NoiseShift | None = None
        if converged:
            sim, self.noise_shift = with_noise_shift(real, sim, self.rig, self.base)
        self.real, self.sim, self.exp = real, sim, exp
        self.field = gapmod.gap_field(real, sim)
        unit_px = corner_unit(real.reproj_px.isel(variant=0).values)
        self.items = build_items(real, sim, self.field)
        #: corner noise propagated to each item's pose noise (px; None: not)
        self.propagated_px: float | None = None
        if converged:
            self.propagated_px = unit_px / np.sqrt(2.0)
            self.items = with_propagated_noise(self.items, self.propagated_px, self.rig, self.base)
        self.runner = SimRunner(exp, simulator)
        fit, choose, measure = split_items(
            len(self.items), settings.fit_fraction, settings.choose_fraction, settings.seed
        )
        #: item indices of the fit, choose and measure splits
        self.fit_index, self.measure_index = fit, measure
        self.choose_index = subsample(choose, settings.max_choose_items, settings.seed)
        #: errors (m, rad) with the chosen effects, per item: the measure split's from the fast
        #: model (:meth:`combined`; NaN elsewhere)
        self.fitted_errors: np.ndarray | None = None
        #: errors (m, rad) of every item re-rendered with the chosen effects (:meth:`confirm`)
        self.confirmed_errors: np.ndarray | None = None
        self.axis_gaps = gapmod.axis_summary(self.field)
        #: axes where the gap is significant: the pose gap is scored on them
        self.significant_axes = np.array([self.axis_gaps[a].significant for a in AXES])
        self.search = ModelSearch(
            self.rig,
            self.base,
            self.items,
            fit_index=self.fit_index,
            choose_index=self.choose_index,
            sim_fit_index=subsample(fit, settings.max_sim_fit_items, settings.seed),
            significant_axes=self.significant_axes,
            runner=self.runner,
            corner_unit_px=unit_px,
            steps=Steps(progress),
        )

    def confirm(self, chosen: Scored) -> Confirmed:
        """Re-run the pipeline (re-render) with all selected effects; score the measure split.

        Every item is re-rendered (:attr:`confirmed_errors`, for the report in mm and mrad); the
        scores are those of the measure split's items, which neither fitted nor chose the model.
        """
        state = self.base
        for cand, fit in chosen.fits:
            state = cand.apply(state, fit.params)
        h = self.items.subset(self.measure_index)
        t0 = time.perf_counter()
        self.search.steps.start("confirmation re-render", len(self.items))
        errors = self.runner.errors(state, self.items, self.search.steps.advance)
        if self.noise_shift is not None:  # as the simulation's own errors (with_noise_shift)
            errors = errors + np.nan_to_num(self.noise_shift.at(self.items))
        self.confirmed_errors = errors
        pred = errors[self.measure_index]
        before = float(gap_score(h.real_err, h.sim_err, h.scale, self.significant_axes))
        after = float(gap_score(h.real_err, pred, h.scale, self.significant_axes))
        return Confirmed(
            items=len(h),
            pose_gap_after=after,
            pose_gap_reduction=1.0 - after / before if before > 0 else 0.0,
            median_abs_gap_after=per_axis(median_abs_gap(h.real_err, pred)),
            seconds=time.perf_counter() - t0,
        )

    def selection(self, chosen: Scored, ranking: list[Scored]) -> Selection:
        """The chosen model's findings and its scores on the choose split.

        A minor geometric or calibration finding carries the effects that explain the evidence
        as well in its place (:meth:`simgap.analysis.search.ModelSearch.look_alikes`, from
        ``ranking``'s effects); the models with them are tried first, so that the look-alikes
        listed with their telling poses include them.
        """
        weight = self.search.contributions(chosen)
        minor = set(self.search.minor(chosen))
        alikes = self.search.look_alikes(chosen, ranking)
        return Selection(
            findings=[
                Finding(
                    effect=fit.effect,
                    params=fit.params,
                    pose_contribution=weight[fit.effect],
                    minor=fit.effect in minor,
                    at_bound=list(fit.extra.get("at_bound", ())),
                    look_alikes=list(alikes.get(fit.effect, ())),
                )
                for _, fit in chosen.fits
            ],
            n_params=chosen.n_params,
            items=len(self.choose_index),
            scores=Scores.of(chosen),
            equivalent_models=[
                self.with_telling_poses(chosen, alternative)
                for alternative in equivalent_alternatives(chosen, self.search.tried)
            ],
        )

    def with_telling_poses(self, chosen: Scored, other: Scored) -> EquivalentModel:
        """A look-alike as the result lists it, with the poses that would tell it apart.

        Its largest corner difference from ``chosen`` over the capture's poses, and the grid
        poses where the two differ most (:mod:`simgap.diagnosis.telling_poses`).
        """
        own = corner_difference_px(self.rig, self.base, chosen, other, self.items)
        return dataclasses.replace(
            equivalent_model(other),
            capture_difference_px=float(np.max(own)) if own.size else None,
            telling_poses=telling_poses(self.rig, self.base, chosen, other),
        )

    def evidence(self) -> DiagnosisEvidence:
        """What the report draws beyond the result (``evidence.nc``): items, gap, image statistics.

        Per item its splits and its real, simulated, fitted and confirmed errors as they stand
        after :meth:`combined` and :meth:`confirm`; the gap and the image statistics of
        :attr:`real` against :attr:`sim`.
        """
        membership = np.zeros((len(self.items), len(SPLITS)), bool)
        splits = {"fit": self.fit_index, "choose": self.choose_index, "measure": self.measure_index}
        for k, name in enumerate(SPLITS):
            membership[splits[name], k] = True
        items = ItemEvidence(
            tag=self.items.tag,
            p=self.items.p,
            theta_rad=self.items.theta,
            distance_m=item_distances(self.items, self.rig),
            in_split=membership,
            real_error=self.items.real_err,
            simulated_error=self.items.sim_err,
            fitted_error=self.fitted_errors,
            confirmed_error=self.confirmed_errors,
        )
        return DiagnosisEvidence(
            items=items,
            gap=GapEvidence.of(self.real, self.sim),
            image_stats=ImageStatEvidence.of(self.real, self.sim),
        )

    def combined(self, chosen: Scored) -> Combined:
        """The chosen model on the measure split, with bootstrap intervals of its reductions."""
        projection = chosen.projection[:2] if chosen.projection else None
        measured = self.search.score(chosen.fits, projection, self.measure_index)
        self.fitted_errors = np.full_like(self.items.real_err, np.nan)
        self.fitted_errors[self.measure_index] = measured.items_and_prediction()[1].error
        interval = bootstrap_reductions(measured, self.significant_axes, seed=self.settings.seed)
        return Combined(
            items=len(self.measure_index),
            scores=Scores.of(measured),
            pose_gap_reduction_interval_90=interval.pose_gap,
            evidence_reduction_interval_90=interval.evidence,
        )


def diagnose(
    real: xr.Dataset,
    exp: Experiment,
    simulator: Simulator | Path,
    settings: DiagnoseSettings | None = None,
    candidates: list[Candidate] | None = None,
    progress: ProgressCallback | None = None,
) -> tuple[DiagnosisResult, Diagnosis]:
    """Run the whole diagnosis; return its result and the diagnosis state.

    Parameters
    ----------
    real : xarray.Dataset
        The real dataset (``simgap ingest``).
    exp : Experiment
        The simulation; restricted to ``real``'s configurations and calibration before it runs.
    simulator : Simulator or Path
        How to simulate, or a cache folder for ``Simulator(folder)`` (in-process scheduler).
    settings : DiagnoseSettings, optional
        Splits, subsample sizes and thresholds (default: :class:`DiagnoseSettings`).
    candidates : list, optional
        Candidate effects, projection or simulation (default: the whole catalogue,
        :data:`simgap.analysis.candidates.CANDIDATES`). A simulation effect is kept only where
        the capture shows its signature
        (:meth:`simgap.analysis.candidates.SimulationCandidate.signature_shown`).
    progress : ProgressCallback, optional
        Told the progress of every step after the simulation (whose progress is the
        simulator's): ``fitting candidates`` (one unit per candidate), ``model search`` (one per
        model fitted, total unknown) and ``confirmation re-render`` (one per item). Default: silent.

    Raises
    ------
    simgap.results.contract.DatasetError
        Before any simulation, when ``real`` does not follow the result dataset contract.
    """
    check_dataset(real, required=("error", "detected", "visible", "corners"))
    settings = settings or DiagnoseSettings()
    if not isinstance(simulator, Simulator):
        simulator = Simulator(Path(simulator))
    t0 = time.perf_counter()
    sim_exp = settings.simulation(simulation_experiment(real, exp))
    seeds = settings.render_seeds(real.sizes["p"] * real.sizes["theta"])
    sim = simulator.dataset(with_render_seeds(sim_exp, seeds))
    d = Diagnosis(real, sim, sim_exp, simulator, settings, progress)
    where = where_summary(d.real, d.sim, d.field, d.axis_gaps)
    if candidates is None:
        candidates = list(CANDIDATES.values())
    # a simulation effect is a candidate only where the capture shows its signature: one of
    # its own image statistics differs significantly (the where step, over every comparable
    # tag; the measure split's pose gap, on which the reduction is measured, plays no part in
    # it), or for a laminate the ink-to-paper ratios of those tags call for one; the camera's
    # pipeline moving the marker edges only where the markers' sizes show an edge offset
    candidates = [
        c
        for c in candidates
        if not isinstance(c, SimulationCandidate)
        or c.signature_shown(where.image_tests, d.runner, d.items)
    ]
    ranking = d.search.rank(candidates, where.significant) if len(d.items) >= 2 else []
    # where nothing differs significantly, only an effect the corners single out is a finding
    # (a calibration file's wrong distortion that moves no pose beyond its noise)
    chosen = d.search.select(ranking) if where.significant else corner_effect_alone(ranking)
    refused = d.search.refused_geometry
    result = DiagnosisResult(
        where=where,
        ranking=[RankedEffect.of(s) for s in ranking],
        on_bound=[RankedEffect.of(s) for s in d.search.on_bound],
        selection=d.selection(chosen, ranking) if chosen else None,
        unexplained_evidence=unexplained_evidence(chosen, where, settings)
        if where.significant
        else [],
        refused_geometry=None if refused is None else equivalent_model(refused),
        split=Split(
            fit=len(d.fit_index),
            choose=len(d.choose_index),
            measure=len(d.measure_index),
            seed=settings.seed,
        ),
        render_seeds=seeds,
        simulation_render=f"{sim_exp.render.mode} {sim_exp.render.spp} spp",
        demosaicing=demosaicing_result(real),
        measured_response=response_from_attrs(real) is not None,
        camera_pipeline=pipeline_signatures(d.real, d.sim),
        edge_offset=edge_offset(d.items),
        propagated_corner_noise_px=d.propagated_px,
        noise_shift_corner_px=None if d.noise_shift is None else d.noise_shift.corner_px,
    )
    if refused is not None:
        result.unexplained_evidence.append("corners")
    if chosen is not None:
        result.combined = d.combined(chosen)
        if settings.confirm:
            result.confirmed = d.confirm(chosen)
    result.seconds = time.perf_counter() - t0
    return result, d


def equivalent_alternatives(chosen: Scored, tried: list[Scored], limit: int = 5) -> list[Scored]:
    """Models of ``tried`` that explain the choose split's evidence like ``chosen``.

    Only models that stand in for it (:func:`~simgap.analysis.search.stands_in_for`: within
    :func:`~simgap.analysis.search.equivalent_models` on every channel, and geometry no worse on
    the cross-fit folds) are listed (a model that is clearly better or worse is not a
    look-alike). Supersets of ``chosen`` are left out: that
    an extra effect changes nothing is no news. Simplest first, each set of effects once (the
    search may have scored one set in two orders).
    """
    same: dict[frozenset[str], Scored] = {}
    for s in sorted(tried, key=lambda s: (s.n_params, s.evidence_after)):
        if set(chosen.effects) <= set(s.effects):  # not the choice plus extras
            continue
        if stands_in_for(s, chosen):
            same.setdefault(frozenset(s.effects), s)
    return list(same.values())[:limit]


def equivalent_model(scored: Scored) -> EquivalentModel:
    """A scored model as the result lists it: its effects, parameter count and scores."""
    return EquivalentModel(
        effects=scored.effects, n_params=scored.n_params, scores=Scores.of(scored)
    )
