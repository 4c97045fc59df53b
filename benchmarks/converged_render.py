"""Converged renders against path tracing, in one run (issue 28).

Three parts, the first two from an empty cache through the whole pipeline (render, camera,
detector, PnP):

- **Accuracy**: the scene variants ``--variants`` of ``--accuracy-experiment`` (baseline, a
  point light whose shadows cross the fixture, a spot light, laminated prints, an uncalibrated
  distortion, a defocused lens), each restricted to the configurations drawn with ``--seed``
  from ``--configs`` pin holes x ``--configs`` angles, path traced at ``--ref-spp`` (the
  reference), at 16 spp, and converged at ``--spp`` (4). Per variant and run: the detected
  corners' distance from the reference's (median and RMS over detections, px) and the mean
  |difference| of the estimated pose per axis (mm, mrad). The issue's bars: 0.02 px, 0.1 mm,
  1 mrad.
- **Render noise** of the stickers' fully covered pixels, per variant over the same
  configurations: two render seeds' difference / sqrt 2 in DN of the sRGB encoding before
  rounding (median and RMS), converged at ``--spp`` and path traced at 16 spp. The issue's bar:
  0.5 DN.
- **Seeds and speed**: the whole baseline sweep (``--sweep-configs`` configurations, default all
  540) path traced at 16 spp and converged at ``--spp``, each at render seeds 0 and 1. Per mode:
  the wall time of the seed-0 sweep and the two seeds' mean |difference| (ty in mm, rotations in
  mrad). The issue's bars: 0.1 mm and 1 mrad between seeds, converged at most half the 16-spp
  time. Then the sweep path traced at ``--spp`` alone (seed 0): the cost of tracing every
  region pixel at the converged render's samples, with no demodulation.
- **The naive way**: the whole frame (1920 x 1080) path traced at the samples that give the
  stickers the converged render's noise (16 spp x (path 16-spp noise / converged noise)^2, both
  measured on the baseline variant above), for ``--naive-configs`` configurations of the sweep.
  That count is thousands, so the frame is timed at 64 and 256 spp and the time extrapolated
  along the straight line through them (the time of a path tracer grows linearly with its
  samples: the two points' time per sample is printed). Against the converged sweep's wall
  time per configuration (which also detects and solves the pose). The issue's bar: 100x.

With ``--ref-seeds 2`` the reference is rendered at two seeds: their difference is the
reference's own noise (a render without noise would sit 1/sqrt 2 of it from either), and the
converged render is also compared with the two references' mean pose. ``--accuracy-only``
stops after the accuracy.

Usage: ``python benchmarks/converged_render.py [--configs 3] [--ref-spp 1024] [--spp 4]
[--sweep-configs 540] [--naive-configs 1] [--variants baseline,glossy_tags] [--ref-seeds 2]
[--accuracy-only]``
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from simgap.pipeline.experiment import Configurations, Experiment, load_experiment
from simgap.pipeline.simulator import Simulator


def run(exp, label: str) -> tuple[xr.Dataset, float]:
    """The experiment's dataset from an empty cache, and its wall time (s)."""
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        t0 = time.perf_counter()
        ds = Simulator(Path(cache), show_progress=False).dataset(exp)
        seconds = time.perf_counter() - t0
    print(f"{label}: {seconds:.1f} s", flush=True)
    return ds, seconds


def compare(ds: xr.Dataset, ref: xr.Dataset, label: str) -> None:
    """Corner distance (px, median and RMS over detections) and mean |pose difference| per axis
    against the reference."""
    both = ds["detected"].values & ref["detected"].values
    corners = ds["corners"].values[both] - ref["corners"].values[both]
    per_detection = np.sqrt(np.mean(np.sum(corners**2, axis=-1), axis=-1))
    rms = float(np.sqrt(np.nanmean(per_detection**2)))
    diff = np.abs(ds["estimated"].values[both] - ref["estimated"].values[both])
    mean = np.nanmean(diff, axis=0)
    print(
        f"  {label}: {int(both.sum())} detections, corners median {np.median(per_detection):.3f} "
        f"RMS {rms:.3f} px; pose mean |diff| "
        f"tx {mean[0] * 1e3:.3f} ty {mean[1] * 1e3:.3f} tz {mean[2] * 1e3:.3f} mm, "
        f"rx {mean[3] * 1e3:.2f} ry {mean[4] * 1e3:.2f} rz {mean[5] * 1e3:.2f} mrad",
        flush=True,
    )


def mean_pose(refs: list[xr.Dataset]) -> xr.Dataset:
    """The mean over ``refs`` of each estimated pose and detected corner (detected in all).

    The pose's rotation vectors are averaged element by element, which holds while they agree;
    a detection whose references differ by more than 0.5 rad on a rotation axis (a flip of the
    planar ambiguity, or the rotation vector's other branch near pi) is left out.
    """
    out = refs[0].copy()
    for name in ("estimated", "corners"):
        out[name] = (refs[0][name].dims, np.mean([r[name].values for r in refs], axis=0))
    rotations = np.stack([r["estimated"].values[..., 3:] for r in refs])
    agree = np.nan_to_num(np.ptp(rotations, axis=0), nan=0.0).max(-1) <= 0.5
    detected = np.logical_and.reduce([r["detected"].values for r in refs]) & agree
    out["detected"] = (refs[0]["detected"].dims, detected)
    return out


