"""The README's picture: two frames of a capture and its diagnosis's error against distance.

Top: the capture's frames nearest and farthest from the camera (p = 0 and p = 14 at theta = 0),
cropped to the fixture; bottom: the diagnosis's ``abs_error_vs_distance.png`` (real, simulated and
simulated with the fitted effects, against camera-to-tag distance, with the mission thresholds).
Made from the README's "Your own captures" example:

    simgap export-bag experiments/pseudo_real_focal.yaml -o out/focal.bag
    simgap ingest out/focal.bag -o out/focal.nc --keep-capture out/focal-capture
    simgap diagnose out/focal.nc --sim experiments/smoke.yaml -o out/focal-diagnosis
    python scripts/overview_figure.py out/focal-capture out/focal-diagnosis
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
#: Crop of a 1920 x 1080 frame around the fixture (rows, columns in px).
CROP = (slice(180, 900), slice(560, 1500))


def frame(capture: Path, p: int, theta_rad: float) -> Path:
    """The image of the manifest row at pin hole ``p`` and turntable angle ``theta_rad``."""
    with open(capture / "manifest.csv", newline="") as f:
        for row in csv.DictReader(f):
            if int(row["p"]) == p and abs(float(row["theta_rad"]) - theta_rad) < 1e-6:
                return capture / row["image"]
    raise SystemExit(f"{capture / 'manifest.csv'}: no frame at p={p}, theta={theta_rad} rad")


def main() -> None:
    """Compose the figure and write it (PNG)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("capture", type=Path)
    parser.add_argument("diagnosis", type=Path)
    parser.add_argument("-o", "--output", type=Path, default=REPO / "docs/images/overview.png")
    args = parser.parse_args()
    errors = plt.imread(args.diagnosis / "abs_error_vs_distance.png")
    fig = plt.figure(figsize=(12, 10.5), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[1, 1.55])
    for ax, p in zip(top.subplots(1, 2), (0, 14), strict=True):
        image = plt.imread(frame(args.capture, p, 0.0))
        ax.imshow(image[CROP], cmap="gray", vmin=0, vmax=1)
        ax.set_title(f"frame at carriage pin hole p = {p}, turntable 0 deg")
        ax.set_axis_off()
    ax = bottom.subplots()
    ax.imshow(errors)
    ax.set_axis_off()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output, dpi=80)
    print(args.output)


if __name__ == "__main__":
    main()
