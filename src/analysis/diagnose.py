"""Diagnose the sim-to-real gap: where it lies, which effect causes it, how far it shrinks.

Steps (DESIGN §5):

1. simulate the real dataset's configurations with the experiment (cached), camera = the real
   calibration;
2. **where**: the gap field with its noise, per-axis significance, regions, detection rates;
3. **which**: every candidate effect is fitted on a training split of the comparable
   configurations and scored on the held-out ones; a ranking; a greedy combination while the
   held-out gap falls; ``unexplained`` when nothing helps beyond noise;
4. **how far**: held-out gap before and after, per axis, confirmed by re-running the full
   pipeline (re-render) with the fitted effects.
"""

from __future__ import annotations

import dataclasses
import json
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from simgap.analysis import gap as gapmod
from simgap.analysis.dataset import check_dataset
from simgap.analysis.fitting import (
    Items,
    default_candidates,
    gap_rms_per_axis,
    gap_score,
)
from simgap.analysis.selection import ModelSearch, Scored
from simgap.atomic import atomic_write
from simgap.cache import Cache, content_hash
from simgap.effects import make_effect
from simgap.effects.state import VariantState
from simgap.experiment import Experiment

AXES = gapmod.AXES


@dataclass(frozen=True)
class DiagnoseSettings:
    """Settings of the diagnosis.

    Attributes
    ----------
    train_fraction : float
        Share of comparable configurations used to fit; the rest are held out for scoring.
    seed : int
        Seed of the split and the subsamples.
    max_sim_items : int
        Configurations used when fitting a candidate by simulation (training subsample).
    max_heldout_items : int
        Held-out configurations on which all candidates are ranked.
    min_gain : float
        Relative fall of the held-out gap needed to add another effect in the greedy search.
    explained_reduction : float
        Held-out gap reduction below which a significant gap is reported as unexplained.
    confirm : bool
        Re-run the full pipeline with the selected effects to confirm the reduction.
    """

    train_fraction: float = 0.6
    seed: int = 0
    max_sim_items: int = 40
    max_heldout_items: int = 80
    min_gain: float = 0.1
    explained_reduction: float = 0.3
    confirm: bool = True


def calibration_from_attrs(real: xr.Dataset):
    """The calibration a capture was ingested with (``calibration_yaml`` attr), or None."""
    import yaml

    from simgap.rig import CameraModel

    text = real.attrs.get("calibration_yaml")
    if not text:
        return None
    data = yaml.safe_load(text)
    keys = ("width", "height", "fx", "fy", "cx", "cy", "distortion")
    return CameraModel(**{k: (tuple(data[k]) if k == "distortion" else data[k]) for k in keys})


def simulation_experiment(real: xr.Dataset, exp: Experiment) -> Experiment:
    """``exp`` restricted to the real dataset's configurations, imaging with its calibration."""
    from simgap.config import to_mapping
    from simgap.experiment import Configurations

    rig = dict(exp.rig)
    cal = calibration_from_attrs(real)
    if cal is not None:
        rig["camera"] = to_mapping(cal)
    conf = Configurations(
        tuple(int(p) for p in real.p.values),
        tuple(round(float(np.rad2deg(t)), 6) for t in real.theta.values),
        tuple(int(t) for t in real.tag.values),
    )
    return dataclasses.replace(exp, rig=rig, configurations=conf, variants=(), grid={})


def build_items(real: xr.Dataset, sim: xr.Dataset, field: gapmod.GapField) -> Items:
    """The comparable (tag, p, theta) items with their errors and corners."""
    real, sim = gapmod.align(real, sim)
    idx = np.argwhere(field.comparable.values)
    tags, ps, thetas = real.tag.values, real.p.values, real.theta.values
    r_err = gapmod.mean_error(real).values
    s_err = gapmod.mean_error(sim).values
    r_c = real.corners.isel(variant=0).mean("repeat", skipna=True).values
    s_c = sim.corners.isel(variant=0).mean("repeat", skipna=True).values
    units = np.array([gapmod.PRACTICAL_FLOOR[gapmod.axis_unit(a)] for a in AXES])
    scale = np.maximum(field.sigma.values, units)
    return Items(
        tag=tags[idx[:, 0]],
        p=ps[idx[:, 1]],
        theta=thetas[idx[:, 2]],
        real_err=r_err[idx[:, 0], idx[:, 1], idx[:, 2]],
        sim_err=s_err[idx[:, 0], idx[:, 1], idx[:, 2]],
        real_corners=r_c[idx[:, 0], idx[:, 1], idx[:, 2]],
        sim_corners=s_c[idx[:, 0], idx[:, 1], idx[:, 2]],
        scale=scale,
    )


