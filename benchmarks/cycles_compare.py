"""Seconds per configuration at equal noise: simgap's Mitsuba crops against Blender Cycles (CPU).

What a user would pick instead of simgap's renderer: Blender Cycles on the CPU. Both render the
same configurations of an experiment in one run (default: 8 spread over the baseline sweep), the
same crops (Cycles the whole rectangle as its render border, simgap only the pixels near the
stickers, :mod:`simgap.pipeline.region`), meshes, tag textures, materials, lights and camera;
adaptive sampling and denoising off (``benchmarks/cycles_worker.py`` says how the scene is carried
over). Prints, per renderer and sample count, the seconds per configuration (pose update and
sampling; scene load and kernel compilation apart) and the relative noise of the flat paper around
each tag (sigma / level of the quiet zone, :func:`simgap.pose.image_stats.tag_stats`), then Cycles'
time at simgap's noise level (noise ~ spp^-1/2 and time ~ spp, fitted over Cycles' sample counts)
and the ratio. Checks that the two scenes agree: the tags detected in both, and the largest corner
difference between them. Writes ``cycles_vs_simgap.png`` (one crop side by side).

``bpy`` (Blender as a Python module, Python 3.11) pins numpy 1.x, which simgap's environment
cannot take, so it lives in an environment of its own: pass that Python as ``--bpy-python`` or
``SIMGAP_BPY_PYTHON`` (``python3.11 -m venv ~/bpy && ~/bpy/bin/pip install bpy``). Without one
the comparison is skipped (exit 0).

Usage: ``python benchmarks/cycles_compare.py [--configs 8] [--cycles-spp 4,16,64] [--out DIR]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from simgap.core.aruco import project_tag_corners
from simgap.core.paths import assets_dir
from simgap.pipeline.cache import Cache
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.variant import VariantPipeline, assets_hash
from simgap.pose.image_stats import STAT_INDEX, MarkerLayout, tag_stats
from simgap.render import imaging
from simgap.render.mitsuba_scene import PAPER_THRESHOLD
from simgap.render.scene import pose_transforms
from simgap.scene.materials import Conductor, Diffuse, Plastic

WORKER = Path(__file__).with_name("cycles_worker.py")
#: The noisy crops are scaled so that this share of pixels is darker than LEVEL before the 8-bit
#: encoding of the noise measurement (the paper sits near it whatever the renderer's units).
BRIGHT_PERCENTILE, LEVEL = 99.0, 0.7


def bpy_python(given: str | None) -> str | None:
    """A Python that imports bpy: ``given``, ``$SIMGAP_BPY_PYTHON``, or this one; else None."""
    for candidate in (given, os.environ.get("SIMGAP_BPY_PYTHON"), sys.executable):
        if not candidate or shutil.which(candidate) is None and not Path(candidate).is_file():
            continue
        probe = subprocess.run([candidate, "-c", "import bpy"], capture_output=True)
        if probe.returncode == 0:
            return candidate
    return None


def material(m) -> dict:
    """A renderer-agnostic material description (see ``cycles_worker._material``)."""
    if isinstance(m, Diffuse):
        return {"kind": "diffuse", "reflectance": m.reflectance}
    if isinstance(m, Plastic):
        return {
            "kind": "plastic",
            "reflectance": m.diffuse_reflectance,
            "int_ior": m.int_ior,
            "alpha": m.alpha,
        }
    if isinstance(m, Conductor):
        return {"kind": "conductor", "alpha": m.alpha}
    raise TypeError(f"no description of {type(m).__name__}")


def scene_description(exp, pipe: VariantPipeline, configs, spp: list[int]) -> dict:
    """Everything the Cycles worker needs, as JSON: scene once, transforms per configuration."""
    state, rig = pipe.state.scene, pipe.rig
    spec, cam = state.spec, state.camera
    tag = spec.tag
    tags = {}
    for face in rig.tags.faces:
        texture = cv2.imread(str(assets_dir() / f"tag_{face.id}.png"), cv2.IMREAD_GRAYSCALE)
        tags[str(face.id)] = np.where(texture > PAPER_THRESHOLD, tag.paper, tag.ink).tolist()
    coating = tag.coating
    tag_material = (
        {"kind": "print"}
        if coating is None
        else {"kind": "plastic", "reflectance": 1.0, "int_ior": coating.int_ior}
        | {"alpha": coating.alpha}
    )
    configurations = []
    for p, theta in configs:
        region = pipe.region(p, theta)
        world = pose_transforms(rig, p, theta, state.errors, state.tag_scale)
        configurations.append(
            {
                "p": int(p),
                "theta": float(theta),
                "size": list(region.size),
                "offset": list(region.offset),
                "transforms": {k: v.tolist() for k, v in world.items()},
            }
        )
    return {
        "camera": {k: getattr(cam, k) for k in ("width", "height", "fx", "fy", "cx", "cy")},
        "max_depth": int(spec.integrator.get("max_depth", 3)),
        "materials": {name: material(m) for name, m in spec.materials.items()},
        "objects": {
            name: {"mesh": str(assets_dir() / o.mesh), "frame": o.frame, "material": o.material}
            for name, o in spec.objects.items()
        },
        "tags": {
            "albedo": tags,
            "material": tag_material,
            "texture": {"filter": tag.texture_filter},
        },
        "lights": [
            {
                "type": light.type,
                "position": list(light.position),
                "target": list(light.target),
                "size": list(light.size),
                "radiance": light.radiance,
                "intensity": light.intensity,
                "cutoff_deg": light.cutoff_deg,
                "rgb": list(light.rgb),
            }
            for light in spec.lights.values()
        ],
        "configurations": configurations,
        "spp": spp,
    }


def relative_paper_noise(hdr, offset, pipe: VariantPipeline, p, theta) -> list[float]:
    """Noise sigma over level of the flat paper around each visible tag of a linear crop."""
    rig, cal = pipe.rig, pipe.state.scene.camera
    scale = LEVEL / max(float(np.percentile(hdr.mean(axis=2), BRIGHT_PERCENTILE)), 1e-12)
    gray = imaging.to_gray(imaging.encode_srgb8(hdr * scale))
    layout = MarkerLayout(rig.marker_cells(), rig.tags.quiet_zone_cells)
    out = []
    for tag in pipe.tags:
        if not rig.is_visible(tag, p, theta):
            continue
        corners = project_tag_corners(
            rig.eyepoint_from_tag(tag, p, theta), rig.tags.size, cal
        )
        s = tag_stats(gray, corners, layout, offset, edge_widths=())
        out.append(s[STAT_INDEX["noise_paper_linear"]] / s[STAT_INDEX["paper_linear"]])
    return out


def detected_corners(hdr, offset, pipe: VariantPipeline) -> dict[int, np.ndarray]:
    """Markers the experiment's detector finds in the crop pasted into a full frame (px)."""
    gray = imaging.to_gray(imaging.encode_srgb8(hdr))
    return pipe.detector.detect(imaging.paste(gray, offset, pipe.image_size))


