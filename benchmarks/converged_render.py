"""Converged renders against a many-sample path-traced reference, in one run (issue 28).

The baseline experiment restricted to ``--configs`` configurations (drawn with ``--seed`` from the
full grid) is run through the whole pipeline (render, camera, detector, PnP), each from an empty
cache:

- the reference: path tracing at ``--ref-spp`` (1024);
- today's baseline: path tracing at 16 spp;
- converged at ``--spp`` (4), at two render seeds.

Prints, per run, the wall time of the run, the detected corners' RMS distance from the
reference's (px), and the mean |difference| of the estimated pose from the reference's per axis
(mm, mrad). Then it prints the two converged seeds' mean |difference| (ty in mm, rotations in
mrad) and the speed ratio of the converged run to the 16-spp one. The issue's bars are 0.02 px,
0.1 mm, 1 mrad, and half the 16-spp time.

Usage: ``python benchmarks/converged_render.py [--configs 12] [--ref-spp 1024] [--spp 4]``
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from simgap.pipeline.experiment import Configurations, load_experiment
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--configs", type=int, default=12)
    parser.add_argument("--ref-spp", type=int, default=1024)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--experiment", default="experiments/baseline.yaml")
    args = parser.parse_args()

    base = load_experiment(args.experiment)
    rng = np.random.default_rng(args.seed)
    p_all, theta_all, _ = base.configuration_axes()
    ps = rng.choice(np.asarray(p_all), size=args.configs)
    thetas = rng.choice(np.rad2deg(np.asarray(theta_all)), size=args.configs)
    # one configuration per (p, theta) drawn: the grid's p and theta sets of the draw
    exp = dataclasses.replace(
        base,
        configurations=Configurations(
            tuple(sorted({int(p) for p in ps})), tuple(sorted({float(t) for t in thetas})), ()
        ),
    )
    print(f"{exp.configurations}", flush=True)
    ref, _ = run(exp.with_render(spp=args.ref_spp), f"reference: path {args.ref_spp} spp")
    path, t_path = run(exp.with_render(spp=16), "baseline: path 16 spp")
    conv = []
    for seed in (0, 1):
        ds, t_conv = run(
            exp.with_render(spp=args.spp, mode="converged", seed=seed),
            f"converged {args.spp} spp, render seed {seed}",
        )
        conv.append((ds, t_conv))
    compare(path, ref, "path 16 spp")
    for seed, (ds, _) in enumerate(conv):
        compare(ds, ref, f"converged {args.spp} spp, seed {seed}")
    compare(conv[1][0], conv[0][0], "converged seed 1 against seed 0")
    print(f"speed: converged / path 16 spp = {conv[0][1] / t_path:.2f} (bar: <= 0.5)")


if __name__ == "__main__":
    main()
