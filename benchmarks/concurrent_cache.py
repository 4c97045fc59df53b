"""Two real processes running the same tiny experiment on one fresh cache, many times over.

Each pair starts two ``simgap run`` processes at once on an empty cache folder (so both render,
write and read the same entries at the same moment), then checks that both exit cleanly and that
their datasets are identical, value for value (and says whether they also equal the first pair's:
a render's last bits depend on what the process rendered before, see docs/reliability.md). With
``--kill``, each pair is instead one run killed with SIGKILL mid-sweep and rerun on its cache,
compared with an uninterrupted run.

    python benchmarks/concurrent_cache.py [--pairs 20] [--kill]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from simgap.results.dataset import read_netcdf

EXPERIMENT = "name: tiny\nconfigurations: {p: [7], theta_deg: [0, 30, 60, 90]}\nrender: {spp: 4}\n"
VARIABLES = ("expected", "estimated", "error", "visible", "detected", "reproj_px", "corners")


def start(exp: Path, out: Path, cache: Path) -> subprocess.Popen:
    """Start ``simgap run`` in its own process."""
    cmd = [sys.executable, "-m", "simgap", "run", str(exp), "-o", str(out), "--cache", str(cache)]
    return subprocess.Popen(
        cmd + ["--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


def differences(a: Path, b: Path) -> list[str]:
    """Coordinates and variables in which two result datasets differ (NaN equal to NaN)."""
    x, y = read_netcdf(a), read_netcdf(b)
    out = [c for c in x.coords if not np.array_equal(x[c].values, y[c].values)]
    for v in VARIABLES:
        if not np.array_equal(x[v].values, y[v].values, equal_nan=True):
            gap = np.nanmax(np.abs(x[v].values.astype(float) - y[v].values.astype(float)))
            out.append(f"{v} (max |diff| {gap:.3g})")
    return out


def same(a: Path, b: Path) -> bool:
    """Whether two result datasets hold the same coordinates and values (NaN equal to NaN)."""
    diff = differences(a, b)
    if diff:
        print(f"    {a.name} and {b.name} differ in {', '.join(diff)}")
    return not diff


def kill_mid_sweep(exp: Path, out: Path, cache: Path) -> str:
    """Run, SIGKILL once the first configuration is cached, rerun; return what happened."""
    proc = start(exp, out, cache)
    while proc.poll() is None and not list((cache / "results").rglob("*.npz")):
        time.sleep(0.02)
    if proc.poll() is not None:
        return "finished before the kill"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done = len(list((cache / "results").rglob("*.npz")))
    again = start(exp, out, cache)
    log, _ = again.communicate()
    if again.returncode:
        return f"rerun exit {again.returncode}: {log[-300:]}"
    return f"ok (killed with {done} of 4 configurations cached)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=20)
    parser.add_argument("--kill", action="store_true", help="kill -9 mid-sweep, then rerun")
    args = parser.parse_args()
    crashes, differ, across, t0 = 0, 0, 0, time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="simgap-concurrency-") as tmp_name:
        tmp = Path(tmp_name)
        exp = tmp / "tiny.yaml"
        exp.write_text(EXPERIMENT)
        reference = tmp / "reference.nc"
        if args.kill:
            ref = start(exp, reference, tmp / "ref-cache")
            if ref.wait() != 0:
                sys.exit(f"reference run failed: {ref.stdout.read()}")
        for i in range(args.pairs):
            cache = tmp / f"cache{i}"
            outs = [tmp / f"pair{i}-a.nc", tmp / f"pair{i}-b.nc"]
            if args.kill:
                what = kill_mid_sweep(exp, outs[0], cache)
                crashes += not what.startswith("ok")
                ok = what.startswith("ok") and same(outs[0], reference)
                print(f"pair {i + 1:2d}: {what}; identical to the uninterrupted run: {ok}")
                differ += not ok
                continue
            procs = [start(exp, out, cache) for out in outs]
            logs = [p.communicate()[0] for p in procs]
            failed = [log[-400:] for p, log in zip(procs, logs, strict=True) if p.returncode]
            crashes += len(failed)
            if not reference.exists() and not failed:
                reference.write_bytes(outs[0].read_bytes())
            ok = not failed and same(outs[0], outs[1])
            differ += not ok
            as_first = not failed and not differences(outs[0], reference)
            across += as_first
            corrupt = len(list(cache.rglob("*.corrupt")))
            leftover = len(list(cache.rglob("*.tmp")))
            print(
                f"pair {i + 1:2d}: exit codes {[p.returncode for p in procs]}, identical {ok} "
                f"(as pair 1: {as_first}), corrupt entries {corrupt}, temporary files {leftover}"
            )
            for log in failed:
                print("   ", " ".join(log.split())[-300:])
    kind = "killed-and-resumed runs" if args.kill else "concurrent pairs"
    print(
        f"\n{args.pairs} {kind}: {crashes} crash(es), {args.pairs - differ}/{args.pairs} with "
        f"identical results ({time.perf_counter() - t0:.0f} s)"
    )
    if not args.kill:
        print(f"pairs whose results equal the first pair's: {across}/{args.pairs}")


if __name__ == "__main__":
    main()