def pipeline(exp, cache: Path) -> VariantPipeline:
    """The pipeline of ``exp``'s first variant on a cache folder."""
    state = exp.variant_states()[0][1]
    tags = tuple(int(t) for t in exp.configuration_axes()[2])
    return VariantPipeline(
        exp.rig_model, state, tags, exp.render.margin_px, Cache(cache), assets_hash()
    )


def simgap_side(exp, configs, cache: Path) -> tuple[VariantPipeline, list, float]:
    """simgap's crops of ``configs`` (empty result cache, warm kernels); seconds per config."""
    warm = pipeline(exp, cache / "warmup")
    for p, theta in configs:  # scene load and its kernels, not timed
        warm.hdr(p, theta, 1)
    pipe = pipeline(exp, cache / "timed")
    crops = [pipe.hdr(p, theta, 0) for p, theta in configs]
    seconds = (pipe.seconds["sampling"] + pipe.seconds["pose update"]) / len(configs)
    return pipe, crops, seconds


def pick_configurations(exp, pipe: VariantPipeline, n: int) -> list[tuple[int, float]]:
    """``n`` configurations spread evenly over the sweep's visible ones."""
    ps, thetas, _ = exp.configuration_axes()
    visible = [(int(p), float(t)) for p in ps for t in thetas if pipe.region(int(p), float(t))]
    idx = np.unique(np.linspace(0, len(visible) - 1, n).round().astype(int))
    return [visible[i] for i in idx]


