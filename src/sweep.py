"""Run an experiment over its configurations: render -> frame -> corners -> pose -> dataset.

Each stage's product is cached under a content hash of everything upstream (:mod:`simgap.cache`):
linear renders as EXR, 8-bit frames as PNG, per-configuration results as ``.npz``. A rerun serves
finished configurations from the cache, and an interrupted sweep resumes where it stopped.
Only a crop around the stickers facing the camera is rendered; it is pasted into a full-size frame
so that the detector's size-relative thresholds see the real image size (DESIGN §4).
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
from simgap.analysis.dataset import build_dataset
from simgap.cache import Cache, content_hash, file_hash, write_text
from simgap.experiment import Experiment
from simgap.paths import assets_dir
from simgap.pose.detect import Detector
from simgap.pose.estimate import estimate_pose, pose_error
from simgap.render import imaging
from simgap.render.scene import projected_sticker_boxes
from simgap.rig import NOMINAL


@dataclass(frozen=True)
class ConfigResult:
    """Detection and pose results of one (p, theta) for every tag of the experiment (tag order)."""

    detected: np.ndarray  # (T,) bool
    estimated: np.ndarray  # (T, 6) global pose, NaN where not detected
    error: np.ndarray  # (T, 6)
    reproj_px: np.ndarray  # (T,)
    corners: np.ndarray  # (T, 4, 2) px

    def arrays(self) -> dict[str, np.ndarray]:
        """As a mapping for storage."""
        return {
            k: getattr(self, k) for k in ("detected", "estimated", "error", "reproj_px", "corners")
        }


#: Crop sides are rounded up to a multiple of this (px); each distinct side compiles one kernel.
CROP_STEP_PX = 32


def crop_side(boxes: dict, margin_px: int, image: tuple[int, int]) -> int:
    """Square crop side (px, multiple of :data:`CROP_STEP_PX`) holding the boxes plus a margin."""
    u0 = min(b[0] for b in boxes.values())
    v0 = min(b[1] for b in boxes.values())
    u1 = max(b[2] for b in boxes.values())
    v1 = max(b[3] for b in boxes.values())
    side = max(u1 - u0, v1 - v0) + 2 * margin_px
    return int(min(math.ceil(side / CROP_STEP_PX) * CROP_STEP_PX, image[0], image[1]))


def crop_offset(boxes: dict, size: tuple[int, int], image: tuple[int, int]) -> tuple[int, int]:
    """Top-left pixel of a crop centred on the union of sticker boxes, kept inside the image."""
    u0 = min(b[0] for b in boxes.values())
    v0 = min(b[1] for b in boxes.values())
    u1 = max(b[2] for b in boxes.values())
    v1 = max(b[3] for b in boxes.values())
    x0 = int(round((u0 + u1) / 2 - size[0] / 2))
    y0 = int(round((v0 + v1) / 2 - size[1] / 2))
    return min(max(x0, 0), image[0] - size[0]), min(max(y0, 0), image[1] - size[1])


def config_seed(base: int, p: int, theta: float) -> int:
    """Deterministic per-configuration render seed."""
    return int(content_hash("seed", base, int(p), round(float(theta), 9))[:8], 16) & 0x7FFFFFFF


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


class Pipeline:
    """Everything needed to turn one (p, theta) into a :class:`ConfigResult`, with caching."""

    def __init__(self, exp: Experiment, cache: Cache) -> None:
        self.exp, self.cache = exp, cache
        self.rig = exp.rig_model
        self.ps, self.thetas, self.tags = exp.grid()
        cam = self.rig.camera
        self.image_size = (cam.width, cam.height)
        assets = sorted(assets_dir().glob("*.ply")) + sorted(assets_dir().glob("tag_*.png"))
        self.scene_key = content_hash(
            "scene", self.rig, NOMINAL, exp.scene_spec, exp.render, file_hash(assets)
        )
        self.detector = Detector(exp.detector)
        self._scenes: dict[int, object] = {}

    def scene(self, side: int):
        """The Mitsuba scene with a ``side`` x ``side`` film, loaded on first use."""
        if side not in self._scenes:
            from simgap.render.scene import FixtureScene

            r = self.exp.render
            spec = self.exp.scene_spec
            self._scenes[side] = FixtureScene(self.rig, spec, (side, side), r.spp, r.sampler)
        return self._scenes[side]

    def crop(self, p: int, theta: float) -> tuple[int, tuple[int, int]] | None:
        """Crop side and offset (px) of one configuration; None when no sticker faces it."""
        boxes = projected_sticker_boxes(self.rig, p, theta)
        if not boxes:
            return None
        side = crop_side(boxes, self.exp.render.crop_margin_px, self.image_size)
        return side, crop_offset(boxes, (side, side), self.image_size)

    def render_key(self, p: int, theta: float) -> str:
        """Cache key of the linear render of one configuration."""
        return content_hash(self.scene_key, int(p), round(float(theta), 9))

    def hdr(self, p: int, theta: float) -> tuple[np.ndarray, tuple[int, int]] | None:
        """The linear crop render and its offset, or None when no sticker faces the camera."""
        crop = self.crop(p, theta)
        if crop is None:
            return None
        side, offset = crop
        path = self.cache.path("renders", self.render_key(p, theta), ".exr")
        if path.is_file():
            return imaging.read_exr(path), offset
        scene = self.scene(side)
        scene.set_pose(p, theta)
        seed = config_seed(self.exp.render.seed, p, theta)
        hdr = imaging.quantise_half(scene.render(offset, seed))
        imaging.write_exr(path, hdr)
        return hdr, offset

    def frame(self, p: int, theta: float) -> Frame | None:
        """The 8-bit frame the camera delivers, or None when no sticker faces it.

        Cached as the crop (PNG) plus its offset (JSON); the rest of the frame is fill.
        """
        key = content_hash(self.render_key(p, theta), self.exp.image)
        png = self.cache.path("frames", key, ".png")
        meta = png.with_suffix(".json")
        if png.is_file() and meta.is_file():
            offset = tuple(json.loads(meta.read_text())["offset"])
            crop8 = cv2.cvtColor(cv2.imread(str(png), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
            return Frame(crop8, offset, self.image_size)
        rendered = self.hdr(p, theta)
        if rendered is None:
            return None
        hdr, offset = rendered
        linear = hdr * self.exp.image.exposure
        if self.exp.image.encoding == "srgb":
            crop8 = imaging.encode_srgb8(linear)
        else:
            crop8 = np.clip(np.round(linear * 255.0), 0, 255).astype(np.uint8)
        write_text(meta, json.dumps({"offset": list(offset), "size": list(self.image_size)}))
        imaging.write_png(png, crop8)
        return Frame(crop8, offset, self.image_size)

    def result_key(self, p: int, theta: float) -> str:
        """Cache key of one configuration's detection and pose results."""
        return content_hash(
            self.render_key(p, theta),
            self.exp.image,
            self.exp.detector,
            self.exp.pnp,
            self.rig.camera,
            self.rig.tags,
            self.tags,
        )

    def run_config(self, p: int, theta: float) -> ConfigResult:
        """Result of one configuration, from cache or computed (and then cached)."""
        key = self.result_key(p, theta)
        cached = self.cache.load_arrays("results", key)
        if cached is not None:
            return ConfigResult(**cached)
        frame = self.frame(p, theta)
        found = {} if frame is None else self.detector.detect(frame.gray())
        result = self.estimate(found, p, theta)
        self.cache.save_arrays("results", key, result.arrays())
        return result

    def estimate(self, found: dict[int, np.ndarray], p: int, theta: float) -> ConfigResult:
        """Pose and error of every experiment tag from detected corners (px)."""
        n = len(self.tags)
        out = ConfigResult(
            detected=np.zeros(n, bool),
            estimated=np.full((n, 6), np.nan),
            error=np.full((n, 6), np.nan),
            reproj_px=np.full(n, np.nan),
            corners=np.full((n, 4, 2), np.nan),
        )
        cam = self.rig.camera
        for i, tag in enumerate(self.tags):
            if tag not in found:
                continue
            out.detected[i] = True
            out.corners[i] = found[tag]
            est = estimate_pose(
                found[tag], self.rig.tags.size, cam.matrix, cam.dist_coeffs, self.exp.pnp
            )
            if est is None:
                continue
            out.estimated[i] = est.pose
            out.error[i] = pose_error(est.pose, self.rig.expected_pose(tag, p, theta))
            out.reproj_px[i] = est.reproj_px
        return out


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeRemainingColumn(),
        transient=False,
    )


