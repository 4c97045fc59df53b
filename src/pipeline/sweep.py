"""Run an experiment: for every (p, theta), every variant and repeat, render -> frame -> pose.

Stages and their caches (:mod:`simgap.pipeline.cache`), each keyed by a content hash of its inputs
only, so a variant reuses everything upstream of the first stage it changes (DESIGN §2):

=========  ===============================================  ====================================
product    key depends on                                    stored as
=========  ===============================================  ====================================
render     scene state (lights, materials, optics, true      linear HDR crop, half-float EXR
           camera, true geometry, quality, seed), p, theta
frame      render key, image state, noise seed (repeat)      8-bit sRGB crop PNG + offset JSON
result     frame key, estimation state, tags                 ``.npz`` of corners, poses, errors
=========  ===============================================  ====================================

Only a square crop around the stickers facing the camera is rendered; the detector sees it pasted
into a full-size frame so that its size-relative thresholds see the real image size (DESIGN §4).
Work is spread over a Dask scheduler: an in-process ``LocalCluster`` by default, or any cluster by
address; one task is one (p, theta) for all variants and repeats, so renders are shared in a task.
"""

from __future__ import annotations

import json
import math
import platform
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import xarray as xr
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

import simgap
from simgap.core.paths import assets_dir
from simgap.core.rig import Rig
from simgap.effects.image import BLOCK_ALIGN_PX, ImageContext, run_pipeline
from simgap.effects.state import VariantState
from simgap.pipeline.cache import Cache, content_hash, file_hash, write_text
from simgap.pipeline.experiment import Experiment
from simgap.pose.detect import Detector
from simgap.pose.tags import RESULT_FIELDS, ConfigResult, estimate_tags, measure_tags
from simgap.render import imaging
from simgap.render.scene import projected_sticker_boxes
from simgap.results.dataset import build_dataset, empty_results

#: Crop sides are rounded up to a multiple of this (px); each distinct side compiles one kernel.
CROP_STEP_PX = 32
#: Part of every result key: bump when what a result holds changes (not the render or frame).
RESULT_VERSION = "image-stats-4"


@dataclass(frozen=True)
class Frame:
    """The camera's 8-bit RGB crop around the tags, and where it sits in the full image (px)."""

    crop: np.ndarray
    offset: tuple[int, int]
    size: tuple[int, int]

    def gray(self) -> np.ndarray:
        """Full-size 8-bit grey frame for the detector (the crop pasted in)."""
        return imaging.paste(imaging.to_gray(self.crop), self.offset, self.size)

    def rgb(self) -> np.ndarray:
        """Full-size 8-bit RGB frame."""
        return imaging.paste(self.crop, self.offset, self.size)


def _read_offset(path: Path) -> tuple[int, int]:
    """The crop offset (x0, y0 px) stored beside a cached frame."""
    offset = json.loads(path.read_text())["offset"]
    if not (isinstance(offset, list) and len(offset) == 2 and all(type(v) is int for v in offset)):
        raise ValueError(f"{path}: offset: expected two integers (px), got {offset!r}")
    return offset[0], offset[1]


def _union(boxes: dict) -> tuple[float, float, float, float]:
    return (
        min(b[0] for b in boxes.values()),
        min(b[1] for b in boxes.values()),
        max(b[2] for b in boxes.values()),
        max(b[3] for b in boxes.values()),
    )


def crop_side(boxes: dict, margin_px: int, image: tuple[int, int]) -> int:
    """Square crop side (px, multiple of :data:`CROP_STEP_PX`) holding the boxes plus a margin."""
    u0, v0, u1, v1 = _union(boxes)
    side = max(u1 - u0, v1 - v0) + 2 * margin_px
    return int(min(math.ceil(side / CROP_STEP_PX) * CROP_STEP_PX, image[0], image[1]))


def crop_offset(boxes: dict, size: tuple[int, int], image: tuple[int, int]) -> tuple[int, int]:
    """Top-left pixel of a crop centred on the boxes, block-aligned and inside the image."""
    u0, v0, u1, v1 = _union(boxes)
    a = BLOCK_ALIGN_PX
    x0 = int(round(((u0 + u1) / 2 - size[0] / 2) / a)) * a
    y0 = int(round(((v0 + v1) / 2 - size[1] / 2) / a)) * a
    return min(max(x0, 0), image[0] - size[0]), min(max(y0, 0), image[1] - size[1])


