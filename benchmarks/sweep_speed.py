"""Sweep wall time: the cached-crop pipeline vs the naive way, measured in one run.

Prints
- the full baseline sweep (540 configurations, both tags) from an empty cache: wall time and rate;
- the same sweep served from cache;
- the naive way on a subset: full-frame render with ``mi.load_dict`` per pose, then detection
  and PnP; its per-configuration time, extrapolated to the full sweep, and the speed ratio.

Usage: ``python benchmarks/sweep_speed.py [--experiment experiments/baseline.yaml] [--subset 8]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.sweep import run_experiment
from simgap.pipeline.variant import config_seed
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
            estimate_pose(corners, rig.tags.size, cam.matrix, cam.dist_coeffs, exp.pnp)
    return (time.perf_counter() - t0) / len(configs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--experiment", default="experiments/baseline.yaml")
    ap.add_argument("--subset", type=int, default=8, help="configurations timed the naive way")
    args = ap.parse_args()
    exp = load_experiment(args.experiment)
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
    print(f"experiment            {exp.name}: {n} configurations, spp {exp.render.spp}")
    print(f"sweep, empty cache    {fast:8.1f} s   {n / fast:7.2f} configurations/s")
    print(f"sweep, from cache     {cached:8.2f} s   {n / cached:7.1f} configurations/s")
    print(f"naive, {len(subset)} configs     {per_naive:8.2f} s per configuration (facing a tag)")
    naive_total = per_naive * len(facing)
    print(f"naive, extrapolated   {naive_total:8.1f} s for the {len(facing)} facing configurations")
    print(f"speed-up              {naive_total / fast:8.1f} x (same run, same machine)")


if __name__ == "__main__":
    main()