class SimRunner:
    """Runs variant states through the cached pipeline for a set of items (in process)."""

    def __init__(self, exp: Experiment, cache_dir: Path) -> None:
        from simgap.sweep import _assets_hash

        self.exp, self.cache = exp, Cache(cache_dir)
        self.rig = exp.rig_model
        self.tags = exp.configuration_axes()[2]
        self.assets = _assets_hash()
        self._pipes: dict[str, Any] = {}
        self._memo: dict[tuple, np.ndarray] = {}

    def pipeline(self, state: VariantState):
        """The (memoised) pipeline of a state."""
        from simgap.sweep import VariantPipeline

        key = content_hash(state)
        if key not in self._pipes:
            self._pipes[key] = VariantPipeline(
                self.rig, state, self.tags, self.exp.render.crop_margin_px, self.cache, self.assets
            )
        return self._pipes[key]

    def _results(self, state: VariantState, items: Items, field: str) -> np.ndarray:
        pipe = self.pipeline(state)
        reps = self.exp.repeats if state.image.stochastic else 1
        shape = (6,) if field == "error" else (4, 2)
        out = np.full((len(items),) + shape, np.nan)
        for i in range(len(items)):
            key = (pipe.scene_key, content_hash(state), int(items.p[i]), float(items.theta[i]))
            if key not in self._memo:
                runs = [pipe.run(int(items.p[i]), float(items.theta[i]), r, 0) for r in range(reps)]
                with warnings.catch_warnings():  # a tag never detected is all-NaN
                    warnings.simplefilter("ignore", RuntimeWarning)
                    self._memo[key] = {
                        f: np.nanmean(np.stack([getattr(x, f) for x in runs]), axis=0)
                        for f in ("error", "corners")
                    }
            out[i] = self._memo[key][field][self.tags.index(int(items.tag[i]))]
        return out

    def __call__(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-mean simulated errors (N, 6) of ``items`` under ``state`` (m, rad)."""
        return self._results(state, items, "error")

    def corners(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-mean detected corners (N, 4, 2) of ``items`` under ``state`` (px)."""
        return self._results(state, items, "corners")


def _split(n: int, fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    order = np.random.default_rng(seed).permutation(n)
    k = min(max(int(round(fraction * n)), 1), n - 1) if n > 1 else n
    return np.sort(order[:k]), np.sort(order[k:])


def _subsample(index: np.ndarray, k: int, seed: int) -> np.ndarray:
    if index.size <= k:
        return index
    return np.sort(np.random.default_rng(seed + 1).choice(index, k, replace=False))


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    return obj


class Diagnosis:
    """State of one diagnosis run (see module docstring)."""

    def __init__(
        self,
        real: xr.Dataset,
        exp: Experiment,
        cache_dir: Path,
        settings: DiagnoseSettings,
        scheduler=None,
    ):
        from simgap.sweep import run_experiment

        self.settings = settings
        self.real = real
        self.exp = simulation_experiment(real, exp)
        self.sim = run_experiment(self.exp, cache_dir, show_progress=True, scheduler=scheduler)
        self.field = gapmod.gap_field(real, self.sim)
        self.items = build_items(real, self.sim, self.field)
        self.runner = SimRunner(self.exp, cache_dir)
        self.base = self.exp.variant_states()[0][1]
        self.rig = self.exp.rig_model
        train, held = _split(len(self.items), settings.train_fraction, settings.seed)
        self.train = train
        self.held = _subsample(held, settings.max_heldout_items, settings.seed)
        self.sim_train = _subsample(train, settings.max_sim_items, settings.seed)
        self.where = gapmod.axis_summary(self.field)
        #: axes where the gap is significant: the held-out gap is scored on them
        self.axes = np.array([self.where[a]["significant"] for a in AXES])
        self.search = ModelSearch(
            self.rig,
            self.base,
            self.items,
            self.train,
            self.held,
            self.sim_train,
            self.axes,
            self.runner,
            settings.min_gain,
        )

    # ------------------------------------------------------------------ which

    # ------------------------------------------------------------------ how far

    def confirm(self, chosen: Scored) -> dict[str, Any]:
        """Re-run the pipeline (re-render) with all selected effects; held-out gap after."""
        state = self.base
        for _, fit in chosen.fits:
            state = make_effect(fit.effect, fit.params).apply(state)
        h = self.items.subset(self.held)
        t0 = time.perf_counter()
        pred = self.runner(state, h)
        return {
            "heldout_gap_after": gap_score(h.real_err, pred, h.scale, self.axes),
            "heldout_gap_after_per_axis": dict(
                zip(AXES, map(float, gap_rms_per_axis(h.real_err, pred)), strict=True)
            ),
            "seconds": time.perf_counter() - t0,
            "configurations": len(h),
        }


def diagnose(
    real: xr.Dataset,
    exp: Experiment,
    cache_dir: Path,
    settings: DiagnoseSettings = DiagnoseSettings(),
    candidates=None,
    scheduler: str | None = None,
) -> tuple[dict[str, Any], Diagnosis]:
    """Run the whole diagnosis; return the ``result.json`` mapping and the diagnosis state.

    Raises
    ------
    simgap.analysis.dataset.DatasetError
        Before any simulation, when ``real`` does not follow the result dataset contract.
    """
    check_dataset(real, required=("error", "detected", "visible", "corners"))
    t0 = time.perf_counter()
    d = Diagnosis(real, exp, cache_dir, settings, scheduler)
    axes = d.where
    significant = any(a["significant"] for a in axes.values())
    det = gapmod.detection_summary(d.field)
    where = {
        "axes": axes,
        "regions": [r for r in gapmod.region_summary(d.field) if r["significant"]],
        "detection": det,
        "significant": significant,
        "comparable_configurations": len(d.items),
    }
    ranking = (
        d.search.rank(candidates or default_candidates(), significant) if len(d.items) >= 2 else []
    )
    chosen = d.search.select(ranking) if significant else None
    explained = chosen is not None and chosen.reduction >= settings.explained_reduction
    result: dict[str, Any] = {
        "ranking": [s.record() for s in ranking],
        "selected": chosen.effects if explained else [],
        "unexplained": bool(significant and not explained),
        "where": _jsonable(where),
        "split": {"train": int(len(d.train)), "heldout": int(len(d.held)), "seed": settings.seed},
    }
    if chosen is not None and explained:
        weight = d.search.contributions(chosen)
        result["combined"] = {
            "effects": [
                {
                    "effect": fit.effect,
                    "params": _jsonable(fit.params),
                    "pose_contribution": weight[fit.effect],
                }
                for _, fit in chosen.fits
            ],
            "n_params": chosen.n_params,
            "heldout_gap_before": chosen.before,
            "heldout_gap_after": chosen.after,
            "reduction": chosen.reduction,
            "heldout_corner_gap_before_px": chosen.corner_before,
            "heldout_corner_gap_after_px": chosen.corner_after,
            "heldout_gap_before_per_axis": dict(
                zip(AXES, map(float, chosen.before_axes), strict=True)
            ),
            "heldout_gap_after_per_axis": dict(
                zip(AXES, map(float, chosen.after_axes), strict=True)
            ),
            "equivalent_models": d.search.alternatives(chosen),
        }
        if settings.confirm:
            conf = d.confirm(chosen)
            conf["reduction"] = 1.0 - conf["heldout_gap_after"] / chosen.before
            result["confirmed"] = conf
    result["seconds"] = time.perf_counter() - t0
    return result, d


def write_json(result: dict[str, Any], path: Path) -> Path:
    """Write ``result.json`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, json.dumps(_jsonable(result), indent=2))
