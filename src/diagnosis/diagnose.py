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

from simgap.analysis import evidence
from simgap.analysis import gap as gapmod
from simgap.analysis.appearance import appearance_candidates
from simgap.analysis.fitting import (
    Items,
    default_candidates,
    gap_rms_per_axis,
    gap_score,
)
from simgap.analysis.image_evidence import repeat_median_stats
from simgap.analysis.scoring import SCORED_STATS, Scored, bootstrap_reductions, corner_unit
from simgap.analysis.selection import ModelSearch
from simgap.core.atomic import atomic_write
from simgap.effects import EFFECTS
from simgap.effects.state import VariantState
from simgap.pipeline.cache import Cache, content_hash
from simgap.pipeline.experiment import Experiment
from simgap.pose.image_stats import STAT_NAMES
from simgap.results.dataset import check_dataset

AXES = gapmod.AXES


@dataclass(frozen=True)
class DiagnoseSettings:
    """Settings of the diagnosis.

    Attributes
    ----------
    train_fraction : float
        Share of the visible configurations used to fit effects.
    choose_fraction : float
        Share used to rank, add, simplify and prune effects (the model choice). The rest is the
        report split: the reduction is measured there only, never on configurations that
        fitted or chose the model.
    seed : int
        Seed of the split and the subsamples.
    max_sim_items : int
        Configurations used when fitting a candidate by simulation (training subsample).
    max_heldout_items : int
        Most configurations of the choice split (all candidates are scored on them).
    explained_reduction : float
        Held-out pose-gap reduction below which a significant pose gap is reported as
        unexplained.
    confirm : bool
        Re-run the full pipeline with the selected effects to confirm the reduction.
    """

    train_fraction: float = 0.5
    choose_fraction: float = 0.25
    seed: int = 0
    max_sim_items: int = 40
    max_heldout_items: int = 80
    explained_reduction: float = 0.3
    confirm: bool = True


def calibration_from_attrs(real: xr.Dataset):
    """The calibration a capture was ingested with (``calibration_yaml`` attr), or None."""
    import yaml

    from simgap.core.rig import CameraModel

    text = real.attrs.get("calibration_yaml")
    if not text:
        return None
    data = yaml.safe_load(text)
    keys = ("width", "height", "fx", "fy", "cx", "cy", "distortion")
    return CameraModel(**{k: (tuple(data[k]) if k == "distortion" else data[k]) for k in keys})


def simulation_experiment(real: xr.Dataset, exp: Experiment) -> Experiment:
    """``exp`` restricted to the real dataset's configurations, imaging with its calibration."""
    from simgap.core.config import to_mapping
    from simgap.pipeline.experiment import Configurations

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
    """The visible (tag, p, theta) items with their errors, corners, image statistics, detection.

    Errors and corners are NaN where a side did not detect the tag; such items still carry image
    statistics and detection outcomes.
    """
    real, sim = gapmod.align(real, sim)
    visible = field.real_detection.notnull()
    idx = np.argwhere(visible.values)
    tags, ps, thetas = real.tag.values, real.p.values, real.theta.values
    at = (idx[:, 0], idx[:, 1], idx[:, 2])
    r_err = gapmod.mean_error(real).values
    s_err = gapmod.mean_error(sim).values
    with warnings.catch_warnings():  # never-detected items are all-NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        r_c = real.corners.isel(variant=0).mean("repeat", skipna=True).values
        s_c = sim.corners.isel(variant=0).mean("repeat", skipna=True).values
    units = np.array([gapmod.PRACTICAL_FLOOR[gapmod.axis_unit(a)] for a in AXES])
    scale = np.maximum(field.sigma.values, units)
    stats = {}
    for name, ds in (("real", real), ("sim", sim)):
        if "image_stats" in ds:
            stats[name] = repeat_median_stats(ds).values[at]
        else:
            stats[name] = np.full((len(idx), len(STAT_NAMES)), np.nan)
    return Items(
        tag=tags[idx[:, 0]],
        p=ps[idx[:, 1]],
        theta=thetas[idx[:, 2]],
        real_err=r_err[at],
        sim_err=s_err[at],
        real_corners=r_c[at],
        sim_corners=s_c[at],
        scale=scale,
        real_stats=stats["real"],
        sim_stats=stats["sim"],
        real_detected=field.real_detection.values[at],
        sim_detected=field.sim_detection.values[at],
    )


