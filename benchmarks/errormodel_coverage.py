"""Honest check of the error model on the baseline study: fit on a random half of the
configurations, predict the other half; print the coverage of the 90 % intervals per axis and the
detection-probability calibration, for five splits. Renders results/baseline.nc if missing."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from simgap.analysis.errormodel import AXES, check_error_model, fit_error_model
from simgap.results.dataset import read_netcdf

REPO = Path(__file__).resolve().parents[1]
BASELINE = REPO / "results" / "baseline.nc"
SEEDS = (0, 1, 2, 3, 4)


def main() -> None:
    if not BASELINE.is_file():
        print(f"{BASELINE} missing: rendering the baseline study (a few minutes)")
        cmd = ["simgap", "run", str(REPO / "experiments/baseline.yaml"), "-o", str(BASELINE)]
        subprocess.run(cmd, check=True)
    ds = read_netcdf(BASELINE)
    t0 = time.perf_counter()
    fit_error_model(ds)
    print(
        f"fit on all {ds.sizes['p'] * ds.sizes['theta']} configurations: "
        f"{time.perf_counter() - t0:.2f} s"
    )
    rows = []
    print(
        "\nseed  " + "  ".join(f"{a:>5s}" for a in AXES) + "  pooled  n_err  outside"
        "  det_pred  det_obs  brier"
    )
    for seed in SEEDS:
        r = check_error_model(ds, seed=seed)
        cov = [r["coverage"][a] for a in AXES]
        pooled = float(np.average(cov))
        d = r["detection"]
        rows.append(cov + [pooled])
        print(
            f"{seed:4d}  "
            + "  ".join(f"{c:5.1%}" for c in cov)
            + f"  {pooled:6.1%}  {r['n_errors']:5d}  {r['n_outside']:7d}"
            f"  {d['predicted_rate']:8.1%}  {d['observed_rate']:7.1%}  {d['brier']:.4f}"
        )
    mean = np.mean(rows, axis=0)
    print("mean  " + "  ".join(f"{c:5.1%}" for c in mean[:-1]) + f"  {mean[-1]:6.1%}")
    print("\ndetection calibration (seed 0): bin of predicted p -> mean predicted, observed, n")
    for b in check_error_model(ds, seed=0)["detection"]["bins"]:
        print(
            f"  [{b['bin'][0]:.2f}, {b['bin'][1]:.2f}]  {b['predicted']:.3f}  "
            f"{b['observed']:.3f}  {b['n']}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