def figure(path: Path, simgap_crop, cycles_crop, spp: int, cycles_spp: int) -> None:
    """simgap's and Cycles' renders of one crop side by side (8-bit sRGB, same exposure)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scale = LEVEL / float(np.percentile(simgap_crop.mean(axis=2), BRIGHT_PERCENTILE))
    fig, axes = plt.subplots(1, 2, figsize=(10, 5.4))
    for ax, img, title in (
        (axes[0], simgap_crop * scale, f"simgap (Mitsuba 3), {spp} spp"),
        (axes[1], cycles_crop * scale, f"Blender Cycles (CPU), {cycles_spp} spp"),
    ):
        ax.imshow(imaging.encode_srgb8(img))
        ax.set_title(title)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--experiment", default="experiments/baseline.yaml")
    ap.add_argument("--configs", type=int, default=8, help="configurations rendered by both")
    ap.add_argument("--cycles-spp", default="4,16,64", help="Cycles sample counts, comma-separated")
    ap.add_argument("--bpy-python", default=None, help="a Python with bpy (else SIMGAP_BPY_PYTHON)")
    ap.add_argument("--out", default="cycles-compare", help="folder for the figure and renders")
    args = ap.parse_args()
    python = bpy_python(args.bpy_python)
    if python is None:
        print("Cycles comparison skipped: no Python with bpy (see --bpy-python).")
        return
    exp = load_experiment(args.experiment)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    spp = [int(s) for s in args.cycles_spp.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        configs = pick_configurations(exp, pipeline(exp, Path(tmp) / "probe"), args.configs)
        pipe, crops, simgap_s = simgap_side(exp, configs, Path(tmp))
        desc = scene_description(exp, pipe, configs, spp)
        (out / "scene.json").write_text(json.dumps(desc))
        t0 = time.perf_counter()
        subprocess.run([python, str(WORKER), str(out / "scene.json"), str(out)], check=True)
        worker_s = time.perf_counter() - t0
    timings = json.loads((out / "timings.json").read_text())
    simgap_noise = np.nanmedian(
        [
            v
            for (p, theta), (hdr, offset) in zip(configs, crops, strict=True)
            for v in relative_paper_noise(hdr, offset, pipe, p, theta)
        ]
    )
    print(f"configurations          {len(configs)} of {exp.name}, crops as simgap renders them")
    print(f"simgap (Mitsuba 3)      {exp.render.spp:3d} spp {exp.render.mode}  "
          f"{simgap_s:6.2f} s/config  paper noise {simgap_noise:.2%}")  # fmt: skip
    rows = []
    worst_px, agree = 0.0, True
    for s in spp:
        runs = [r for r in timings["renders"] if r["spp"] == s]
        seconds = float(np.mean([r["seconds"] for r in runs]))
        noise = []
        for k, ((p, theta), (hdr, offset)) in enumerate(zip(configs, crops, strict=True)):
            cyc = np.load(out / f"c{k}_s{s}.npy")
            noise += relative_paper_noise(cyc, offset, pipe, p, theta)
            if s == max(spp):
                mine = detected_corners(hdr, offset, pipe)
                theirs = detected_corners(cyc, offset, pipe)
                agree &= set(mine) == set(theirs)
                for tag in set(mine) & set(theirs):
                    worst_px = max(worst_px, float(np.abs(mine[tag] - theirs[tag]).max()))
        rows.append((s, seconds, float(np.nanmedian(noise))))
        print(f"Blender Cycles (CPU)    {s:3d} spp  {seconds:6.2f} s/config  "
              f"paper noise {rows[-1][2]:.2%}")  # fmt: skip
    s_arr, t_arr, n_arr = (np.array(c, float) for c in zip(*rows, strict=True))
    # noise = a spp^-1/2 (least squares on the log), time = b + c spp (least squares)
    a = float(np.exp(np.mean(np.log(n_arr) + 0.5 * np.log(s_arr))))
    equal_spp = (a / simgap_noise) ** 2
    c, b = np.polyfit(s_arr, t_arr, 1)
    equal_s = float(b + c * equal_spp)
    print(f"Cycles at simgap's noise {equal_spp:5.1f} spp  {equal_s:6.2f} s/config (fitted)")
    print(f"speed-up at equal noise {equal_s / simgap_s:6.1f}x")
    print(f"Cycles scene build      {timings['scene_build_s']:6.2f} s, first render "
          f"{timings['first_render_s']:.2f} s (worker {worker_s:.1f} s in all)")  # fmt: skip
    print(f"same scene              tags detected alike: {'yes' if agree else 'NO'}; largest "
          f"corner difference {worst_px:.2f} px at {max(spp)} spp")  # fmt: skip
    nearest = min(spp, key=lambda s: abs(s - equal_spp))
    figure(out / "cycles_vs_simgap.png", crops[0][0], np.load(out / f"c0_s{nearest}.npy"),
           exp.render.spp, nearest)  # fmt: skip
    print(f"figure                  {out / 'cycles_vs_simgap.png'}")


if __name__ == "__main__":
    main()