class SimRunner:
    """Runs variant states through the cached pipeline for a set of items (in process)."""

    def __init__(self, exp: Experiment, cache_dir: Path) -> None:
        from simgap.pipeline.sweep import _assets_hash

        self.exp, self.cache = exp, Cache(cache_dir)
        self.rig = exp.rig_model
        self.tags = exp.configuration_axes()[2]
        self.assets = _assets_hash()
        self._pipes: dict[str, Any] = {}
        self._memo: dict[tuple, np.ndarray] = {}

    def pipeline(self, state: VariantState):
        """The (memoised) pipeline of a state."""
        from simgap.pipeline.sweep import VariantPipeline

        key = content_hash(state)
        if key not in self._pipes:
            self._pipes[key] = VariantPipeline(
                self.rig, state, self.tags, self.exp.render.crop_margin_px, self.cache, self.assets
            )
        return self._pipes[key]

    def _results(self, state: VariantState, items: Items, field: str) -> np.ndarray:
        pipe = self.pipeline(state)
        reps = self.exp.repeats if state.image.stochastic else 1
        shape = {"error": (6,), "corners": (4, 2), "image_stats": (len(STAT_NAMES),)}
        out = np.full((len(items),) + shape.get(field, ()), np.nan)
        for i in range(len(items)):
            key = (pipe.scene_key, content_hash(state), int(items.p[i]), float(items.theta[i]))
            if key not in self._memo:
                runs = [pipe.run(int(items.p[i]), float(items.theta[i]), r, 0) for r in range(reps)]
                with warnings.catch_warnings():  # a tag never detected is all-NaN
                    warnings.simplefilter("ignore", RuntimeWarning)
                    self._memo[key] = {
                        f: np.nanmean(np.stack([getattr(x, f) for x in runs]), axis=0)
                        for f in ("error", "corners")
                    } | {
                        "image_stats": np.nanmedian(
                            np.stack([x.image_stats for x in runs]), axis=0
                        ),
                        "detected": np.mean(np.stack([x.detected for x in runs]), axis=0),
                    }
            out[i] = self._memo[key][field][self.tags.index(int(items.tag[i]))]
        return out

    def __call__(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-mean simulated errors (N, 6) of ``items`` under ``state`` (m, rad)."""
        return self._results(state, items, "error")

    def corners(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-mean detected corners (N, 4, 2) of ``items`` under ``state`` (px)."""
        return self._results(state, items, "corners")

    def stats(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-median image statistics (N, S) of ``items`` under ``state``."""
        return self._results(state, items, "image_stats")

    def detected(self, state: VariantState, items: Items) -> np.ndarray:
        """Detection rate over repeats (N,) of ``items`` under ``state``."""
        return self._results(state, items, "detected")

    def depths(self, items: Items) -> np.ndarray:
        """Depth of each item's tag along the optical axis, nominal rig (N,) (m)."""
        return self.rig.eyepoints_from_tags(items.tag, items.p, items.theta)[:, 1, 3]


def split_items(
    n: int, train_fraction: float, choose_fraction: float, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Disjoint random fit / choose / report index sets of ``n`` items (each non-empty if n >= 3).

    Parameters
    ----------
    n : int
        Number of items.
    train_fraction, choose_fraction : float
        Shares of the fit and choice splits; the report split takes the rest.
    seed : int
        Seed of the permutation.
    """
    order = np.random.default_rng(seed).permutation(n)
    if n < 3:
        return np.sort(order), np.sort(order), np.sort(order)
    k_fit = min(max(int(round(train_fraction * n)), 1), n - 2)
    k_choose = min(max(int(round(choose_fraction * n)), 1), n - k_fit - 1)
    cut = k_fit + k_choose
    return np.sort(order[:k_fit]), np.sort(order[k_fit:cut]), np.sort(order[cut:])


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
        from simgap.pipeline.sweep import run_experiment

        self.settings = settings
        self.real = real
        self.exp = simulation_experiment(real, exp)
        self.sim = run_experiment(self.exp, cache_dir, show_progress=True, scheduler=scheduler)
        self.field = gapmod.gap_field(real, self.sim)
        self.items = build_items(real, self.sim, self.field)
        self.runner = SimRunner(self.exp, cache_dir)
        self.base = self.exp.variant_states()[0][1]
        self.rig = self.exp.rig_model
        train, choose, report = split_items(
            len(self.items), settings.train_fraction, settings.choose_fraction, settings.seed
        )
        self.train, self.report = train, report
        self.held = _subsample(choose, settings.max_heldout_items, settings.seed)
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
            corner_unit(real.reproj_px.isel(variant=0).values),
        )

    # ------------------------------------------------------------------ which

    # ------------------------------------------------------------------ how far

    def confirm(self, chosen: Scored) -> dict[str, Any]:
        """Re-run the pipeline (re-render) with all selected effects; report-split gap after."""
        state = self.base
        for cand, fit in chosen.fits:
            state = cand.apply(state, fit.params)
        h = self.items.subset(self.report)
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


def unexplained_evidence(
    chosen: Scored | None, where: dict[str, Any], settings: DiagnoseSettings
) -> list[str]:
    """Significant evidence that the chosen model leaves unexplained on held-out data.

    ``pose``: the held-out pose gap falls by less than ``settings.explained_reduction``;
    an image statistic: its held-out misfit stays at or above its floor; ``detection``: the
    held-out detection mismatch stays at or above 5 %; ``scatter``: the model has no noise
    effect (the pose scatter of a model is not predicted otherwise). Everything significant is
    unexplained when no model was chosen.
    """
    out = []
    pose = any(a["significant"] for a in where["axes"].values())
    if pose and (chosen is None or chosen.reduction < settings.explained_reduction):
        out.append("pose")
    misfit = dict(zip(SCORED_STATS, chosen.image_after, strict=True)) if chosen else {}
    out += [
        r["stat"]
        for r in where["image_tests"]
        if r["significant"] and misfit.get(r["stat"], np.inf) >= 1.0
    ]
    if any(r["significant"] for r in where["detection_tests"]) and (
        chosen is None or chosen.detection_after >= 1.0
    ):
        out.append("detection")
    noisy = chosen is not None and any(
        EFFECTS[e].stochastic for e in chosen.effects
    )
    if any(r["significant"] for r in where["scatter_tests"]) and not noisy:
        out.append("scatter")
    return out


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
    simgap.results.dataset.DatasetError
        Before any simulation, when ``real`` does not follow the result dataset contract.
    """
    check_dataset(real, required=("error", "detected", "visible", "corners"))
    t0 = time.perf_counter()
    d = Diagnosis(real, exp, cache_dir, settings, scheduler)
    axes = d.where
    pose_significant = any(a["significant"] for a in axes.values())
    det = gapmod.detection_summary(d.field)
    tests = {
        "scatter": evidence.scatter_tests(d.real, d.sim),
        "detection": evidence.detection_tests(d.real, d.sim),
        "image": evidence.image_tests(d.real, d.sim),
    }
    families = {"pose": pose_significant} | {
        name: any(r["significant"] for r in rows) for name, rows in tests.items()
    }
    significant = any(families.values())
    where = {
        "axes": axes,
        "regions": [r for r in gapmod.region_summary(d.field) if r["significant"]],
        "detection": det,
        "significant": significant,
        "significant_evidence": [name for name, hit in families.items() if hit],
        "scatter_tests": tests["scatter"],
        "detection_tests": tests["detection"],
        "image_tests": tests["image"],
        "comparable_configurations": int(d.field.comparable.sum()),
    }
    if candidates is None:
        candidates = default_candidates() + appearance_candidates(d.rig.camera.fx)
    ranking = d.search.rank(candidates, significant) if len(d.items) >= 2 else []
    chosen = d.search.select(ranking) if significant else None
    left = unexplained_evidence(chosen, where, settings) if significant else []
    explained = chosen is not None
    result: dict[str, Any] = {
        "ranking": [s.record() for s in ranking],
        "selected": chosen.effects if explained else [],
        "minor": d.search.minor(chosen) if explained else [],
        "unexplained": bool(significant and left),
        "unexplained_evidence": left,
        "where": _jsonable(where),
        "split": {
            "train": int(len(d.train)),
            "heldout": int(len(d.held)),
            "report": int(len(d.report)),
            "seed": settings.seed,
        },
    }
    if chosen is not None and explained:
        weight = d.search.contributions(chosen)
        projection = chosen.projection[:2] if chosen.projection else None
        reported = d.search.score(chosen.fits, projection, d.report)
        interval = bootstrap_reductions(reported, d.axes, seed=settings.seed)
        result["combined"] = {
            "effects": [
                {
                    "effect": fit.effect,
                    "params": _jsonable(fit.params),
                    "pose_contribution": weight[fit.effect],
                    "minor": weight[fit.effect] < 1.0,
                }
                for _, fit in chosen.fits
            ],
            "n_params": chosen.n_params,
            "measured_on": "report split: configurations that neither fitted nor chose the model",
            "configurations": len(d.report),
            "heldout_gap_before": reported.before,
            "heldout_gap_after": reported.after,
            "reduction": reported.reduction,
            "reduction_interval_90": interval["pose_reduction"],
            "heldout_corner_gap_before_px": reported.corner_before,
            "heldout_corner_gap_after_px": reported.corner_after,
            "heldout_evidence_before": reported.evidence_before,
            "heldout_evidence_after": reported.evidence_after,
            "evidence_reduction": reported.evidence_reduction,
            "evidence_reduction_interval_90": interval["evidence_reduction"],
            "heldout_gap_before_per_axis": dict(
                zip(AXES, map(float, reported.before_axes), strict=True)
            ),
            "heldout_gap_after_per_axis": dict(
                zip(AXES, map(float, reported.after_axes), strict=True)
            ),
            "choice": {
                "configurations": len(d.held),
                "heldout_evidence_before": chosen.evidence_before,
                "heldout_evidence_after": chosen.evidence_after,
                "heldout_gap_after": chosen.after,
            },
            "equivalent_models": d.search.alternatives(chosen),
        }
        if settings.confirm:
            conf = d.confirm(chosen)
            conf["reduction"] = (
                1.0 - conf["heldout_gap_after"] / reported.before if reported.before > 0 else 0.0
            )
            result["confirmed"] = conf
    result["seconds"] = time.perf_counter() - t0
    return result, d


def write_json(result: dict[str, Any], path: Path) -> Path:
    """Write ``result.json`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, json.dumps(_jsonable(result), indent=2))
