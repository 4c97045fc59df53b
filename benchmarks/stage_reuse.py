"""Stage reuse: an image-stage variant over the full sweep, served from cached renders.

Runs the baseline experiment once (renders cached), then the same experiment with one image-stage
variant (blur) and one estimation-stage variant (corner refinement NONE) added, and prints the rate
at which those variants' configurations are processed when every render comes from the cache.

Always starts from an empty temporary cache, so the variants' frames and results are new while
their renders come from the baseline run (timings include the Dask client start, ~3 s, which is
subtracted through the cached baseline run).

Usage: ``python benchmarks/stage_reuse.py [--experiment experiments/baseline.yaml]``
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

from simgap.pipeline.experiment import VariantSpec, load_experiment
from simgap.pipeline.sweep import run_experiment


def timed(exp, cache: Path) -> float:
    t0 = time.perf_counter()
    run_experiment(exp, cache, show_progress=False)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--experiment", default="experiments/baseline.yaml")
    args = ap.parse_args()
    base = load_experiment(args.experiment)
    n = len(base.configuration_axes()[0]) * len(base.configuration_axes()[1])
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp)
        t_base = timed(base, cache)
        t_cached = timed(base, cache)
        rows = []
        for spec in (
            VariantSpec("blur", {"blur": {"sigma_px": 1.0}}),
            VariantSpec("refine_none", {"detector_refinement": {"method": "NONE"}}),
        ):
            exp = dataclasses.replace(base, variants=(VariantSpec("baseline"), spec))
            # baseline served entirely from cache, the new variant from cached renders
            rows.append((spec.name, timed(exp, cache) - t_cached))
    print(f"experiment               {base.name}: {n} configurations")
    print(f"baseline, empty cache    {t_base:7.1f} s   {n / t_base:7.1f} configurations/s")
    print(f"baseline, from cache     {t_cached:7.2f} s   {n / t_cached:7.1f} configurations/s")
    for name, t in rows:
        stage = "image" if name == "blur" else "estimation"
        print(
            f"{stage + '-stage variant':24s} {t:7.1f} s   {n / t:7.1f} configurations/s  ({name})"
        )


if __name__ == "__main__":
    main()