def run_experiment(exp: Experiment, cache_dir: Path, show_progress: bool = True) -> xr.Dataset:
    """Run every configuration of ``exp`` and return the result dataset (DESIGN §3)."""
    pipe = Pipeline(exp, Cache(cache_dir))
    ps, thetas, tags = pipe.ps, pipe.thetas, pipe.tags
    rig = pipe.rig
    shape = (1, 1, len(tags), len(ps), len(thetas))
    res = {
        "detected": np.zeros(shape, bool),
        "estimated": np.full(shape + (6,), np.nan),
        "error": np.full(shape + (6,), np.nan),
        "reproj_px": np.full(shape, np.nan),
        "corners": np.full(shape + (4, 2), np.nan),
    }
    configs = [(i, j) for i in range(len(ps)) for j in range(len(thetas))]
    with _progress() as bar:
        task = bar.add_task(exp.name, total=len(configs), rate="", visible=show_progress)
        for n, (i, j) in enumerate(configs, 1):
            r = pipe.run_config(ps[i], thetas[j])
            for name, value in r.arrays().items():
                res[name][0, 0, :, i, j] = value
            elapsed = bar.tasks[0].elapsed or 1e-9
            bar.update(task, advance=1, rate=f"{n / elapsed:.1f} cfg/s")
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in thetas] for p in ps] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in thetas] for p in ps] for t in tags])
    return build_dataset(tags, ps, thetas, expected, visible, res, attrs=dataset_attrs(exp, pipe))


def dataset_attrs(exp: Experiment, pipe: Pipeline) -> dict[str, str]:
    """Provenance attributes: resolved config, seeds, versions, renderer, detector and PnP."""
    import drjit
    import mitsuba

    from simgap.backend import choose_variant

    return {
        "title": f"simgap result: {exp.name}",
        "experiment": exp.name,
        "experiment_yaml": exp.to_yaml(),
        "seed": str(exp.render.seed),
        "simgap_version": simgap.__version__,
        "mitsuba_version": mitsuba.__version__,
        "drjit_version": drjit.__version__,
        "opencv_version": cv2.__version__,
        "numpy_version": np.__version__,
        "xarray_version": xr.__version__,
        "python_version": platform.python_version(),
        "renderer_variant": choose_variant(),
        "render_crop": f"square crops around the facing tags, sides in steps of {CROP_STEP_PX} px",
        "detector": f"{exp.detector}",
        "pnp": f"{exp.pnp}",
        "conventions": "DESIGN.md §1: global frame = eyepoint (+X right, +Y forward, +Z up)",
    }
