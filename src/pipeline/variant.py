"""One variant's stages for any (p, theta): render -> frame -> result, each cached.

The stage caches and what their keys depend on are listed in :mod:`simgap.pipeline.sweep`.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import Counter, OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from simgap.core.paths import assets_dir
from simgap.core.rig import Rig
from simgap.effects.image import (
    METER_STRIDE_PX,
    ImageContext,
    needs_meter,
    pipeline_reach_px,
    run_pipeline,
)
from simgap.effects.state import VariantState
from simgap.pipeline.cache import Cache, content_hash, file_hash, write_text
from simgap.pipeline.region import OUTLINE_POINTS_PER_SIDE, Region, sticker_region
from simgap.pose.detect import Detector
from simgap.pose.tags import ConfigResult, add_image_stats, estimate_tags
from simgap.render import imaging
from simgap.render.converged import converged_pixels, render_version
from simgap.render.scene import projected_sticker_outlines

#: Part of every render key: bump when what a render holds changes (its pixels or their samples).
RENDER_VERSION = "sticker-region-1"  # 1: only the pixels near the stickers, rendered as a list
#: Part of every result key: bump when what a result holds changes (not the render or frame).
#: 8: pipeline signatures (black clipping, edge overshoot, colour fringe, repeat gain);
#: 7: JPEG DC step; 6: ArUco on the window around the crop.
RESULT_VERSION = "window-detect-8"
#: The stages :attr:`VariantPipeline.seconds` times (benchmarks/sweep_speed.py prints them).
STAGES = (
    "scene load",  # Mitsuba scene built (its first render compiles the kernels)
    "pose update",  # carriage, camera and turntable moved (mi.traverse)
    "sampling",  # the path tracer's samples of the region's pixels
    "image pipeline",  # region into its crop, image-stage effects, 8-bit sRGB encoding
    "detection",  # ArUco on the grey frame (the window around the crop)
    "pnp",  # pose of every detected tag and its error
    "image statistics",  # levels, edge widths, noise ... of every visible tag
    "io",  # cache reads and writes (EXR, PNG, JSON, results)
)


@dataclass(frozen=True)
class Frame:
    """The camera's 8-bit RGB crop around the tags, and where it sits in the full image (px).

    ``record`` holds what the camera chose for this frame (``auto_exposure_ev``, EV).
    """

    crop: np.ndarray
    offset: tuple[int, int]
    size: tuple[int, int]
    record: dict[str, float] = field(default_factory=dict)

    @cached_property
    def gray_crop(self) -> np.ndarray:
        """The crop in 8-bit grey (what the detector and the image statistics read)."""
        return imaging.to_gray(self.crop)

    def gray(self) -> np.ndarray:
        """Full-size 8-bit grey frame for the detector (the crop pasted in)."""
        return imaging.paste(self.gray_crop, self.offset, self.size)

    def rgb(self) -> np.ndarray:
        """Full-size 8-bit RGB frame."""
        return imaging.paste(self.crop, self.offset, self.size)

    def gray_window(self, pad_px: int) -> tuple[np.ndarray, tuple[int, int]]:
        """The part of :meth:`gray` within ``pad_px`` of the crop, and its origin (x0, y0 px)."""
        (ox, oy), (w, h) = self.offset, self.size
        ch, cw = self.crop.shape[:2]
        x0, y0 = max(ox - pad_px, 0), max(oy - pad_px, 0)
        x1, y1 = min(ox + cw + pad_px, w), min(oy + ch + pad_px, h)
        return imaging.paste(self.gray_crop, (ox - x0, oy - y0), (x1 - x0, y1 - y0)), (x0, y0)


def _read_meta(path: Path) -> tuple[tuple[int, int], dict[str, float]]:
    """The crop offset (x0, y0 px) and the camera's choices stored beside a cached frame."""
    meta = json.loads(path.read_text())
    offset, record = meta["offset"], meta.get("record", {})
    if not (isinstance(offset, list) and len(offset) == 2 and all(type(v) is int for v in offset)):
        raise ValueError(f"{path}: offset: expected two integers (px), got {offset!r}")
    if not (isinstance(record, dict) and all(isinstance(v, float) for v in record.values())):
        raise ValueError(f"{path}: record: expected a mapping of names to numbers, got {record!r}")
    return (offset[0], offset[1]), record


