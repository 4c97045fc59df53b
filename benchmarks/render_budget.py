"""Where a baseline configuration's time goes, and what half the 16-spp sweep leaves a render.

Issue 28's speed bar asks the converged sweep to take at most half of the 16-spp sweep in the
same run, on the premise that the converged render's extra pass is "primary rays only, nearly
free" and that its samples are what a sweep pays for. This prints, in one run, on the same
``--configs`` x ``--configs`` configurations drawn like :mod:`converged_render`'s sweep:

- **Stages**, per mode (path traced at 16 and at 4 spp, converged at 4): each configuration run
  from an empty cache through the whole pipeline in this process (one worker, no Dask, so that
  the pipeline's own stage timers, :attr:`simgap.pipeline.variant.VariantPipeline.seconds`, add
  up to the wall time), in ms a configuration: the render (``sampling``) and everything else
  (detection, PnP, image statistics, the camera's image pipeline, cache IO, posing the scene).
- **The budget**: half the 16-spp total minus the converged run's work besides the render: the
  time a render may take for the converged sweep to meet the bar.
- **Floors** of any render that traces the region, on one posed scene at the same
  configurations (each the least of three runs: warm kernels; no IO): one kernel launch on two
  pixels (what a render costs before its pixels), every region pixel path traced once (1 spp),
  every region pixel's primary rays with their sticker and albedo (2 fixed rays a pixel, the
  fewest the footprint pass takes), every region pixel path traced at 4 spp with its primary
  hits (the converged render's first pass) and the whole converged render.

Usage: ``python benchmarks/render_budget.py [--configs 10] [--seed 2]``
"""

from __future__ import annotations

import argparse
import gc
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
from converged_render import drawn

from simgap.pipeline.experiment import Experiment, load_experiment
from simgap.pipeline.sweep import experiment_pipelines
from simgap.pipeline.variant import clear_scenes
from simgap.render.pixel_samples import footprint_samples

#: The pipeline's stage that renders (:attr:`simgap.pipeline.variant.VariantPipeline.seconds`).
RENDER_STAGE = "sampling"


def stages(exp: Experiment, label: str) -> tuple[Counter[str], float, int]:
    """Stage seconds, wall seconds and configurations of ``exp`` run here from an empty cache."""
    p_all, theta_all, _ = exp.configuration_axes()
    configs = [(int(p), float(t)) for p in p_all for t in theta_all]
    clear_scenes()  # only this run's scene alive, as in a sweep's worker (:func:`floors`)
    gc.collect()
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        pipe = experiment_pipelines(exp, Path(cache))[0]
        pipe.scene()  # the scene load is once a process: not a configuration's cost
        pipe.seconds.clear()
        t0 = time.perf_counter()
        for p, theta in configs:
            pipe.run(p, theta, 0, 0)
        wall = time.perf_counter() - t0
    rest = wall - sum(pipe.seconds.values())
    per = {k: 1e3 * v / len(configs) for k, v in pipe.seconds.most_common()}
    print(
        f"{label}: {1e3 * wall / len(configs):.1f} ms a configuration; "
        + ", ".join(f"{k} {v:.1f}" for k, v in per.items())
        + f", untimed {1e3 * rest / len(configs):.1f} ms",
        flush=True,
    )
    return pipe.seconds, wall, len(configs)


def path_once(scene, pixels: np.ndarray) -> np.ndarray:
    """Every pixel path traced once, in one launch (N, 3): the least a path tracer does."""
    import drjit as dr

    padded = np.resize(pixels, (max(len(pixels), 2), 2)).astype(np.float32)
    _, value = scene.trace(padded, 0, 1)
    dr.eval(value)
    return np.stack([np.asarray(c) for c in (value.x, value.y, value.z)], axis=-1)


def floors(exp: Experiment) -> dict[str, float]:
    """ms a configuration of the renders that bound any render of the region (module docstring).

    On one Mitsuba scene, alone in the process as in a sweep's worker: every other scene alive
    slows each launch (benchmarks/scenes_alive.py).
    """
    from simgap.render.converged import converged_pixels
    from simgap.render.pixel_samples import sample_pixels

    clear_scenes()
    gc.collect()
    p_all, theta_all, _ = exp.configuration_axes()
    configs = [(int(p), float(t)) for p in p_all for t in theta_all]
    out: Counter[str] = Counter()
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        pipe = experiment_pipelines(exp.with_render(mode="converged", spp=4), Path(cache))[0]
        scene = pipe.scene()
        steps = {
            "one launch (2 pixels)": lambda px: path_once(scene, px[:2]),
            "path 1 spp, every region pixel": lambda px: path_once(scene, px),
            "primary rays, 2 a pixel": lambda px: footprint_samples(scene, px, 2),
            "path 4 spp with primary hits": lambda px: sample_pixels(scene, px, 0),
            "converged 4 spp, all of it": lambda px: converged_pixels(scene, px, 0),
        }
        for p, theta in configs:
            region = pipe.region(p, theta)
            if region is None:
                continue
            scene.set_pose(p, theta)
            pixels = region.pixels()
            for name, step in steps.items():
                # the least of three runs: Dr.Jit compiles a kernel on its first launch at a new
                # size (about 0.2 s, measured), and frees the last step's arrays at a later one:
                # neither is the render's own cost
                times = []
                for _ in range(3):
                    t0 = time.perf_counter()
                    step(pixels)
                    times.append(time.perf_counter() - t0)
                out[name] += min(times)
    clear_scenes()
    return {k: 1e3 * v / len(configs) for k, v in out.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", type=int, default=10, help="pin holes and angles drawn")
    parser.add_argument("--seed", type=int, default=2)
    parser.add_argument(
        "--experiment", type=Path, default=Path(__file__).parents[1] / "experiments/baseline.yaml"
    )
    args = parser.parse_args()
    exp = drawn(load_experiment(args.experiment), args.configs, args.seed)
    print(f"configurations: {exp.configurations}", flush=True)
    runs = {}
    for label, settings in (
        ("path 16 spp", {"mode": "path", "spp": 16}),
        ("path 4 spp", {"mode": "path", "spp": 4}),
        ("converged 4 spp", {"mode": "converged", "spp": 4}),
    ):
        runs[label] = stages(exp.with_render(**settings, seed=0), label)

    def ms(label: str, render: bool) -> float:
        seconds, wall, n = runs[label]
        other = wall - seconds[RENDER_STAGE]
        return 1e3 * (seconds[RENDER_STAGE] if render else other) / n

    total16 = ms("path 16 spp", True) + ms("path 16 spp", False)
    other = ms("converged 4 spp", False)
    budget = 0.5 * total16 - other
    print(
        f"16-spp sweep {total16:.1f} ms a configuration, {ms('path 16 spp', True):.1f} of it the "
        f"render; the converged run's other work {other:.1f} ms "
        f"({other / total16:.0%} of the 16-spp total)"
    )
    print(f"budget for a converged render at half the 16-spp sweep: {budget:.1f} ms a config.")
    print("floors, on the same posed configurations (warm kernels, no IO), ms a configuration:")
    for name, value in floors(exp).items():
        print(f"  {name}: {value:.1f} ({value / budget:.2f} of the budget)")


if __name__ == "__main__":
    main()