def render_noise(exp: Experiment, spp: int) -> dict[str, tuple[float, float]]:
    """Per variant: two render seeds' difference / sqrt 2 on fully covered sticker pixels (DN of
    the sRGB encoding, not rounded), converged at ``spp`` and path traced at 16 spp.

    Returns the RMS (DN) per variant: (converged, path 16 spp).
    """
    import colour

    from simgap.pipeline.sweep import experiment_pipelines
    from simgap.render.converged import converged_pixels
    from simgap.render.pixel_samples import sample_pixels

    def dn(linear: np.ndarray) -> np.ndarray:
        """sRGB-encoded value in DN, not rounded (rounding alone adds 0.29 DN RMS a frame)."""
        return 255.0 * colour.cctf_encoding(np.clip(linear, 0.0, 1.0), function="sRGB")

    p_all, theta_all, _ = exp.configuration_axes()
    out = {}
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        pipes = experiment_pipelines(exp.with_render(spp=spp, mode="converged"), Path(cache))
        for pipe, spec in zip(pipes, exp.variant_specs(), strict=True):
            scene = pipe.scene()
            converged, path = [], []
            for p in p_all:
                for theta in theta_all:
                    region = pipe.region(int(p), float(theta))
                    if region is None:
                        continue
                    scene.set_pose(int(p), float(theta))
                    pixels = region.pixels()
                    first = sample_pixels(scene, pixels, 0, 16)
                    inside = first.coverage >= 1.0
                    second = sample_pixels(scene, pixels, 1, 16)
                    path.append(dn(first.mean[inside]) - dn(second.mean[inside]))
                    a = converged_pixels(scene, pixels, 0).values[inside]
                    b = converged_pixels(scene, pixels, 1).values[inside]
                    converged.append(dn(a) - dn(b))
            row, rms = [], []
            for label, diffs in ((f"converged {spp} spp", converged), ("path 16 spp", path)):
                d = np.abs(np.concatenate(diffs)) / np.sqrt(2)
                rms.append(float(np.sqrt(np.mean(d**2))))
                row.append(f"{label} median {np.median(d):.2f} RMS {rms[-1]:.2f}")
            out[spec.name] = (rms[0], rms[1])
            print(f"  {spec.name}: render noise (DN) " + "; ".join(row), flush=True)
    return out


def naive_full_frame(exp: Experiment, spp: int, configurations: int, seed: int) -> float:
    """Seconds per configuration to path trace the whole frame at ``spp`` (no cache, no IO)."""
    from simgap.pipeline.sweep import experiment_pipelines

    p_all, theta_all, _ = exp.configuration_axes()
    rng = np.random.default_rng(seed)
    picks = [(int(rng.choice(p_all)), float(rng.choice(theta_all))) for _ in range(configurations)]
    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as cache:
        pipe = experiment_pipelines(exp.with_render(spp=spp, mode="path"), Path(cache))[0]
        scene = pipe.scene()
        w, h = pipe.image_size
        rows, cols = np.mgrid[0:h, 0:w]
        pixels = np.stack([cols.ravel(), rows.ravel()], axis=1)
        scene.set_pose(*picks[0])
        scene.render_pixels(pixels[:4096], 0)  # compile the kernel outside the timing
        t0 = time.perf_counter()
        for p, theta in picks:
            scene.set_pose(p, theta)
            scene.render_pixels(pixels, 0)
        return (time.perf_counter() - t0) / configurations


