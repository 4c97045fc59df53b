"""Diagnose the sim-to-real gap: where it lies, which effect causes it, how far it shrinks.

Steps (DESIGN §5):

1. simulate the real dataset's configurations with the experiment (cached), camera = the real
   calibration (:mod:`simgap.diagnosis.items`);
2. **where**: the gap field with its noise, per-axis significance, regions, detection rates
   (:mod:`simgap.diagnosis.where`);
3. **which**: every candidate effect is fitted on a training split of the comparable
   configurations and scored on the held-out ones; a ranking; a greedy combination while the
   held-out gap falls; ``unexplained`` when nothing helps beyond noise;
4. **how far**: held-out gap before and after, per axis, confirmed by re-running the full
   pipeline (re-render) with the fitted effects.

The pipeline is reached only through a :class:`simgap.pipeline.simulator.Simulator` given by the
caller (the CLI, the blind validation); ``result.json`` is written by
:mod:`simgap.diagnosis.result_json`.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from simgap.analysis import gap as gapmod
from simgap.analysis.appearance import signature_significant
from simgap.analysis.candidates import CANDIDATES
from simgap.analysis.channels import corner_unit, root_sum_square
from simgap.analysis.fitting import gap_score, median_abs_gap
from simgap.analysis.scored import Scored, bootstrap_reductions
from simgap.analysis.scoring import equivalent_models
from simgap.analysis.selection import ModelSearch
from simgap.analysis.thresholds import MINOR_CONTRIBUTION
from simgap.core.axes import AXES
from simgap.diagnosis.items import (
    build_items,
    repeats_of_simulation,
    simulation_experiment,
    split_items,
    subsample,
    with_render_seeds,
)
from simgap.diagnosis.result_json import jsonable
from simgap.diagnosis.settings import DiagnoseSettings
from simgap.diagnosis.sim_runner import SimRunner
from simgap.diagnosis.where import unexplained_evidence, where_summary
from simgap.pipeline.experiment import Experiment
from simgap.pipeline.simulator import Simulator
from simgap.results.dataset import check_dataset


def _per_axis(values: np.ndarray) -> dict[str, float]:
    return dict(zip(AXES, map(float, values), strict=True))


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
    """

    def __init__(
        self,
        real: xr.Dataset,
        sim: xr.Dataset,
        exp: Experiment,
        simulator: Simulator,
        settings: DiagnoseSettings,
    ) -> None:
        self.settings = settings
        real = repeats_of_simulation(real, sim)
        self.real, self.sim, self.exp = real, sim, exp
        self.field = gapmod.gap_field(real, sim)
        self.items = build_items(real, sim, self.field)
        self.runner = SimRunner(exp, simulator)
        self.base = exp.variant_states()[0][1]
        self.rig = exp.rig_model
        fit, choose, report = split_items(
            len(self.items), settings.fit_fraction, settings.choose_fraction, settings.seed
        )
        #: item indices of the fit, choose and report splits
        self.fit_index, self.report_index = fit, report
        self.choose_index = subsample(choose, settings.max_choose_items, settings.seed)
        self.axis_gaps = gapmod.axis_summary(self.field)
        #: axes where the gap is significant: the pose gap is scored on them
        self.significant_axes = np.array([self.axis_gaps[a]["significant"] for a in AXES])
        self.search = ModelSearch(
            self.rig,
            self.base,
            self.items,
            fit_index=self.fit_index,
            choose_index=self.choose_index,
            sim_fit_index=subsample(fit, settings.max_sim_fit_items, settings.seed),
            significant_axes=self.significant_axes,
            runner=self.runner,
            corner_unit_px=corner_unit(real.reproj_px.isel(variant=0).values),
        )

    def confirm(self, chosen: Scored) -> dict[str, Any]:
        """Re-run the pipeline (re-render) with all selected effects; report-split gap after."""
        state = self.base
        for cand, fit in chosen.fits:
            state = cand.apply(state, fit.params)
        h = self.items.subset(self.report_index)
        t0 = time.perf_counter()
        pred = self.runner.errors(state, h)
        return {
            "heldout_gap_after": gap_score(h.real_err, pred, h.scale, self.significant_axes),
            "heldout_gap_after_per_axis": _per_axis(median_abs_gap(h.real_err, pred)),
            "seconds": time.perf_counter() - t0,
            "configurations": len(h),
        }

    def combined(self, chosen: Scored) -> dict[str, Any]:
        """The ``combined`` record of ``result.json``: the chosen model on the report split."""
        weight = self.search.contributions(chosen)
        projection = chosen.projection[:2] if chosen.projection else None
        reported = self.search.score(chosen.fits, projection, self.report_index)
        interval = bootstrap_reductions(reported, self.significant_axes, seed=self.settings.seed)
        return {
            "effects": [
                {
                    "effect": fit.effect,
                    "params": jsonable(fit.params),
                    "pose_contribution": weight[fit.effect],
                    "minor": weight[fit.effect] < MINOR_CONTRIBUTION,
                }
                for _, fit in chosen.fits
            ],
            "n_params": chosen.n_params,
            "measured_on": "report split: configurations that neither fitted nor chose the model",
            "configurations": len(self.report_index),
            "heldout_gap_before": reported.pose_gap_before,
            "heldout_gap_after": reported.pose_gap_after,
            "reduction": reported.pose_gap_reduction,
            "reduction_interval_90": list(interval.pose_gap),
            "heldout_corner_gap_before_px": reported.corner_gap_before_px,
            "heldout_corner_gap_after_px": reported.corner_gap_after_px,
            "heldout_evidence_before": reported.evidence_before,
            "heldout_evidence_after": reported.evidence_after,
            "evidence_reduction": reported.evidence_reduction,
            "evidence_reduction_interval_90": list(interval.evidence),
            "heldout_gap_before_per_axis": _per_axis(reported.median_abs_gap_before),
            "heldout_gap_after_per_axis": _per_axis(reported.median_abs_gap_after),
            "choice": {
                "configurations": len(self.choose_index),
                "heldout_evidence_before": chosen.evidence_before,
                "heldout_evidence_after": chosen.evidence_after,
                "heldout_gap_after": chosen.pose_gap_after,
            },
            "equivalent_models": equivalent_alternatives(chosen, self.search.tried),
        }


