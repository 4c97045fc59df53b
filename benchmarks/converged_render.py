"""Converged renders against path tracing, in one run (issue 28).

Two parts, each run from an empty cache through the whole pipeline (render, camera, detector,
PnP):

- **Accuracy**: the baseline experiment restricted to ``--configs`` configurations (drawn with
  ``--seed`` from the full grid), path traced at ``--ref-spp`` (the reference), at 16 spp, and
  converged at ``--spp`` (4). Per run: the detected corners' RMS distance from the reference's
  (px) and the mean |difference| of the estimated pose per axis (mm, mrad). The issue's bars:
  0.02 px, 0.1 mm, 1 mrad.
- **Seeds and speed**: the whole baseline sweep (``--sweep-configs`` configurations, default all
  540) path traced at 16 spp and converged at ``--spp``, each at render seeds 0 and 1. Per mode:
  the wall time of the seed-0 sweep and the two seeds' mean |difference| (ty in mm, rotations in
  mrad). The issue's bars: 0.1 mm and 1 mrad between seeds, converged at most half the 16-spp
  time.

Usage: ``python benchmarks/converged_render.py [--configs 12] [--ref-spp 1024] [--spp 4]
[--sweep-configs 540]``
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from simgap.pipeline.experiment import Configurations, Experiment, load_experiment
from simgap.pipeline.simulator import Simulator


def run(exp, label: str) -> tuple[xr.Dataset, float]:
    """The experiment's dataset from an empty cache, and its wall time (s)."""
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        t0 = time.perf_counter()
        ds = Simulator(Path(cache), show_progress=False).dataset(exp)
        seconds = time.perf_counter() - t0
    print(f"{label}: {seconds:.1f} s", flush=True)
    return ds, seconds


def compare(ds: xr.Dataset, ref: xr.Dataset, label: str) -> None:
    """Corner RMS (px) and mean |pose difference| per axis against the reference."""
    both = ds["detected"].values & ref["detected"].values
    corners = ds["corners"].values[both] - ref["corners"].values[both]
    rms = float(np.sqrt(np.nanmean(np.sum(corners**2, axis=-1))))
    diff = np.abs(ds["estimated"].values[both] - ref["estimated"].values[both])
    mean = np.nanmean(diff, axis=0)
    print(
        f"  {label}: {int(both.sum())} detections, corners {rms:.3f} px RMS; pose mean |diff| "
        f"tx {mean[0] * 1e3:.3f} ty {mean[1] * 1e3:.3f} tz {mean[2] * 1e3:.3f} mm, "
        f"rx {mean[3] * 1e3:.2f} ry {mean[4] * 1e3:.2f} rz {mean[5] * 1e3:.2f} mrad",
        flush=True,
    )


def drawn(base: Experiment, n: int, seed: int) -> Experiment:
    """``base`` on the (p, theta) sets of ``n`` configurations drawn from its grid."""
    if n >= len(base.configuration_axes()[0]) * len(base.configuration_axes()[1]):
        return base
    rng = np.random.default_rng(seed)
    p_all, theta_all, _ = base.configuration_axes()
    ps = rng.choice(np.asarray(p_all), size=n)
    thetas = rng.choice(np.rad2deg(np.asarray(theta_all)), size=n)
    configurations = Configurations(
        tuple(sorted({int(p) for p in ps})), tuple(sorted({float(t) for t in thetas})), ()
    )
    return dataclasses.replace(base, configurations=configurations)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--configs", type=int, default=12)
    parser.add_argument("--ref-spp", type=int, default=1024)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--sweep-configs", type=int, default=540)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--experiment", default="experiments/baseline.yaml")
    args = parser.parse_args()
    base = load_experiment(args.experiment)

    exp = drawn(base, args.configs, args.seed)
    print(f"accuracy: {exp.configurations}", flush=True)
    ref, _ = run(exp.with_render(spp=args.ref_spp), f"reference: path {args.ref_spp} spp")
    path, _ = run(exp.with_render(spp=16), "path 16 spp")
    conv, _ = run(exp.with_render(spp=args.spp, mode="converged"), f"converged {args.spp} spp")
    compare(path, ref, "path 16 spp")
    compare(conv, ref, f"converged {args.spp} spp")

    sweep = drawn(base, args.sweep_configs, args.seed + 1)
    print(f"seeds and speed: {sweep.configurations}", flush=True)
    seconds = {}
    modes = {
        "path 16 spp": {"spp": 16},
        f"converged {args.spp} spp": {"spp": args.spp, "mode": "converged"},
    }
    for label, settings in modes.items():
        seeds = []
        for seed in (0, 1):
            ds, t = run(sweep.with_render(**settings, seed=seed), f"{label}, render seed {seed}")
            seeds.append(ds)
            seconds.setdefault(label, t)
        compare(seeds[1], seeds[0], f"{label}: render seed 1 against seed 0")
    path_s, conv_s = seconds.values()
    print(f"speed: converged / path 16 spp = {conv_s / path_s:.2f} (bar: <= 0.5)")


if __name__ == "__main__":
    main()
