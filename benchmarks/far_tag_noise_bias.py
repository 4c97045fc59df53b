"""A far, oblique tag's simulated pose error per render mode: the bias corner noise gives PnP.

At one configuration of the baseline (default: tag 1 at p 14, theta 200 deg, the farthest and
most oblique of the public sample-focal's), the pose error of the simulated tag rendered
converged at 4 spp, path traced at 16 spp and path traced at ``--ref-spp`` (the reference),
each at several render seeds. Where the 16-spp errors sit on one side of the reference's, the
render's noise biases the pose there rather than only spreading it (docs/results/
converged_render_step8.md#step-6: ty +10 mm at 16 spp, converged within the reference's spread).

Usage: ``python benchmarks/far_tag_noise_bias.py [--p 14] [--theta 200] [--tag 1]
[--ref-spp 1024]``
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from simgap.core.axes import AXES
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.experiment_settings import Configurations
from simgap.pipeline.sweep import run_experiment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--experiment", default="experiments/baseline.yaml")
    parser.add_argument("--p", type=int, default=14)
    parser.add_argument("--theta", type=float, default=200.0, help="deg")
    parser.add_argument("--tag", type=int, default=1)
    parser.add_argument("--ref-spp", type=int, default=1024)
    args = parser.parse_args()
    base = load_experiment(args.experiment)
    exp = dataclasses.replace(base, configurations=Configurations((args.p,), (args.theta,), ()))
    runs = [("converged 4 spp", {"spp": 4, "mode": "converged"}, (0, 1))]
    runs += [("path 16 spp", {"spp": 16, "mode": "path"}, (0, 1, 2, 3))]
    runs += [(f"path {args.ref_spp} spp", {"spp": args.ref_spp, "mode": "path"}, (0, 1))]
    print(f"tag {args.tag}, p {args.p}, theta {args.theta:g} deg: pose error (mm, mrad)")
    print("| render | seed | " + " | ".join(AXES) + " |")
    print("|---|---|" + "---|" * len(AXES))
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        for label, render, seeds in runs:
            for seed in seeds:
                ds = run_experiment(
                    exp.with_render(**render, seed=seed), Path(cache), show_progress=False
                )
                error = ds["error"].sel(tag=args.tag).isel(variant=0, repeat=0)
                error = error.squeeze(drop=True).values * 1e3  # (axis,), m and rad -> mm, mrad
                cells = " | ".join(f"{v:.2f}" for v in np.asarray(error, float))
                print(f"| {label} | {seed} | {cells} |", flush=True)


if __name__ == "__main__":
    main()
