"""Fewer samples at equal accuracy? The path-traced sweep at fewer samples or pixels (issue 11).

For each sample count and each render margin (:mod:`simgap.pipeline.region`: pixels within that
distance of a sticker are rendered), one sequential pass over the experiment's configurations (every
``--every``-th, default all) from an empty cache in this process: sampling seconds per
configuration, detections compared with the reference sample count's (identical?), and the mean
absolute difference of the pose errors per axis over the tags detected at both (and the median;
issue 11's bar: <= 0.1 mm and 1 mrad over the full sweep), beside the same difference between two
reference passes with other render seeds: the reference's own render noise, which that bar is to
be read against (measured 2026-11-23 on every 5th configuration of the baseline: 1.1 mm in ty,
7 mrad in rz between two 16-spp seeds). Poses on the other branch of the planar ambiguity (a
rotation difference beyond ``simgap.diagnosis.items.FLIP_RAD``) are counted and left out.

Usage: ``python benchmarks/render_accuracy.py [--spp 4,8] [--margins 8,12] [--every 1]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from simgap.analysis.thresholds import FLIP_RAD
from simgap.core.axes import AXES
from simgap.pipeline.cache import Cache
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.variant import VariantPipeline, assets_hash


def sweep(exp, configs, cache: Path) -> tuple[np.ndarray, np.ndarray, float]:
    """Detections (C, T), errors (C, T, 6) and sampling seconds per configuration of one pass."""
    state = exp.variant_states()[0][1]
    tags = tuple(int(t) for t in exp.configuration_axes()[2])
    pipe = VariantPipeline(
        exp.rig_model, state, tags, exp.render.margin_px, Cache(cache), assets_hash()
    )
    detected, errors = [], []
    for p, theta in configs:
        result = pipe.run(p, theta, 0, 0)
        detected.append(result.detected)
        errors.append(result.error)
    sampling = pipe.seconds["sampling"] / len(configs)
    return np.array(detected), np.array(errors), sampling


def compare(ref: tuple, other: tuple) -> str:
    """Detections alike, flips, and mean |delta error| per axis (mm, mrad) of two passes."""
    (d0, e0, _), (d1, e1, _) = ref, other
    both = d0 & d1
    delta = (e1 - e0)[both]
    flips = np.abs(delta[:, 3:]).max(axis=1) > FLIP_RAD
    delta = np.abs(delta[~flips])
    means = [
        f"{a} {1e3 * delta[:, k].mean():.3f} ({1e3 * np.median(delta[:, k]):.3f})"
        for k, a in enumerate(AXES)
    ]
    changed = int((d0 != d1).sum())
    return (
        f"detections {'identical' if changed == 0 else f'{changed} differ'} "
        f"({int(d0.sum())} at the reference), flips {int(flips.sum())}; "
        f"mean (median) |delta| (mm, mrad): {', '.join(means)}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--experiment", default="experiments/baseline.yaml")
    ap.add_argument("--spp", default="4,8", help="sample counts to try, comma-separated")
    ap.add_argument("--margins", default="8,12", help="render margins to try (px), comma-separated")
    ap.add_argument("--reference", type=int, default=16, help="reference samples per pixel")
    ap.add_argument("--reference-margin", type=int, default=24, help="reference margin (px)")
    ap.add_argument("--every", type=int, default=1, help="every k-th configuration")
    args = ap.parse_args()
    base = load_experiment(args.experiment)
    ps, thetas, _ = base.configuration_axes()
    configs = [(int(p), float(t)) for p in ps for t in thetas][:: args.every]

    def at(spp: int, seed: int, margin: int = args.reference_margin):
        return base.with_render(spp=spp, seed=seed, margin_px=margin, mode="path")

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        ref = sweep(at(args.reference, base.render.seed), configs, Path(tmp))
        print(f"{len(configs)} configurations of {base.name} ({time.perf_counter() - t0:.0f} s)")
        print(f"{args.reference:3d} spp (reference, margin {args.reference_margin} px)  "
              f"sampling {1e3 * ref[2]:6.1f} ms/config")  # fmt: skip
        again = sweep(at(args.reference, base.render.seed + 1), configs, Path(tmp))
        print(f"{args.reference:3d} spp, other seed  {compare(ref, again)}")
        for spp in (int(s) for s in args.spp.split(",")):
            low = sweep(at(spp, base.render.seed), configs, Path(tmp))
            ratio = ref[2] / low[2]
            print(f"{spp:3d} spp             sampling {1e3 * low[2]:6.1f} ms/config "
                  f"({ratio:.1f}x less); {compare(ref, low)}")  # fmt: skip
        for margin in (int(m) for m in args.margins.split(",") if m):
            tight = sweep(at(args.reference, base.render.seed, margin), configs, Path(tmp))
            ratio = ref[2] / tight[2]
            print(f"margin {margin:2d} px        sampling {1e3 * tight[2]:6.1f} ms/config "
                  f"({ratio:.1f}x less); {compare(ref, tight)}")  # fmt: skip


if __name__ == "__main__":
    main()