def diagnose(
    real: xr.Dataset,
    exp: Experiment,
    simulator: Simulator | Path,
    settings: DiagnoseSettings | None = None,
    candidates: list | None = None,
) -> tuple[dict[str, Any], Diagnosis]:
    """Run the whole diagnosis; return the ``result.json`` mapping and the diagnosis state.

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
        Candidate effects, projection or appearance (default: the whole catalogue,
        :data:`simgap.analysis.candidates.CANDIDATES`).
        An appearance effect is kept only where one of its own image statistics differs
        significantly (:func:`simgap.analysis.appearance.signature_significant`).

    Raises
    ------
    simgap.results.dataset.DatasetError
        Before any simulation, when ``real`` does not follow the result dataset contract.
    """
    check_dataset(real, required=("error", "detected", "visible", "corners"))
    settings = settings or DiagnoseSettings()
    if not isinstance(simulator, Simulator):
        simulator = Simulator(Path(simulator))
    t0 = time.perf_counter()
    sim_exp = simulation_experiment(real, exp)
    seeds = settings.render_seeds(real.sizes["p"] * real.sizes["theta"])
    sim = simulator.dataset(with_render_seeds(sim_exp, seeds))
    d = Diagnosis(real, sim, sim_exp, simulator, settings)
    where = where_summary(d.real, d.sim, d.field, d.axis_gaps)
    significant = where["significant"]
    if candidates is None:
        candidates = list(CANDIDATES.values())
    # an appearance effect is a candidate only where one of its own image statistics differs
    # significantly (the where step, over every comparable tag; the report split's pose gap,
    # on which the reduction is measured, plays no part in it)
    candidates = [c for c in candidates if signature_significant(c, where["image_tests"])]
    ranking = d.search.rank(candidates, significant) if len(d.items) >= 2 else []
    chosen = d.search.select(ranking) if significant else None
    left = unexplained_evidence(chosen, where, settings) if significant else []
    result: dict[str, Any] = {
        "ranking": [ranking_record(s) for s in ranking],
        "selected": chosen.effects if chosen else [],
        "minor": d.search.minor(chosen) if chosen else [],
        "unexplained": bool(significant and left),
        "unexplained_evidence": left,
        "where": jsonable(where),
        "split": {
            "train": int(len(d.fit_index)),
            "heldout": int(len(d.choose_index)),
            "report": int(len(d.report_index)),
            "seed": settings.seed,
        },
        "render_seeds": seeds,
    }
    if chosen is not None:
        result["combined"] = d.combined(chosen)
        if settings.confirm:
            conf = d.confirm(chosen)
            before = result["combined"]["heldout_gap_before"]
            conf["reduction"] = 1.0 - conf["heldout_gap_after"] / before if before > 0 else 0.0
            result["confirmed"] = conf
    result["seconds"] = time.perf_counter() - t0
    return result, d


def equivalent_alternatives(
    chosen: Scored, tried: list[Scored], limit: int = 5
) -> list[dict[str, Any]]:
    """Models of ``tried`` that explain the held-out evidence indistinguishably from ``chosen``.

    Only models within :func:`equivalent_models` on every channel are listed (a model that is
    clearly better or worse is not a look-alike). Supersets of ``chosen`` are left out: that
    an extra effect changes nothing is no news.
    """
    same = [
        s
        for s in tried
        if not set(chosen.effects) <= set(s.effects)  # not the choice plus extras
        and equivalent_models(s, chosen)
    ]
    return [
        {
            "effects": s.effects,
            "n_params": s.n_params,
            "heldout_corner_gap_after_px": s.corner_gap_after_px,
            "heldout_evidence_after": s.evidence_after,
            "heldout_gap_after": s.pose_gap_after,
        }
        for s in sorted(same, key=lambda s: (s.n_params, s.evidence_after))[:limit]
    ]


def ranking_record(s: Scored) -> dict[str, Any]:
    """JSON record of a single-effect model (ranking entry)."""
    cand, fit = s.fits[0]
    return {
        "effect": fit.effect,
        "params": fit.params,
        "heldout_gap_before": s.pose_gap_before,
        "heldout_gap_after": s.pose_gap_after,
        "reduction": s.pose_gap_reduction,
        "heldout_gap_all_axes_before": s.pose_gap_all_axes_before,
        "heldout_gap_all_axes_after": s.pose_gap_all_axes_after,
        "heldout_corner_gap_before_px": s.corner_gap_before_px,
        "heldout_corner_gap_after_px": s.corner_gap_after_px,
        "heldout_gap_before_per_axis": _per_axis(s.median_abs_gap_before),
        "heldout_gap_after_per_axis": _per_axis(s.median_abs_gap_after),
        "heldout_image_misfit_before": root_sum_square(s.image_misfit_before),
        "heldout_image_misfit_after": root_sum_square(s.image_misfit_after),
        "heldout_detection_mismatch_before": s.detection_mismatch_before,
        "heldout_detection_mismatch_after": s.detection_mismatch_after,
        "heldout_evidence_before": s.evidence_before,
        "heldout_evidence_after": s.evidence_after,
        "n_params": cand.n_params,
        "fit_seconds": fit.seconds,
        "stage": cand.kind,
    }