def config_seed(base: int, p: int, theta: float, *extra) -> int:
    """Deterministic per-configuration seed (31 bits)."""
    return (
        int(content_hash("seed", base, int(p), round(float(theta), 9), *extra)[:8], 16) & 0x7FFFFFFF
    )


_SCENES: dict[tuple[str, int], object] = {}


class VariantPipeline:
    """One variant's stages for any (p, theta), with caching."""

    def __init__(
        self, rig: Rig, state: VariantState, tags, margin_px: int, cache: Cache, assets: str
    ):
        self.rig, self.state, self.tags, self.cache = rig, state, tuple(tags), cache
        self.margin_px = margin_px
        cam = state.scene.camera
        self.image_size = (cam.width, cam.height)
        self.scene_key = content_hash("scene", rig, state.scene, assets)
        self.detector = Detector(state.estimation.detector)

    def scene(self, side: int):
        """The Mitsuba scene of this variant with a ``side`` x ``side`` film (one per process)."""
        key = (self.scene_key, side)
        if key not in _SCENES:
            from simgap.render.scene import FixtureScene

            s = self.state.scene
            spec = _scene_spec(s.overrides)
            _SCENES[key] = FixtureScene(
                self.rig,
                spec,
                (side, side),
                s.quality.spp,
                s.quality.sampler,
                errors=s.errors,
                camera=s.camera,
                tag_scale=s.tag_scale,
                lens=(s.aperture_radius_m, s.focus_distance_m),
                max_depth=s.quality.max_depth,
            )
        return _SCENES[key]

    def crop(self, p: int, theta: float) -> tuple[int, tuple[int, int]] | None:
        """Crop side and offset (px) of one configuration; None when no sticker faces it."""
        s = self.state.scene
        boxes = projected_sticker_boxes(self.rig, p, theta, s.errors, s.camera, s.tag_scale)
        if not boxes:
            return None
        side = crop_side(boxes, self.margin_px, self.image_size)
        return side, crop_offset(boxes, (side, side), self.image_size)

    def render_key(self, p: int, theta: float, render_repeat: int) -> str:
        """Cache key of the linear render of one configuration."""
        return content_hash(self.scene_key, int(p), round(float(theta), 9), render_repeat)

    def hdr(self, p: int, theta: float, render_repeat: int):
        """The linear crop render and its offset, or None when no sticker faces the camera."""
        crop = self.crop(p, theta)
        if crop is None:
            return None
        side, offset = crop
        path = self.cache.path("renders", self.render_key(p, theta, render_repeat), ".exr")
        cached = self.cache.read(path, lambda f: imaging.read_exr(f, (side, side)))
        if cached is not None:
            return cached, offset
        scene = self.scene(side)
        scene.set_pose(p, theta)
        seed = config_seed(self.state.scene.render_seed, p, theta, render_repeat)
        hdr = imaging.quantise_half(scene.render(offset, seed))
        try:
            imaging.write_exr(path, hdr, exclusive=True)
        except FileExistsError:  # another process published this render first: share its copy
            shared = self.cache.read(path, lambda f: imaging.read_exr(f, (side, side)))
            if shared is None:  # it was corrupt (and is now moved aside): publish ours
                imaging.write_exr(path, hdr)
            else:
                hdr = shared
        return hdr, offset

    def frame_key(self, p: int, theta: float, repeat: int, render_repeat: int) -> str:
        """Cache key of the 8-bit frame (the repeat matters only for a stochastic pipeline)."""
        noise = repeat if self.state.image.stochastic else 0
        return content_hash(self.render_key(p, theta, render_repeat), self.state.image, noise)

    def frame(self, p: int, theta: float, repeat: int, render_repeat: int) -> Frame | None:
        """The 8-bit frame the camera delivers, or None when no sticker faces it."""
        key = self.frame_key(p, theta, repeat, render_repeat)
        png = self.cache.path("frames", key, ".png")
        meta = png.with_suffix(".json")
        if png.is_file() and meta.is_file():
            offset = self.cache.read(meta, _read_offset)
            crop8 = self.cache.read(png, imaging.read_png)
            if offset is not None and crop8 is not None:
                return Frame(crop8, offset, self.image_size)
        rendered = self.hdr(p, theta, render_repeat)
        if rendered is None:
            return None
        hdr, offset = rendered
        seed = config_seed(self.state.scene.render_seed, p, theta, "image", repeat)
        ctx = ImageContext(offset, self.state.scene.camera, np.random.default_rng(seed))
        crop8 = run_pipeline(hdr, self.state.image, ctx)
        write_text(meta, json.dumps({"offset": list(offset), "size": list(self.image_size)}))
        imaging.write_png(png, crop8)
        return Frame(crop8, offset, self.image_size)

    def result_key(self, p: int, theta: float, repeat: int, render_repeat: int) -> str:
        """Cache key of the detection, pose and image-evidence result of one frame."""
        return content_hash(
            self.frame_key(p, theta, repeat, render_repeat),
            self.state.estimation,
            self.tags,
            RESULT_VERSION,
        )

    def run(self, p: int, theta: float, repeat: int, render_repeat: int) -> ConfigResult:
        """Result of one configuration and repeat, from cache or computed (and then cached)."""
        key = self.result_key(p, theta, repeat, render_repeat)
        cached = self.cache.load_arrays("results", key)
        if cached is not None:
            return ConfigResult(**cached)
        frame = self.frame(p, theta, repeat, render_repeat)
        if frame is None:
            result = estimate_tags(self.rig, self.state.estimation, self.tags, {}, p, theta)
        else:
            crop_gray = imaging.to_gray(frame.crop)
            full = imaging.paste(crop_gray, frame.offset, frame.size)
            found, rejected = self.detector.detect_with_rejected(full)
            result = measure_tags(
                self.rig, self.state.estimation, self.tags, crop_gray, frame.offset, found,
                rejected, p, theta,
            )
        self.cache.save_arrays("results", key, result.arrays())
        return result