def config_seed(base: int, p: int, theta: float, *extra) -> int:
    """Deterministic per-configuration seed (31 bits)."""
    return (
        int(content_hash("seed", base, int(p), round(float(theta), 9), *extra)[:8], 16) & 0x7FFFFFFF
    )


#: Mitsuba scenes a process keeps, at most (more where one experiment's variants are used in turn:
#: :class:`VariantPipeline`'s ``scenes_alive``). Every scene alive slows every kernel
#: launch of every scene: Dr.Jit traces a virtual call (a BSDF's, an emitter's) over all the
#: instances registered in the process. Measured (benchmarks/scenes_alive.py, 2 cores): a launch
#: of two pixels took 4.2 ms beside no other scene, 6.5 ms beside one, 34 ms beside 10 and 158 ms
#: beside 40, a converged baseline render 48, 53, 93 and 248 ms
#: (docs/results/converged_render_step8.md). A diagnosis or a validation run builds a scene for
#: every camera and every scene-stage candidate it renders; kept, they made its later renders
#: slower and slower. One: the callers render one state's configurations in turn (a sweep's
#: task its experiment's variants, which all stay alive), and a scene dropped is rebuilt when
#: needed again (the same renders, bit for bit).
MAX_SCENES_ALIVE = 1
#: Mitsuba scenes by scene key, least recently used first, shared by every pipeline of this
#: process: a variant that changes only the image or estimation stage has the same scene key and
#: reuses the scene and its compiled kernels, and a Dask worker keeps them between tasks. Keyed by
#: content hashes, so sharing is safe; :func:`clear_scenes` empties it.
_SCENES: OrderedDict[str, object] = OrderedDict()
#: Guards :data:`_SCENES` where a Dask worker runs tasks on several threads (a scene dropped by one
#: thread stays valid for another that holds it; it is only no longer shared).
_SCENES_LOCK = threading.Lock()


def clear_scenes() -> None:
    """Forget the Mitsuba scenes built in this process (they are rebuilt when next needed)."""
    with _SCENES_LOCK:
        _SCENES.clear()


def cached_scenes() -> int:
    """How many Mitsuba scenes this process keeps for reuse (:data:`MAX_SCENES_ALIVE`)."""
    return len(_SCENES)


