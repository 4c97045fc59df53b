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
import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from simgap.analysis import gap as gapmod
from simgap.analysis.fitting import (
    Fit,
    Items,
    ProjectionCandidate,
    corner_score,
    default_candidates,
    gap_rms_per_axis,
    gap_score,
)
from simgap.cache import Cache, content_hash
from simgap.effects import make_effect
from simgap.effects.state import VariantState
from simgap.experiment import Experiment

AXES = gapmod.AXES
#: Held-out gap score at which the remaining gap is taken as noise (pure noise scores ~0.67).
NOISE_LEVEL = 1.0


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


@dataclass
class Scored:
    """A candidate's fit and its held-out scores."""

    candidate: Any
    fit: Fit
    before: float
    after: float
    before_axes: np.ndarray
    after_axes: np.ndarray
    before_all: float = float("nan")
    after_all: float = float("nan")
    corner_before: float = float("nan")
    corner_after: float = float("nan")

    @property
    def reduction(self) -> float:
        """Relative fall of the held-out gap."""
        return 1.0 - self.after / self.before if self.before > 0 else 0.0

    def record(self) -> dict[str, Any]:
        """JSON record (ranking entry)."""
        return {
            "effect": self.fit.effect,
            "params": _jsonable(self.fit.params),
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
            "fit_seconds": self.fit.seconds,
            "stage": self.candidate.kind,
        }


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

    # ------------------------------------------------------------------ which

    def _delta(self, cand, fit: Fit, items: Items) -> np.ndarray:
        if isinstance(cand, ProjectionCandidate):
            return cand.delta(self.rig, self.base, fit, items)
        return cand.delta(self.runner, self.base, fit, items)

    def _corner_delta(self, cand, fit: Fit, items: Items) -> np.ndarray:
        if isinstance(cand, ProjectionCandidate):
            return cand.corner_shift(self.rig, self.base, fit.extra["x"], items)
        state = make_effect(cand.effect, fit.params).apply(self.base)
        return self.runner.corners(state, items) - self.runner.corners(self.base, items)

    def _fit(self, cand, offset_train: np.ndarray, corner_offset: np.ndarray) -> Fit:
        items = self.items
        if isinstance(cand, ProjectionCandidate):
            tr = items.subset(self.train)
            return cand.fit(self.rig, self.base, tr, target=tr.real_corners - corner_offset)
        sub = items.subset(self.sim_train)
        pos = np.searchsorted(self.train, self.sim_train)
        return cand.fit(self.runner, self.base, sub, sub.real_err - offset_train[pos], self.axes)

    def score(self, cand, fit: Fit, offset_held: np.ndarray, corner_held=0.0) -> Scored:
        """Held-out gap before and after adding ``fit`` on top of the offsets (m, rad; px)."""
        h = self.items.subset(self.held)
        pred0 = h.sim_err + offset_held
        pred1 = pred0 + np.nan_to_num(self._delta(cand, fit, h))
        c0 = h.sim_corners + corner_held
        c1 = c0 + np.nan_to_num(self._corner_delta(cand, fit, h))
        return Scored(
            cand,
            fit,
            gap_score(h.real_err, pred0, h.scale, self.axes),
            gap_score(h.real_err, pred1, h.scale, self.axes),
            gap_rms_per_axis(h.real_err, pred0),
            gap_rms_per_axis(h.real_err, pred1),
            gap_score(h.real_err, pred0, h.scale),
            gap_score(h.real_err, pred1, h.scale),
            corner_score(h.real_corners, c0),
            corner_score(h.real_corners, c1),
        )

    def rank(self, candidates, significant: bool) -> list[Scored]:
        """Fit and score every candidate alone; projection ones only when no gap is significant."""
        zero_t = np.zeros((len(self.train), 6))
        zero_h = np.zeros((len(self.held), 6))
        zero_c = np.zeros((len(self.train), 4, 2))
        out = []
        for cand in candidates:
            if not significant and not isinstance(cand, ProjectionCandidate):
                continue
            out.append(self.score(cand, self._fit(cand, zero_t, zero_c), zero_h))
        # ranked on the held-out detected corners: the most direct evidence, in one unit (px),
        # free of the planar pose ambiguity; an effect must move the corners the way reality does
        return sorted(out, key=lambda s: s.corner_after)

    def greedy(self, ranking: list[Scored], max_effects: int = 3) -> list[Scored]:
        """Add effects one at a time while the held-out gap falls by ``min_gain`` or more."""
        if not ranking:
            return []
        chosen = [ranking[0]]
        items = self.items
        for _ in range(max_effects - 1):
            off_t = sum(
                np.nan_to_num(self._delta(s.candidate, s.fit, items.subset(self.train)))
                for s in chosen
            )
            corner_h = sum(
                np.nan_to_num(self._corner_delta(s.candidate, s.fit, items.subset(self.held)))
                for s in chosen
            )
            off_h = sum(
                np.nan_to_num(self._delta(s.candidate, s.fit, items.subset(self.held)))
                for s in chosen
            )
            corner = np.zeros((len(self.train), 4, 2))
            for s in chosen:
                if isinstance(s.candidate, ProjectionCandidate):
                    corner += np.nan_to_num(
                        s.candidate.corner_shift(
                            self.rig, self.base, s.fit.extra["x"], items.subset(self.train)
                        )
                    )
            if chosen[-1].after < NOISE_LEVEL:
                break  # what is left of the gap is noise
            current = chosen[-1].corner_after
            best = None
            for s in ranking[1:]:
                if s.fit.effect in {c.fit.effect for c in chosen}:
                    continue
                fit = self._fit(s.candidate, off_t, corner)
                scored = self.score(s.candidate, fit, off_h, corner_h)
                if best is None or scored.corner_after < best.corner_after:
                    best = scored
            if best is None or best.corner_after > current * (1.0 - self.settings.min_gain):
                break
            chosen.append(best)
        return chosen

    # ------------------------------------------------------------------ how far

    def confirm(self, chosen: list[Scored]) -> dict[str, Any]:
        """Re-run the pipeline (re-render) with all selected effects; held-out gap after."""
        state = self.base
        for s in chosen:
            state = make_effect(s.fit.effect, s.fit.params).apply(state)
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
    """Run the whole diagnosis; return the ``result.json`` mapping and the diagnosis state."""
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
    ranking = d.rank(candidates or default_candidates(), significant) if len(d.items) >= 2 else []
    chosen = d.greedy(ranking) if significant else []
    explained = (
        bool(chosen) and (1.0 - chosen[-1].after / chosen[0].before) >= settings.explained_reduction
    )
    result: dict[str, Any] = {
        "ranking": [s.record() for s in ranking],
        "selected": [s.fit.effect for s in chosen] if explained else [],
        "unexplained": bool(significant and not explained),
        "where": _jsonable(where),
        "split": {"train": int(len(d.train)), "heldout": int(len(d.held)), "seed": settings.seed},
    }
    if chosen and explained:
        before = chosen[0].before
        result["combined"] = {
            "effects": [
                {"effect": s.fit.effect, "params": _jsonable(s.fit.params)} for s in chosen
            ],
            "heldout_gap_before": before,
            "heldout_gap_after": chosen[-1].after,
            "reduction": 1.0 - chosen[-1].after / before,
            "heldout_gap_before_per_axis": dict(
                zip(AXES, map(float, chosen[0].before_axes), strict=True)
            ),
            "heldout_gap_after_per_axis": dict(
                zip(AXES, map(float, chosen[-1].after_axes), strict=True)
            ),
        }
        if settings.confirm:
            conf = d.confirm(chosen)
            conf["reduction"] = 1.0 - conf["heldout_gap_after"] / before
            result["confirmed"] = conf
    result["seconds"] = time.perf_counter() - t0
    return result, d


def write_json(result: dict[str, Any], path: Path) -> Path:
    """Write ``result.json`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(_jsonable(result), indent=2))
    os.replace(tmp, path)
    return path
