"""How noisy is one render, in the 8-bit steps the camera pipeline keeps? (issue 11)

Adaptive sampling would stop sampling a pixel once the standard error of its mean, carried through
the camera pipeline, is below a stated fraction of an 8-bit step. Whether that saves samples
depends on where the baseline's sample count lies against that floor, which this script measures.

For ``--configs`` configurations of the experiment (drawn with a fixed seed), the stickers' own
pixels (:func:`simgap.pipeline.region.sticker_region` with no margin) are path traced twice at
``--spp`` samples (default 16) with two render seeds, and once more at ``--factor`` times the
samples.
Each render is encoded as the detector sees it (8-bit sRGB, grey); the per-pixel render noise is
the standard deviation of the two renders' difference over sqrt(2). Printed per sample count:

- the per-pixel render noise (DN, median over configurations);
- the same at ``--factor`` times the samples (against the mean of the two renders, whose own noise
  is taken out), which checks the 1/sqrt(samples) law;
- the same estimated from each pixel's own samples as if they were independent (what a per-pixel
  stopping rule reads); the sampler stratifies a pixel's samples, so the true error is smaller;
- the samples a pixel needs for the render noise to fall to ``--target`` DN (from the measured
  noise and the 1/sqrt(samples) law, which the ``--factor`` row checks).

Usage: ``python benchmarks/render_noise.py [--experiment experiments/baseline.yaml]
[--configs 8] [--spp 16] [--factor 4] [--target 0.5]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import colour
import numpy as np

from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.region import OUTLINE_POINTS_PER_SIDE, sticker_region
from simgap.pipeline.sweep import experiment_pipelines
from simgap.render import imaging
from simgap.render.scene import FixtureScene, projected_sticker_outlines


def grey_dn(linear: np.ndarray) -> np.ndarray:
    """The detector's grey value (DN, float) of linear RGB pixels (N, 3)."""
    return imaging.to_gray(imaging.encode_srgb8(linear[None]))[0].astype(float)


def srgb(linear: np.ndarray) -> np.ndarray:
    """The sRGB encoding (0-1) of linear values, as the camera pipeline applies it."""
    return colour.cctf_encoding(linear, function="sRGB")


def independent_sample_error(
    one: FixtureScene, spp: int, pixels: np.ndarray, seed: int
) -> np.ndarray:
    """Per-pixel standard error (DN) of the mean if the pixel's samples were independent.

    ``one`` renders one sample a pixel (posed); ``spp`` of them are drawn for every pixel. The
    samples' own variance over their count, through the sRGB slope at the pixel's mean and the
    grey frame's channel weights: what a stopping rule reading each pixel's sample spread would
    estimate.
    """
    repeated = np.repeat(pixels, spp, axis=0)
    samples = one.render_pixels(repeated, seed).reshape(len(pixels), spp, 3)
    # each channel's sRGB slope (DN per unit linear radiance) at the pixel's mean, then the grey
    # frame's weights: the first-order change of the grey DN with each sample
    level, step = np.clip(samples.mean(axis=1), 1e-4, 1.0), 1e-5
    slope = 255.0 * (srgb(level + step) - srgb(level - step)) / (2 * step)
    grey = np.einsum("nsc,nc,c->ns", samples, slope, np.asarray(imaging.GRAY_WEIGHTS))
    return grey.std(axis=1, ddof=1) / np.sqrt(spp)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--experiment", type=Path, default=Path("experiments/baseline.yaml"))
    ap.add_argument("--configs", type=int, default=8)
    ap.add_argument("--spp", type=int, default=16, help="path-traced samples per pixel")
    ap.add_argument("--factor", type=int, default=4)
    ap.add_argument("--target", type=float, default=0.5, help="render noise to reach (DN)")
    args = ap.parse_args()

    # path traced (the baseline renders converged since issue 28: benchmarks/converged_render.py)
    exp = load_experiment(args.experiment).with_render(spp=args.spp, mode="path")
    with tempfile.TemporaryDirectory() as tmp:
        pipe = experiment_pipelines(exp, Path(tmp))[0]
        scene = pipe.scene()
        more, one = (
            experiment_pipelines(exp.with_render(spp=n), Path(tmp))[0].scene()
            for n in (scene.spp * args.factor, 1)
        )
        s = pipe.state.scene
        positions, thetas = exp.configuration_axes()[:2]
        grid = [(int(p), float(t)) for p in positions for t in thetas]
        picks = np.random.default_rng(0).permutation(len(grid))
        rows, t0 = [], time.perf_counter()
        for p, theta in (grid[i] for i in picks):
            outlines = projected_sticker_outlines(
                exp.rig_model, p, theta, s.errors, s.camera, s.tag_scale, OUTLINE_POINTS_PER_SIDE
            )
            region = sticker_region(outlines, 0, pipe.image_size)
            if region is None:
                continue
            for posed in (scene, more, one):
                posed.set_pose(p, theta)
            pixels = region.pixels()
            a, b = (grey_dn(scene.render_pixels(pixels, seed)) for seed in (1, 2))
            c = grey_dn(more.render_pixels(pixels, 3))
            rows.append(
                (
                    np.std(a - b) / np.sqrt(2),
                    np.sqrt(max(np.var(c - 0.5 * (a + b)) - 0.25 * np.var(a - b), 0.0)),
                    float(np.median(independent_sample_error(one, scene.spp, pixels, 4))),
                    len(pixels),
                )
            )
            print(f"p {p:2d} theta {np.degrees(theta):5.1f} deg: {len(pixels)} sticker pixels, "
                  f"render noise {rows[-1][0]:.2f} DN at {scene.spp} spp", flush=True)  # fmt: skip
            if len(rows) == args.configs:
                break
    noise, noise_more, independent, _ = np.median(np.array(rows), axis=0)
    spp = scene.spp
    print(f"\n{args.experiment} ({len(rows)} configurations, {time.perf_counter() - t0:.0f} s):")
    print(f"  render noise per sticker pixel at {spp} spp: {noise:.2f} DN (median)")
    print(f"  at {spp * args.factor} spp: {noise_more:.2f} DN "
          f"(1/sqrt(samples) predicts {noise / np.sqrt(args.factor):.2f})")  # fmt: skip
    print(f"  read from each pixel's samples as if independent: {independent:.2f} DN "
          f"({independent / noise:.1f}x the true error: the sampler stratifies)")  # fmt: skip
    need = spp * (noise / args.target) ** 2
    print(f"  samples a pixel needs for {args.target} DN: {need:.0f} "
          f"({need / spp:.0f}x the experiment's {spp})")  # fmt: skip


if __name__ == "__main__":
    main()
