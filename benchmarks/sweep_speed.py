"""Sweep wall time: the cached-crop pipeline vs the naive way, measured in one run.

Prints
- a breakdown per configuration of one sequential pass over the whole sweep in a fresh process
  (scene load, pose update, sampling, image pipeline, detection, PnP, image statistics, IO; the
  stages of ``simgap.pipeline.variant.STAGES``) and the Dr.Jit kernels it launched and compiled,
  first with an empty kernel cache (a fresh machine: ``DRJIT_CACHE_DIR`` a new folder) and then
  with that cache warm;
- the full baseline sweep (540 configurations, both tags) from an empty result cache (Dask, warm
  kernel cache): wall time and rate;
- the same sweep served from cache;
- the naive way on a subset: full-frame render with ``mi.load_dict`` per pose, then detection
  and PnP; its per-configuration time, extrapolated to the full sweep, and the speed ratio. It
  path traces at the experiment's samples per pixel, which for a converged experiment is not
  its noise: ``benchmarks/converged_render.py`` times the naive way at the converged noise.

Usage: ``python benchmarks/sweep_speed.py [--experiment experiments/baseline.yaml] [--subset 8]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from simgap.pipeline.cache import Cache
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.sweep import run_experiment
from simgap.pipeline.variant import STAGES, VariantPipeline, assets_hash, config_seed
from simgap.pose.detect import Detector
from simgap.pose.estimate import estimate_pose
from simgap.render import imaging
from simgap.render.scene import FixtureScene, projected_sticker_boxes


def naive(exp, configs) -> float:
    """Seconds per configuration: scene reloaded per pose, full frame rendered and detected."""
    rig, det = exp.rig_model, Detector(exp.detector)
    cam = rig.camera
    t0 = time.perf_counter()
    for p, theta in configs:
        scene = FixtureScene(rig, exp.scene_spec, (cam.width, cam.height), exp.render.spp)
        scene.set_pose(p, theta)
        frame = imaging.encode_srgb8(scene.render((0, 0), config_seed(exp.render.seed, p, theta)))
        for corners in det.detect(imaging.to_gray(frame)).values():
            estimate_pose(corners, rig.tags.size, cam, exp.pnp)
    return (time.perf_counter() - t0) / len(configs)


def stage_pass(exp) -> dict:
    """One sequential pass over every configuration and repeat of ``exp``'s first variant.

    Runs in this process from an empty result cache; returns the wall time, the seconds per
    stage and the Dr.Jit kernels launched (compiled from scratch, loaded from the on-disk cache,
    and the compile time).
    """
    import drjit as dr

    state = exp.variant_states()[0][1]
    ps, thetas, tags = exp.configuration_axes()
    kernels = {"launched": 0, "compiled": 0, "from_disk": 0, "compile_s": 0.0}

    def collect() -> None:  # the history holds every kernel's IR: drain it as we go
        for h in dr.kernel_history([dr.KernelType.JIT]):
            kernels["launched"] += 1
            # measured: a kernel compiled here has neither flag, one loaded from the on-disk
            # cache both, one reused from memory only cache_hit
            kernels["compiled"] += not h["cache_hit"]
            kernels["from_disk"] += bool(h["cache_hit"] and h["cache_disk"])
            kernels["compile_s"] += h.get("backend_time", 0.0) / 1000.0

    with tempfile.TemporaryDirectory() as tmp, dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        pipe = VariantPipeline(
            exp.rig_model, state, tags, exp.render.margin_px, Cache(Path(tmp)), assets_hash()
        )
        t0 = time.perf_counter()
        for p in ps:
            for theta in thetas:
                for repeat in range(exp.repeats):
                    pipe.run(int(p), float(theta), repeat, 0)
                collect()
        wall = time.perf_counter() - t0
    return {"wall_s": wall, "configurations": len(ps) * len(thetas), **kernels,
            "stages_s": dict(pipe.seconds)}  # fmt: skip


def stage_passes(experiment: str) -> tuple[dict, dict]:
    """:func:`stage_pass` in two fresh processes sharing a new kernel cache: cold, then warm."""
    with tempfile.TemporaryDirectory() as kernel_dir:
        env = {**os.environ, "DRJIT_CACHE_DIR": kernel_dir}
        cmd = [sys.executable, __file__, "--experiment", experiment, "--stage-pass"]
        runs = [
            json.loads(subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)
                       .stdout.splitlines()[-1])
            for _ in range(2)
        ]  # fmt: skip
    return runs[0], runs[1]


def print_breakdown(cold: dict, warm: dict) -> None:
    """The per-stage table of :func:`stage_passes`."""
    n = cold["configurations"]
    print(f"one process, sequential, {n} configurations    cold kernels   warm kernels")
    for stage in STAGES:
        a, b = (run["stages_s"].get(stage, 0.0) / n * 1e3 for run in (cold, warm))
        print(f"  {stage:<20} ms per configuration  {a:10.1f}     {b:10.1f}")
    walls = f"{cold['wall_s']:10.1f}     {warm['wall_s']:10.1f}"
    print(f"  {'total wall':<20} s                    {walls}")
    for key, label in (("launched", "kernels launched"), ("compiled", "kernels compiled"),
                       ("from_disk", "kernels from disk")):  # fmt: skip
        print(f"  {label:<20}                      {cold[key]:10d}     {warm[key]:10d}")
    print(f"  {'kernel compile':<20} s                    {cold['compile_s']:10.1f}     "
          f"{warm['compile_s']:10.1f}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--experiment", default="experiments/baseline.yaml")
    ap.add_argument("--subset", type=int, default=8, help="configurations timed the naive way")
    ap.add_argument("--stage-pass", action="store_true", help=argparse.SUPPRESS)  # child process
    args = ap.parse_args()
    exp = load_experiment(args.experiment)
    if args.stage_pass:
        print(json.dumps(stage_pass(exp)))
        return
    print_breakdown(*stage_passes(args.experiment))
    ps, thetas, _ = exp.configuration_axes()
    n = len(ps) * len(thetas)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run_experiment(exp, Path(tmp), show_progress=False)
        fast = time.perf_counter() - t0
        t0 = time.perf_counter()
        run_experiment(exp, Path(tmp), show_progress=False)
        cached = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    facing = [(p, t) for p in ps for t in thetas if projected_sticker_boxes(exp.rig_model, p, t)]
    subset = [facing[i] for i in rng.choice(len(facing), args.subset, replace=False)]
    per_naive = naive(exp, subset)
    print(
        f"experiment            {exp.name}: {n} configurations, {exp.render.mode} "
        f"{exp.render.spp} spp (naive: path traced at {exp.render.spp} spp)"
    )
    print(f"sweep, empty cache    {fast:8.1f} s   {n / fast:7.2f} configurations/s")
    print(f"sweep, from cache     {cached:8.2f} s   {n / cached:7.1f} configurations/s")
    print(f"naive, {len(subset)} configs     {per_naive:8.2f} s per configuration (facing a tag)")
    naive_total = per_naive * len(facing)
    print(f"naive, extrapolated   {naive_total:8.1f} s for the {len(facing)} facing configurations")
    print(f"speed-up              {naive_total / fast:8.1f} x (same run, same machine)")


if __name__ == "__main__":
    main()
