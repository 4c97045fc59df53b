"""How other Mitsuba scenes alive in a process slow a scene's kernel launches.

Dr.Jit traces a virtual call (a BSDF's, an emitter's) over every instance registered in the
process, so every scene alive adds to every launch of every scene; the pipeline therefore keeps
at most :data:`simgap.pipeline.variant.MAX_SCENES_ALIVE` (docs/results/converged_render_step8.md).
One baseline scene is posed at four configurations (:data:`CONFIGS`); with ``--alive`` other
scenes built beside it (the same scene at other sample counts: each is a scene of its own), it
prints the least of three launches on two pixels and a converged render's time (ms, mean over
the configurations), then the same after the others are deleted.

Usage: ``python benchmarks/scenes_alive.py [--alive 0,1,4,10,20,40]``
"""

from __future__ import annotations

import argparse
import gc
import tempfile
import time
from pathlib import Path

from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.sweep import experiment_pipelines
from simgap.pipeline.variant import clear_scenes
from simgap.render.converged import converged_pixels

#: (pin hole, turntable angle in rad) of the timed configurations
CONFIGS = ((3, 1.0), (5, 2.0), (9, 4.0), (12, 5.5))


def timed(pipe, scene) -> tuple[float, float]:
    """Least of three two-pixel launches and one warm converged render (ms, configuration mean)."""
    launch = render = 0.0
    for p, theta in CONFIGS:
        pixels = pipe.region(p, theta).pixels()
        scene.set_pose(p, theta)
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            scene.render_pixels(pixels[:2], 0)
            times.append(time.perf_counter() - t0)
        launch += min(times)
        converged_pixels(scene, pixels, 0)  # compiles at this region's size
        t0 = time.perf_counter()
        converged_pixels(scene, pixels, 0)
        render += time.perf_counter() - t0
    return 1e3 * launch / len(CONFIGS), 1e3 * render / len(CONFIGS)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--alive", default="0,1,4,10,20,40", help="other scenes alive, ascending")
    parser.add_argument(
        "--experiment", type=Path, default=Path(__file__).parents[1] / "experiments/baseline.yaml"
    )
    args = parser.parse_args()
    exp = load_experiment(args.experiment)
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        pipe = experiment_pipelines(exp.with_render(mode="converged", spp=4), Path(cache))[0]
        scene = pipe.scene()
        built = 0
        for alive in (int(a) for a in args.alive.split(",")):
            while built < alive:
                # another sample count (a square, as the sampler wants) is a scene of its own;
                # kept alive beside the first (the pipeline would otherwise drop the least used)
                other = exp.with_render(mode="converged", spp=(3 + built) ** 2)
                other_pipe = experiment_pipelines(other, Path(cache))[0]
                other_pipe.scenes_alive = alive + 1
                other_pipe.scene()
                built += 1
            launch, render = timed(pipe, scene)
            print(
                f"other scenes alive {alive:3d}: launch of two pixels {launch:6.1f} ms, "
                f"converged render {render:6.1f} ms",
                flush=True,
            )
        clear_scenes()
        gc.collect()
        scene = pipe.scene()  # built again, alone
        launch, render = timed(pipe, scene)
        print(f"the others deleted: launch {launch:.1f} ms, converged render {render:.1f} ms")


if __name__ == "__main__":
    main()
