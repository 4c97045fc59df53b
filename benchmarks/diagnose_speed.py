"""Time to diagnose a 540-configuration capture against the whole catalogue.

Renders a pseudo-real capture of the full study (hidden: focal length +2 %, plus another light and
sensor noise), ingests it, and times ``diagnose`` (simulation of the same configurations, gap,
every candidate fitted and ranked, greedy combination, confirmation by re-rendering). The
simulation's baseline renders come from the cache when it is warm (``--cache``); the candidates'
renders are always new unless the same cache ran this benchmark before.

Usage: ``python benchmarks/diagnose_speed.py [--cache DIR] [--out DIR]``
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

from simgap.analysis.diagnose import diagnose
from simgap.capture import ingest
from simgap.experiment import VariantSpec, load_experiment
from simgap.validate import NUISANCE, render_capture


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--experiment", default="experiments/baseline.yaml")
    ap.add_argument("--cache", default=None, help="cache folder (default: a new temporary one)")
    ap.add_argument("--out", default=None, help="where to keep the capture (default: temporary)")
    args = ap.parse_args()
    base = load_experiment(args.experiment)
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(args.cache or Path(tmp) / "cache")
        out = Path(args.out or Path(tmp) / "capture")
        hidden = dataclasses.replace(
            base,
            name="pseudo_real",
            render=dataclasses.replace(base.render, seed=4242),
            effects={**NUISANCE, "focal_length": {"scale": 0.02}},
            variants=(VariantSpec("baseline"),),
        )
        t0 = time.perf_counter()
        render_capture(hidden, cache, out)
        t_capture = time.perf_counter() - t0
        t0 = time.perf_counter()
        real = ingest(out, base.rig_model)
        t_ingest = time.perf_counter() - t0
        t0 = time.perf_counter()
        result, _ = diagnose(real, base, cache)
        t_diag = time.perf_counter() - t0
    n = real.sizes["p"] * real.sizes["theta"]
    top = result["ranking"][0]
    print(f"capture                 {n} configurations (p x theta)")
    print(f"render capture          {t_capture:7.1f} s (not part of the diagnosis)")
    print(f"ingest                  {t_ingest:7.1f} s")
    print(f"diagnose                {t_diag:7.1f} s  ({t_diag / 60:.1f} min; target <= 15 min)")
    print(f"top-1                   {top['effect']} {top['params']}")
    print(f"selected                {result['selected']}")
    if "confirmed" in result:
        print(f"held-out reduction      {result['confirmed']['reduction']:.0%} (confirmed)")


if __name__ == "__main__":
    main()
