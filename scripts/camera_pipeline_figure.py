"""A rendered tag's corner through each stage of a camera's own image pipeline, side by side.

One near, frontal tag (pin hole 2, turntable 0 deg, the smoke study's render) through each stage
of ``simgap.effects.camera_pipeline`` and the lens's lateral colour, magnified around the marker's
top-left corner, each panel titled with the stage and its signature statistic (the same renders
and settings as tests/test_camera_pipeline.py). Writes docs/images/camera_pipeline.png:

    python scripts/camera_pipeline_figure.py [-o PATH] [--cache DIR]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import matplotlib
import numpy as np
import yaml

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from simgap.pipeline.experiment import load_experiment  # noqa: E402
from simgap.pipeline.sweep import experiment_pipelines  # noqa: E402
from simgap.pose.image_stats import STAT_INDEX  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
P, THETA_DEG = 2, 0.0
#: Half the side of the magnified window around the marker's top-left corner (px).
HALF_PX = 12
NOISE = {"sensor_noise": {"full_well_e": 2000, "read_noise_e": 5}}
#: (panel title, effects, signature statistic shown and its format).
PANELS = (
    ("as simulated", {}, "edge_overshoot", "overshoot {:.0%}"),
    ("sharpening (amount 1, 1 px)", {"sharpen": {"amount": 1.0, "radius_px": 1.0}},
     "edge_overshoot", "overshoot {:.0%}"),
    ("shot and read noise", NOISE, "noise_paper_dn", "paper noise {:.1f} DN"),
    ("noise, then denoising (12 DN, 1 px)",
     {**NOISE, "denoise": {"strength_dn": 12, "radius_px": 1.0}},
     "noise_paper_dn", "paper noise {:.1f} DN"),
    ("Bayer RGGB, edge-aware demosaicing", {"bayer": {"method": "edge_aware"}},
     "colour_fringe_dn", "colour fringe {:.0f} DN"),
    ("lateral colour (1.5 px at the corner)", {"chromatic_aberration": {"shift_px": 1.5}},
     "colour_fringe_dn", "colour fringe {:.0f} DN"),
    ("black level (5 % of full scale)", {"black_level": {"level": 0.05}},
     "black_clipped_fraction", "{:.0%} of the sticker at 0 DN"),
    ("tone curve (S-curve, slope 5)", {"tone_curve": {"contrast": 5, "midpoint": 0.5}},
     "ink_linear", "ink {:.3f} linear"),
)  # fmt: skip


def main() -> None:
    """Render the panels and write the figure (PNG)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "-o", "--output", type=Path, default=REPO / "docs/images/camera_pipeline.png"
    )
    parser.add_argument("--cache", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="simgap-figure-") as tmp:
        path = Path(tmp) / "stages.yaml"
        data = {
            "name": "stages",
            "inherit": str(REPO / "experiments" / "smoke.yaml"),
            "configurations": {"p": [P], "theta_deg": [THETA_DEG]},
            "variants": [{"name": f"v{i}", "effects": e} for i, (_, e, _, _) in enumerate(PANELS)],
        }
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        exp = load_experiment(path)
        # the experiment's own baseline comes first, then one variant per panel
        pipes = experiment_pipelines(exp, args.cache or Path(tmp) / "cache")[-len(PANELS) :]
        fig, axes = plt.subplots(2, 4, figsize=(14, 7.6), layout="constrained")
        theta = float(np.radians(THETA_DEG))
        # one full-frame window for every panel: around the first panel's detected corner
        corner = np.round(pipes[0].run(P, theta, 0, 0).corners[0][0]).astype(int)
        for ax, pipe, (title, _, stat, fmt) in zip(axes.ravel(), pipes, PANELS, strict=True):
            result = pipe.run(P, theta, 0, 0)
            frame = pipe.frame(P, theta, 0, 0)
            x, y = corner - np.asarray(frame.offset)  # each crop starts elsewhere
            window = frame.crop[y - HALF_PX : y + HALF_PX, x - HALF_PX : x + HALF_PX]
            ax.imshow(window, interpolation="nearest")
            ax.set_title(
                f"{title}\n{fmt.format(result.image_stats[0, STAT_INDEX[stat]])}", fontsize=10
            )
            ax.set_xticks([])
            ax.set_yticks([])
        fig.suptitle(
            "A camera's own image pipeline at a tag's corner "
            f"({2 * HALF_PX} x {2 * HALF_PX} px, pin hole {P}, {THETA_DEG:g} deg)"
        )
        args.output.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.output, dpi=90)
    print(args.output)


if __name__ == "__main__":
    main()
