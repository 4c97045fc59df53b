"""A small focal-length error through a demosaicing camera on frontal poses, seen or hidden.

Renders pseudo-real captures of a camera whose focal length is ``--scale`` longer than its
calibration (default +0.7 %), through a full image pipeline (Bayer colour filter with edge-aware
demosaicing, a 2.2 gamma, a black level, bilateral denoising, sharpening, frame-to-frame gain) on
mostly frontal poses (0, 10, 170, 180, 190 deg and one oblique stop), each with a drawn other
camera (lights, exposure, sensor, pixel filter). Each capture is diagnosed twice: as ingested
(the simulation images through the colour filter the frames show, ``camera_demosaicing``) and
with that reading removed (the simulation without demosaicing). Prints per trial the colour
filter read, the selected effects and the depth gap's significance.

Usage: ``python benchmarks/demosaicing_geometry.py [--trials 6] [--scale 0.007]
[--out out/demosaicing_geometry] [--cache DIR]``
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from simgap.core.paths import default_cache_dir
from simgap.diagnosis.diagnose import diagnose
from simgap.diagnosis.nuisance import FRONTAL_HEAVY_STOPS_DEG, draw_nuisance
from simgap.diagnosis.settings import DiagnoseSettings
from simgap.diagnosis.validate import pseudo_real_experiment, render_capture
from simgap.pipeline.capture import ingest
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.simulator import Simulator

LAYOUTS = ("RGGB", "GRBG", "BGGR", "GBRG")
#: The camera's own pipeline beside the drawn other camera.
PIPELINE = {
    "denoise": {"strength_dn": 8.0, "radius_px": 1.0},
    "sharpen": {"amount": 0.8, "radius_px": 1.0},
    "black_level": {"level": 0.02},
    "gain_change": {"sigma_ev": 0.08},
    "gamma": {"encoding": "gamma", "gamma": 2.2},
}
SEED = 77
#: The one oblique stop of each trial (deg), in turn: both tags, both sides (of
#: :data:`simgap.diagnosis.nuisance.OBLIQUE_STOPS_DEG`).
OBLIQUE_STOPS = (40.0, 320.0, 140.0, 220.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--experiment", default="experiments/baseline.yaml")
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--scale", type=float, default=0.007, help="focal length error")
    parser.add_argument("--out", type=Path, default=Path("out/demosaicing_geometry"))
    parser.add_argument("--cache", type=Path, default=None)
    args = parser.parse_args()
    base = load_experiment(args.experiment)
    rig = base.rig_model
    simulator = Simulator(args.cache or default_cache_dir(), show_progress=False)
    hidden = {"focal_length": {"scale": args.scale}}
    print(f"focal length {args.scale:+.2%}, frontal stops {FRONTAL_HEAVY_STOPS_DEG} + one oblique")
    print("| trial | colour filter read | simulation | selected | ty gap z (significant) |")
    print("|---|---|---|---|---|")
    for i in range(args.trials):
        camera = draw_nuisance(np.random.default_rng([SEED, i]), rig)
        bayer = {"pattern": LAYOUTS[i % 4], "method": "edge_aware"}
        oblique = OBLIQUE_STOPS[i % len(OBLIQUE_STOPS)]
        camera = dataclasses.replace(
            camera,
            effects={**camera.effects, **PIPELINE, "bayer": bayer},
            theta_deg=tuple(sorted((*FRONTAL_HEAVY_STOPS_DEG, oblique))),
        )
        folder = args.out / f"trial_{i:02d}"
        if not (folder / "manifest.csv").is_file():
            exp = pseudo_real_experiment(base, hidden, camera, 5000 + i)
            render_capture(exp, simulator, folder, hidden)
        real = ingest(folder, rig)
        read = json.loads(real.attrs["camera_demosaicing"])
        for label, capture in (
            ("with its demosaicing", real),
            ("without", real.assign_attrs(camera_demosaicing="")),
        ):
            result, _ = diagnose(capture, base, simulator, DiagnoseSettings())
            found = ", ".join(
                f"{f.effect} {f.params['scale']:+.2%}" if "scale" in f.params else f.effect
                for f in (result.selection.findings if result.selection else [])
            )
            gap = result.where.axis_gaps["ty"]
            print(
                f"| {i} | {read['layout']} {read['method']} (ratio {read['ratio']:.2f}) | "
                f"{label} | {found or '-'} | {gap.z_median:.1f} ({gap.significant}) |",
                flush=True,
            )


if __name__ == "__main__":
    main()