def _scene_spec(overrides: dict):
    from simgap.render.scene import load_scene_spec

    return load_scene_spec(overrides)


def _assets_hash() -> str:
    return file_hash(sorted(assets_dir().glob("*.ply")) + sorted(assets_dir().glob("tag_*.png")))


_PIPELINES: dict[str, list[VariantPipeline]] = {}


def experiment_pipelines(exp: Experiment, cache_dir: Path) -> list[VariantPipeline]:
    """One pipeline per variant (cached per process: Dask workers keep them between tasks)."""
    key = content_hash("pipelines", exp.to_yaml(), str(cache_dir))
    if key not in _PIPELINES:
        _, _, tags = exp.configuration_axes()
        assets = _assets_hash()
        cache = Cache(cache_dir)
        rig = exp.rig_model
        margin = exp.render.crop_margin_px
        _PIPELINES[key] = [
            VariantPipeline(rig, state, tags, margin, cache, assets)
            for _, state in exp.variant_states()
        ]
    return _PIPELINES[key]


def run_task(exp: Experiment, cache_dir: str, p: int, theta: float) -> dict[str, np.ndarray]:
    """All variants and repeats of one (p, theta): arrays shaped (V, R, T, ...)."""
    pipes = experiment_pipelines(exp, Path(cache_dir))
    reps = exp.repeats
    out: dict[str, list] = {k: [] for k in RESULT_FIELDS}
    for pipe in pipes:
        rows = []
        for r in range(reps):
            render_repeat = r if exp.render.reseed_repeats else 0
            if r > 0 and not pipe.state.image.stochastic and not exp.render.reseed_repeats:
                rows.append(rows[0])  # deterministic pipeline: every repeat is the same frame
                continue
            rows.append(pipe.run(p, theta, r, render_repeat))
        for k in RESULT_FIELDS:
            out[k].append(np.stack([getattr(row, k) for row in rows]))
    return {k: np.stack(v) for k, v in out.items()}