class VariantPipeline:
    """One variant's stages for any (p, theta), with caching."""

    def __init__(
        self,
        rig: Rig,
        state: VariantState,
        tags,
        margin_px: int,
        cache: Cache,
        assets: str,
        scenes_alive: int = 1,
    ):
        self.rig, self.state, self.tags, self.cache = rig, state, tuple(tags), cache
        #: Scenes its caller uses in turn (an experiment's variants, one task after another):
        #: the process keeps this many when it is more than :data:`MAX_SCENES_ALIVE`
        self.scenes_alive = scenes_alive
        #: Render margin around the stickers (px): the experiment's, or more where the camera
        #: pipeline spreads pixels further (a wide blur must not pull in the flat surround)
        self.margin_px = max(int(margin_px), math.ceil(pipeline_reach_px(state.image)))
        cam = state.scene.camera
        self.image_size = (cam.width, cam.height)
        self.scene_key = content_hash("scene", rig, state.scene, assets)
        self.detector = Detector(state.estimation.detector)
        #: Wall seconds spent in each of :data:`STAGES` by this pipeline, in this process.
        self.seconds: Counter[str] = Counter()
        #: Stickers rendered per treatment in ``converged`` mode, in this process
        #: (:class:`simgap.render.converged.ConvergedRender`).
        self.sticker_treatments: Counter[str] = Counter()

    @contextmanager
    def _timed(self, stage: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[stage] += time.perf_counter() - t0

    def scene(self):
        """The Mitsuba scene of this variant (one per process and scene key).

        Building one drops the least recently used beyond :data:`MAX_SCENES_ALIVE` (or this
        pipeline's ``scenes_alive``, if more).
        """
        with _SCENES_LOCK:
            scene = _SCENES.get(self.scene_key)
            if scene is not None:
                _SCENES.move_to_end(self.scene_key)
                return scene
            from simgap.render.scene import FixtureScene

            while _SCENES and len(_SCENES) >= max(MAX_SCENES_ALIVE, self.scenes_alive):
                _SCENES.popitem(last=False)
            s = self.state.scene
            with self._timed("scene load"):
                scene = FixtureScene(
                    self.rig,
                    s.spec,
                    self.image_size,
                    s.quality.spp,
                    s.quality.sampler,
                    errors=s.errors,
                    camera=s.camera,
                    tag_scale=s.tag_scale,
                    lens=(s.aperture_radius_m, s.focus_distance_m),
                    max_depth=s.quality.max_depth,
                )
            _SCENES[self.scene_key] = scene
            return scene

    def region(self, p: int, theta: float) -> Region | None:
        """The pixels rendered at one configuration; None when no sticker faces the camera."""
        s = self.state.scene
        outlines = projected_sticker_outlines(
            self.rig, p, theta, s.errors, s.camera, s.tag_scale, OUTLINE_POINTS_PER_SIDE
        )
        return sticker_region(outlines, self.margin_px, self.image_size)

    def render_key(self, p: int, theta: float, render_repeat: int) -> str:
        """Cache key of the linear render of one configuration."""
        # a converged render's own version; a path render's key stays what it was
        s = self.state.scene
        converged = render_version(s.spec) if s.quality.mode == "converged" else ()
        return content_hash(
            self.scene_key, int(p), round(float(theta), 9), render_repeat, self.margin_px,
            RENDER_VERSION, *converged,
        )  # fmt: skip

    def hdr(self, p: int, theta: float, render_repeat: int):
        """The linear crop render and its offset, or None when no sticker faces the camera."""
        region = self.region(p, theta)
        if region is None:
            return None
        path = self.cache.path("renders", self.render_key(p, theta, render_repeat), ".exr")
        with self._timed("io"):
            cached = self.cache.read(path, lambda f: imaging.read_exr(f, region.size))
        if cached is not None:
            return cached, region.offset
        scene = self.scene()
        with self._timed("pose update"):
            scene.set_pose(p, theta)
        seed = config_seed(self.state.scene.render_seed, p, theta, render_repeat)
        with self._timed("sampling"):
            if self.state.scene.quality.mode == "converged":
                converged = converged_pixels(scene, region.pixels(), seed)
                values = converged.values
                self.sticker_treatments.update(converged.treatments.values())
            else:
                values = scene.render_pixels(region.pixels(), seed)
        with self._timed("image pipeline"):
            hdr = imaging.quantise_half(region.crop(values))
        with self._timed("io"):
            try:
                imaging.write_exr(path, hdr, exclusive=True)
            except FileExistsError:  # another process published this render first: share it
                shared = self.cache.read(path, lambda f: imaging.read_exr(f, region.size))
                if shared is None:  # it was corrupt (and is now moved aside): publish ours
                    imaging.write_exr(path, hdr)
                else:
                    hdr = shared
        return hdr, region.offset

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
            with self._timed("io"):
                stored = self.cache.read(meta, _read_meta)
                crop8 = self.cache.read(png, imaging.read_png)
            if stored is not None and crop8 is not None:
                return Frame(crop8, stored[0], self.image_size, stored[1])
        rendered = self.hdr(p, theta, render_repeat)
        if rendered is None:
            return None
        hdr, offset = rendered
        seed = config_seed(self.state.scene.render_seed, p, theta, "image", repeat)
        image = self.state.image
        meter = self.meter(p, theta, render_repeat) if needs_meter(image) else None
        ctx = ImageContext(
            offset,
            self.state.scene.camera,
            np.random.default_rng(seed),
            meter=None if meter is None else meter * np.float32(image.exposure),
        )
        with self._timed("image pipeline"):
            crop8 = run_pipeline(hdr, image, ctx)
        with self._timed("io"):
            stored_meta = {"offset": list(offset), "size": list(self.image_size)}
            write_text(meta, json.dumps({**stored_meta, "record": ctx.record} if ctx.record
                                        else stored_meta))  # fmt: skip
            imaging.write_png(png, crop8)
        return Frame(crop8, offset, self.image_size, dict(ctx.record))

    def meter(self, p: int, theta: float, render_repeat: int) -> np.ndarray:
        """The whole frame's metering grid: one pixel every :data:`METER_STRIDE_PX` px (linear).

        Path traced at the scene's samples per pixel (a meter averages thousands of them), and
        cached beside the renders.
        """
        (w, h), s = self.image_size, METER_STRIDE_PX
        cols, rows = np.arange(s // 2, w, s), np.arange(s // 2, h, s)
        key = content_hash(self.render_key(p, theta, render_repeat), "meter", s)
        path = self.cache.path("renders", key, ".exr")
        with self._timed("io"):
            cached = self.cache.read(path, lambda f: imaging.read_exr(f, (len(cols), len(rows))))
        if cached is not None:
            return cached
        scene = self.scene()
        with self._timed("pose update"):
            scene.set_pose(p, theta)
        uu, vv = np.meshgrid(cols, rows)
        seed = config_seed(self.state.scene.render_seed, p, theta, render_repeat, "meter")
        with self._timed("sampling"):
            values = scene.render_pixels(np.stack([uu.ravel(), vv.ravel()], axis=1), seed)
        grid = imaging.quantise_half(values.reshape(len(rows), len(cols), 3))
        with self._timed("io"):
            imaging.write_exr(path, grid)
        return grid

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
        with self._timed("io"):
            cached = self.cache.load_arrays("results", key)
        if cached is not None:
            return ConfigResult(**cached)
        frame = self.frame(p, theta, repeat, render_repeat)
        if frame is None:
            result = estimate_tags(self.rig, self.state.estimation, self.tags, {}, p, theta)
        else:
            result = self._measure(frame, p, theta)
        with self._timed("io"):
            self.cache.save_arrays("results", key, result.arrays())
        return result

    def _measure(self, frame: Frame, p: int, theta: float) -> ConfigResult:
        """Detection, pose and image evidence of one frame (and the camera's choices)."""
        with self._timed("detection"):
            found, rejected = self._detect(frame)
        args = (self.rig, self.state.estimation, self.tags)
        with self._timed("pnp"):
            result = estimate_tags(*args, found, p, theta)
        with self._timed("image statistics"):
            gray, offset = frame.gray_crop, frame.offset
            add_image_stats(result, *args, gray, offset, found, rejected, p, theta, rgb=frame.crop)
        result.auto_exposure_ev[:] = frame.record.get("auto_exposure_ev", np.nan)
        return result

    def _detect(self, frame: Frame) -> tuple[dict[int, np.ndarray], list[np.ndarray]]:
        """ArUco on the frame: on the window around the crop where that is exact (it is faster)."""
        pad = self.detector.window_pad_px
        if pad is None:
            return self.detector.detect_with_rejected(frame.gray())
        window, origin = frame.gray_window(pad)
        return self.detector.detect_with_rejected(window, origin, frame.size)


def assets_hash() -> str:
    """Content hash of the fixture meshes and tag textures every render depends on."""
    return file_hash(sorted(assets_dir().glob("*.ply")) + sorted(assets_dir().glob("tag_*.png")))
