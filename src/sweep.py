"""Run an experiment over its configurations: render -> frame -> corners -> pose -> dataset.

Each stage's product is cached under a content hash of everything upstream (:mod:`simgap.cache`):
linear renders as EXR, 8-bit frames as PNG, per-configuration results as ``.npz``. A rerun serves
finished configurations from the cache, and an interrupted sweep resumes where it stopped.
Only a crop around the stickers facing the camera is rendered; it is pasted into a full-size frame
so that the detector's size-relative thresholds see the real image size (DESIGN §4).
"""

from __future__ import annotations

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
from simgap.cache import Cache, content_hash, file_hash
from simgap.experiment import Experiment
from simgap.paths import assets_dir
from simgap.pose.detect import Detector
from simgap.pose.estimate import estimate_pose, pose_error
from simgap.render import imaging
from simgap.rig import NOMINAL, Rig


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


def crop_size(rig: Rig, ps, thetas, margin_px: int) -> tuple[int, int]:
    """Square crop side (px, multiple of 16) that holds every facing sticker plus ``margin_px``."""
    from simgap.render.scene import projected_sticker_boxes

    side = 0.0
    for p in ps:
        for theta in thetas:
            for u0, v0, u1, v1 in projected_sticker_boxes(rig, p, theta).values():
                side = max(side, u1 - u0, v1 - v0)
    side = min(
        int(math.ceil((side + 2 * margin_px) / 16.0) * 16), rig.camera.width, rig.camera.height
    )
    return side, side


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


class Pipeline:
    """Everything needed to turn one (p, theta) into a :class:`ConfigResult`, with caching."""

    def __init__(self, exp: Experiment, cache: Cache) -> None:
        self.exp, self.cache = exp, cache
        self.rig = exp.rig_model
        self.ps, self.thetas, self.tags = exp.grid()
        self.crop = crop_size(self.rig, self.ps, self.thetas, exp.render.crop_margin_px)
        assets = sorted(assets_dir().glob("*.ply")) + sorted(assets_dir().glob("tag_*.png"))
        self.scene_key = content_hash(
            "scene", self.rig, NOMINAL, exp.scene_spec, exp.render, self.crop, file_hash(assets)
        )
        self.detector = Detector(exp.detector)
        self._scene = None

    @property
    def scene(self):
        """The Mitsuba scene, loaded on first use (cached runs never load it)."""
        if self._scene is None:
            from simgap.render.scene import FixtureScene

            r = self.exp.render
            self._scene = FixtureScene(self.rig, self.exp.scene_spec, self.crop, r.spp, r.sampler)
        return self._scene

    def render_key(self, p: int, theta: float) -> str:
        """Cache key of the linear render of one configuration."""
        return content_hash(self.scene_key, int(p), round(float(theta), 9))

    def hdr(self, p: int, theta: float) -> tuple[np.ndarray, tuple[int, int]] | None:
        """The linear crop render and its offset, or None when no sticker faces the camera."""
        from simgap.render.scene import projected_sticker_boxes

        boxes = projected_sticker_boxes(self.rig, p, theta)
        if not boxes:
            return None
        cam = self.rig.camera
        offset = crop_offset(boxes, self.crop, (cam.width, cam.height))
        path = self.cache.path("renders", self.render_key(p, theta), ".exr")
        if path.is_file():
            return imaging.read_exr(path), offset
        self.scene.set_pose(p, theta)
        hdr = imaging.quantise_half(
            self.scene.render(offset, config_seed(self.exp.render.seed, p, theta))
        )
        imaging.write_exr(path, hdr)
        return hdr, offset

    def frame(self, p: int, theta: float) -> np.ndarray | None:
        """The 8-bit RGB frame the camera delivers (full size), or None when nothing faces it."""
        key = content_hash(self.render_key(p, theta), self.exp.image)
        path = self.cache.path("frames", key, ".png")
        if path.is_file():
            return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        rendered = self.hdr(p, theta)
        if rendered is None:
            return None
        hdr, offset = rendered
        linear = hdr * self.exp.image.exposure
        if self.exp.image.encoding == "srgb":
            crop8 = imaging.encode_srgb8(linear)
        else:
            crop8 = np.clip(np.round(linear * 255.0), 0, 255).astype(np.uint8)
        cam = self.rig.camera
        frame = imaging.paste(crop8, offset, (cam.width, cam.height))
        imaging.write_png(path, frame)
        return frame

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
        found = {} if frame is None else self.detector.detect(imaging.to_gray(frame))
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
        "render_crop_px": f"{pipe.crop[0]}x{pipe.crop[1]}",
        "detector": f"{exp.detector}",
        "pnp": f"{exp.pnp}",
        "conventions": "DESIGN.md §1: global frame = eyepoint (+X right, +Y forward, +Z up)",
    }