def preflight(exp: Experiment) -> None:
    """Build every distinct variant scene once (tiny film) so bad scene settings fail up front.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the variant whose scene Mitsuba cannot build.
    """
    from simgap.core.config import ConfigError
    from simgap.render.scene import FixtureScene

    seen = set()
    for name, state in exp.variant_states():
        key = content_hash(state.scene.overrides)
        if key in seen:
            continue
        seen.add(key)
        try:
            FixtureScene(exp.rig_model, _scene_spec(state.scene.overrides), (8, 8), 1)
        except ConfigError as exc:
            raise ConfigError(f"variant {name!r}: {exc}") from exc


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeRemainingColumn(),
    )


def _client(scheduler: str | None):
    """A Dask client: an existing scheduler by address, or an in-process LocalCluster."""
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None
    # One in-process worker thread: Mitsuba/Dr.Jit already use every core for each render.
    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    )
    return Client(cluster), cluster


def run_experiment(
    exp: Experiment,
    cache_dir: Path,
    show_progress: bool = True,
    scheduler: str | None = None,
) -> xr.Dataset:
    """Run every configuration, variant and repeat of ``exp``; return the result dataset.

    Parameters
    ----------
    exp : Experiment
        The experiment.
    cache_dir : Path
        Cache folder (must be reachable by the workers under the same path).
    show_progress : bool
        Show a progress bar with counts and rate.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://HOST:PORT``); default: an in-process LocalCluster.
    """
    from distributed import as_completed

    ps, thetas, tags = exp.configuration_axes()
    names = [name for name, _ in exp.variant_states()]
    shape = (len(names), exp.repeats, len(tags), len(ps), len(thetas))
    res = empty_results(shape)
    configs = [(i, j) for i in range(len(ps)) for j in range(len(thetas))]
    preflight(exp)
    client, cluster = _client(scheduler)
    try:
        futures = {
            client.submit(run_task, exp, str(cache_dir), ps[i], float(thetas[j]), pure=False): (
                i,
                j,
            )
            for i, j in configs
        }
        with _progress() as bar:
            task = bar.add_task(exp.name, total=len(configs), rate="", visible=show_progress)
            for n, fut in enumerate(as_completed(futures), 1):
                i, j = futures[fut]
                for k, v in fut.result().items():
                    res[k][:, :, :, i, j] = v
                elapsed = bar.tasks[0].elapsed or 1e-9
                bar.update(task, advance=1, rate=f"{n / elapsed:.1f} cfg/s")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    rig = exp.rig_model
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in thetas] for p in ps] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in thetas] for p in ps] for t in tags])
    return build_dataset(
        tags,
        ps,
        thetas,
        expected,
        visible,
        res,
        variants=tuple(names),
        repeats=tuple(range(exp.repeats)),
        attrs=dataset_attrs(exp, scheduler),
    )


def dataset_attrs(exp: Experiment, scheduler: str | None) -> dict[str, str]:
    """Provenance attributes: resolved config, seeds, versions, renderer, detector and PnP."""
    import distributed
    import drjit
    import mitsuba

    from simgap.render.backend import choose_variant

    states = exp.variant_states()
    return {
        "title": f"simgap result: {exp.name}",
        "experiment": exp.name,
        "experiment_yaml": exp.to_yaml(),
        "seed": str(exp.render.seed),
        "repeats": str(exp.repeats),
        "variant_effects": json.dumps({spec.name: spec.effects for spec in exp.variant_specs()}),
        "simgap_version": simgap.__version__,
        "mitsuba_version": mitsuba.__version__,
        "drjit_version": drjit.__version__,
        "opencv_version": cv2.__version__,
        "numpy_version": np.__version__,
        "xarray_version": xr.__version__,
        "dask_distributed_version": distributed.__version__,
        "python_version": platform.python_version(),
        "renderer_variant": choose_variant(),
        "scheduler": scheduler or "in-process LocalCluster",
        "render_crop": f"square crops around facing tags, sides in steps of {CROP_STEP_PX} px",
        "detector": json.dumps({n: f"{s.estimation.detector}" for n, s in states}),
        "pnp": json.dumps({n: f"{s.estimation.pnp}" for n, s in states}),
        "conventions": "DESIGN.md §1: global frame = eyepoint (+X right, +Y forward, +Z up)",
    }