def drawn(base: Experiment, n: int, seed: int) -> Experiment:
    """``base`` on ``n`` pin holes x ``n`` angles drawn from its grid (without replacement)."""
    if n * n >= len(base.configuration_axes()[0]) * len(base.configuration_axes()[1]):
        return base
    rng = np.random.default_rng(seed)
    p_all, theta_all, _ = base.configuration_axes()
    ps = rng.choice(np.asarray(p_all), size=min(n, len(p_all)), replace=False)
    thetas = rng.choice(
        np.rad2deg(np.asarray(theta_all)), size=min(n, len(theta_all)), replace=False
    )
    configurations = Configurations(
        tuple(sorted({int(p) for p in ps})), tuple(sorted({float(t) for t in thetas})), ()
    )
    return dataclasses.replace(base, configurations=configurations)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--configs", type=int, default=3)
    parser.add_argument("--ref-spp", type=int, default=1024)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--sweep-configs", type=int, default=540)
    parser.add_argument("--naive-configs", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--ref-seeds",
        type=int,
        default=1,
        help="references at render seeds 0..N-1 (N >= 2: "
        "the reference's own noise, and the converged render against their mean pose)",
    )
    parser.add_argument("--accuracy-only", action="store_true", help="stop after the accuracy")
    parser.add_argument("--experiment", default="experiments/baseline.yaml")
    parser.add_argument("--accuracy-experiment", default="experiments/rendering_options.yaml")
    parser.add_argument(
        "--variants",
        default="baseline,light_point,light_spot_3000K,glossy_tags,distortion_uncalibrated,defocus",
    )
    args = parser.parse_args()
    if args.ref_seeds < 1:
        parser.error("--ref-seeds: expected an integer >= 1")
    base = load_experiment(args.experiment)

    names = args.variants.split(",")
    options = load_experiment(args.accuracy_experiment)
    options = dataclasses.replace(
        options, variants=tuple(v for v in options.variants if v.name in names)
    )
    exp = drawn(options, args.configs, args.seed)
    n = len(exp.configuration_axes()[0]) * len(exp.configuration_axes()[1])
    print(f"accuracy: {exp.configurations}, {len(exp.variant_specs())} variants x {n}", flush=True)
    refs = []
    for seed in range(args.ref_seeds):
        reference = exp.with_render(spp=args.ref_spp, mode="path", seed=seed)
        refs.append(run(reference, f"reference: path {args.ref_spp} spp, render seed {seed}")[0])
    ref = refs[0]
    path, _ = run(exp.with_render(spp=16, mode="path"), "path 16 spp")
    conv, _ = run(exp.with_render(spp=args.spp, mode="converged"), f"converged {args.spp} spp")
    for variant in [s.name for s in exp.variant_specs()] + [None]:
        pick = (lambda d: d) if variant is None else (lambda d, v=variant: d.sel(variant=v))
        print(f"{variant or 'all variants'}:", flush=True)
        compare(pick(path), pick(ref), "path 16 spp")
        compare(pick(conv), pick(ref), f"converged {args.spp} spp")
        if len(refs) > 1:
            # the reference's own noise: a render with none would sit 1 / sqrt 2 of the two
            # references' difference from either (Gaussian noise), and 1 / sqrt(2 n) of it from
            # the mean of n references' poses
            compare(pick(refs[1]), pick(ref), "reference seed 1 against seed 0")
            compare(pick(conv), pick(mean_pose(refs)), f"converged {args.spp} spp, mean reference")
    if args.accuracy_only:
        return
    print("render noise:", flush=True)
    noise = render_noise(exp, args.spp)

    # about --sweep-configs configurations: as many pin holes as angles
    sweep = drawn(base, int(np.ceil(np.sqrt(args.sweep_configs))), args.seed + 1)
    print(f"seeds and speed: {sweep.configurations}", flush=True)
    seconds = {}
    modes = {
        "path 16 spp": {"spp": 16, "mode": "path"},
        f"converged {args.spp} spp": {"spp": args.spp, "mode": "converged"},
    }
    for label, settings in modes.items():
        seeds = []
        for seed in (0, 1):
            ds, t = run(sweep.with_render(**settings, seed=seed), f"{label}, render seed {seed}")
            seeds.append(ds)
            seconds.setdefault(label, t)
        compare(seeds[1], seeds[0], f"{label}: render seed 1 against seed 0")
    path_s, conv_s = seconds.values()
    print(f"speed: converged / path 16 spp = {conv_s / path_s:.2f} (bar: <= 0.5)")
    # the floor of any render that path traces every region pixel at the converged samples
    _, floor_s = run(sweep.with_render(spp=args.spp, mode="path"), f"path {args.spp} spp")
    print(
        f"path {args.spp} spp alone / path 16 spp = {floor_s / path_s:.2f}; converged / path "
        f"{args.spp} spp = {conv_s / floor_s:.2f}"
    )

    converged_noise, path_noise = noise.get("baseline", next(iter(noise.values())))
    equal_spp = 16.0 * (path_noise / converged_noise) ** 2
    timed = {n: naive_full_frame(sweep, n, args.naive_configs, args.seed) for n in (64, 256)}
    per_sample = (timed[256] - timed[64]) / (256 - 64)
    naive_s = timed[64] + per_sample * (equal_spp - 64)
    n_sweep = len(sweep.configuration_axes()[0]) * len(sweep.configuration_axes()[1])
    print(
        f"naive full frame: 64 spp {timed[64]:.1f} s, 256 spp {timed[256]:.1f} s a configuration "
        f"({timed[64] / 64 * 1e3:.1f} and {timed[256] / 256 * 1e3:.1f} ms a sample per pixel); "
        f"the converged noise at {equal_spp:.0f} spp: {naive_s:.0f} s a configuration"
    )
    print(
        f"speed-up over the naive way: {naive_s / (conv_s / n_sweep):.0f}x "
        f"(converged sweep {conv_s / n_sweep:.3f} s a configuration; bar: >= 100x)"
    )


if __name__ == "__main__":
    main()
