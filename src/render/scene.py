"""The parametric Mitsuba scene of the fixture, built from the template and the rig.

The scene is loaded once; :meth:`FixtureScene.set_pose` moves the carriage, camera and turntable
through ``mi.traverse`` so that every pose reuses the compiled render kernels
(docs/conventions.md §4). The scene frame is the rig's ``rail`` frame (metres).
"""

from __future__ import annotations

import copy
from types import ModuleType
from typing import Any

import cv2
import numpy as np

from simgap.core import transforms as tf
from simgap.core.config import ConfigError
from simgap.core.paths import assets_dir
from simgap.core.rig import NOMINAL, CameraModel, FixtureErrors, Rig
from simgap.render.backend import mitsuba
from simgap.render.camera import PLUGIN_NAME as SENSOR_PLUGIN
from simgap.render.mitsuba_scene import bsdf, emitter, light_transform, print_albedo, tag_bsdf
from simgap.scene.materials import Diffuse
from simgap.scene.spec import SceneSpec, load_scene_spec

#: Most samples traced in one kernel launch of :meth:`FixtureScene.render_pixels` (bounds memory).
SAMPLES_PER_LAUNCH = 1 << 22

__all__ = [
    "FixtureScene",
    "PixelTracer",
    "sensor_dict",
    "SceneSpec",
    "load_scene_spec",
    "pose_transforms",
    "projected_sticker_boxes",
    "projected_sticker_outlines",
]


class PixelTracer:
    """Renders any set of a loaded scene's pixels through its OpenCV sensor (one kernel).

    A subclass sets ``mi`` (the Mitsuba module), ``scene`` (the loaded scene), ``camera`` (its
    :mod:`simgap.render.camera` sensor), ``spp``, ``spec`` (its pixel filter: ``spec.rfilter``)
    and ``pose`` (None until the scene is posed).
    """

    mi: ModuleType
    scene: Any
    camera: Any
    spp: int
    spec: SceneSpec
    pose: Any

    def render_pixels(self, pixels: np.ndarray, seed: int = 0) -> np.ndarray:
        """Render any set of full-image pixels: only these are sampled.

        Each pixel gets :attr:`spp` stratified samples, traced by the scene's integrator and
        averaged; the samples' offsets from the pixel centre are drawn from the scene's
        reconstruction filter (:func:`filter_offsets`: filter importance sampling), so a ``box``
        filter samples the pixel's square and a ``tent`` or ``gaussian`` one a softer
        footprint reaching into the neighbours, as the template's film would weigh them. The
        number of pixels is not part of the compiled kernel: regions of any size and shape reuse
        it (one kernel per scene, launched in chunks of :data:`SAMPLES_PER_LAUNCH` samples).

        Parameters
        ----------
        pixels : ndarray of int (N, 2)
            Full-image pixel columns and rows ``(u, v)`` (px).
        seed : int
            Sampler seed (same seed, same image).

        Returns
        -------
        numpy.ndarray
            Linear RGB radiance, float32, shape (N, 3).
        """
        if self.pose is None:
            raise RuntimeError("set_pose() must be called before render()")
        pixels = np.asarray(pixels).reshape(-1, 2)
        out = np.empty((len(pixels), 3), np.float32)
        for start, padded, launch_seed in launches(pixels, seed, self.spp):
            m = min(len(padded), len(pixels) - start)
            out[start : start + m] = self._render_launch(padded, launch_seed)[:m]
        return out

    def trace(
        self,
        pixels: np.ndarray,
        seed: int,
        spp: int | None = None,
        pattern: np.ndarray | None = None,
    ):
        """Trace ``spp`` camera samples through each pixel (one kernel launch; Dr.Jit values).

        Each pixel's samples are consecutive lanes; their offsets follow the reconstruction
        filter (:func:`filter_offsets`). Returns the primary rays and the integrator's radiance
        per sample (``mitsuba.Ray3f``, ``mitsuba.Color3f``), unevaluated, for
        :meth:`render_pixels` and for passes that also need the primary hits
        (:mod:`simgap.render.pixel_samples`). ``pixels`` holds at least two (a one-element array
        would become a literal of the kernel, recompiled per value).

        With ``pattern`` (S, 4), every pixel takes the same S samples instead of the sampler's
        (columns: the pixel filter's sample, then the aperture's, in [0, 1)); ``seed`` and
        ``spp`` are then unused, and only the primary rays are traced (radiance None).
        """
        ray, sampler = self.camera_rays(pixels, seed, spp, pattern)
        if sampler is None:
            return ray, None
        value, _, _ = self.scene.integrator().sample(
            self.scene, sampler, self.mi.RayDifferential3f(ray)
        )
        return ray, value

    def camera_rays(
        self,
        pixels: np.ndarray,
        seed: int,
        spp: int | None = None,
        pattern: np.ndarray | None = None,
    ):
        """The primary rays of :meth:`trace` and the sampler that continues their paths.

        The sampler is None with a ``pattern`` (primary rays only).
        """
        import drjit as dr

        mi = self.mi
        sampler = None
        if pattern is None:
            spp = self.spp if spp is None else int(spp)
            sampler = self.camera.sampler().clone()
            if spp != self.spp:
                sampler.set_sample_count(spp)
            sampler.set_samples_per_wavefront(spp)
            sampler.seed(seed, len(pixels) * spp)
            filter_sample, aperture = sampler.next_2d(), sampler.next_2d()
        else:
            spp = len(pattern)
            tiled = np.tile(np.asarray(pattern, np.float32), (len(pixels), 1))
            filter_sample = mi.Point2f(tiled[:, 0], tiled[:, 1])
            aperture = mi.Point2f(tiled[:, 2], tiled[:, 3])
        pixel = dr.arange(mi.UInt32, len(pixels) * spp) // spp
        u = dr.gather(mi.Float, mi.Float(pixels[:, 0]), pixel)
        v = dr.gather(mi.Float, mi.Float(pixels[:, 1]), pixel)
        offset = filter_offsets(self.spec.rfilter, filter_sample, mi)
        return self.camera.ray_through(u + offset.x, v + offset.y, aperture), sampler

    def _render_launch(self, pixels: np.ndarray, seed: int) -> np.ndarray:
        """One kernel launch of :meth:`render_pixels` (N, 3)."""
        import drjit as dr

        spp = self.spp
        _, radiance = self.trace(pixels, seed)
        dr.eval(radiance)
        # the samples were drawn from the reconstruction filter, so each pixel's value is the
        # plain mean of its consecutive samples; per channel, so that an evaluated Float
        # converts to numpy without a (size-specific) kernel
        means = [dr.block_sum(c, spp) / spp for c in (radiance.x, radiance.y, radiance.z)]
        dr.eval(means)
        return np.stack([np.asarray(c) for c in means], axis=-1)


class FixtureScene(PixelTracer):
    """The fixture loaded in Mitsuba, posable per (p, theta).

    Parameters
    ----------
    rig : Rig
        Fixture description; its camera model is what the renderer images with.
    spec : SceneSpec
        The scene description (:mod:`simgap.scene`): materials, tag print, lights, objects and
        integrator; converted by :mod:`simgap.render.mitsuba_scene`.
    film_size : tuple of int
        Film width, height (px): the crop size, or the full image size.
    spp : int
        Samples per pixel.
    sampler : str
        Mitsuba sampler plugin (``multijitter``, ``ldsampler``, ``independent`` ...).
    errors : FixtureErrors
        The true fixture's differences from CAD, used for rendering (the ground truth stays CAD).
    camera : CameraModel, optional
        The true camera that takes the picture (default: the rig's).
    tag_scale : float
        Printed size of the stickers relative to nominal (dimensionless).
    lens : tuple of float
        Thin lens ``(aperture_radius_m, focus_distance_m)``; radius 0 is a pinhole.
    max_depth : int, optional
        Path tracer depth (default: the template integrator's).
    """

    def __init__(
        self,
        rig: Rig,
        spec: SceneSpec,
        film_size: tuple[int, int],
        spp: int = 16,
        sampler: str = "multijitter",
        errors: FixtureErrors = NOMINAL,
        camera: CameraModel | None = None,
        tag_scale: float = 1.0,
        lens: tuple[float, float] = (0.0, 1.0),
        max_depth: int | None = None,
    ) -> None:
        self.mi = mi = mitsuba()
        self.rig, self.spec, self.errors, self.tag_scale = rig, spec, errors, float(tag_scale)
        self.film_size, self.spp = tuple(film_size), int(spp)
        #: the integrator's settings (the template's, with ``max_depth`` if given)
        self.integrator_dict: dict[str, Any] = {
            **copy.deepcopy(spec.integrator),
            **({} if max_depth is None else {"max_depth": int(max_depth)}),
        }
        scene_dict: dict[str, Any] = {
            "type": "scene",
            "integrator": copy.deepcopy(self.integrator_dict),
            "sensor": sensor_dict(film_size, spec.rfilter, sampler, self.spp),
        }
        for name, obj in spec.objects.items():
            mesh_path = assets_dir() / obj.mesh
            if not mesh_path.is_file():
                raise ConfigError(
                    f"objects.{name}.mesh: {mesh_path} not found (run `simgap assets`)"
                )
            scene_dict[name] = {
                "type": "ply",
                "filename": str(mesh_path),
                "face_normals": True,
                "bsdf": bsdf(spec.materials[obj.material]),
            }
        if spec.ground is not None:
            g = spec.ground
            scene_dict["ground"] = {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f().translate([0.0, 0.0, g.height_m])
                @ mi.ScalarTransform4f().scale([g.size_m / 2, g.size_m / 2, 1.0]),
                "bsdf": bsdf(Diffuse(reflectance=g.reflectance)),
            }
        #: per tag id, the print's albedo texture the tag BSDF looks up (rows x columns; one
        #: texel per cell with nearest lookup, each cell repeated with bilinear)
        self.print_albedo: dict[int, np.ndarray] = {}
        for face in rig.tags.faces:
            texture = cv2.imread(str(assets_dir() / f"tag_{face.id}.png"), cv2.IMREAD_GRAYSCALE)
            if texture is None:
                raise ConfigError(f"assets/tag_{face.id}.png not found (run `simgap assets`)")
            self.print_albedo[face.id] = print_albedo(spec.tag, texture)
            scene_dict[f"tag_{face.id}"] = {
                "type": "rectangle",
                "bsdf": tag_bsdf(spec.tag, self.print_albedo[face.id], mi),
            }
        rail_from_eyepoint = rig.rail_from_eyepoint(0, errors)
        for name, light in spec.lights.items():
            scene_dict[f"light_{name}"] = emitter(light.placed(rail_from_eyepoint), mi)
        try:
            # optimize=False: Mitsuba would merge meshes sharing a BSDF, and we move them apart
            self.scene = mi.load_dict(scene_dict, optimize=False)
        except RuntimeError as exc:
            raise ConfigError(f"scene: Mitsuba could not build the scene: {exc}") from exc
        self.params = mi.traverse(self.scene)
        self.camera = self.scene.sensors()[0]
        # the sampler may round the count up (multijitter: to a product of two near-equal sides)
        self.spp = int(self.camera.sampler().sample_count())
        #: the camera that takes the picture, and its thin lens (aperture radius, focus; m)
        self.camera_model = cam = camera or rig.camera
        self.lens = (float(lens[0]), float(lens[1]))
        self.camera.set_intrinsics(
            cam.fx, cam.fy, cam.cx, cam.cy, cam.distortion, cam.distortion_model
        )
        self.camera.set_lens(*self.lens)
        self._base = {
            name: np.array(self.params[f"{name}.vertex_positions"]).reshape(-1, 3)
            for name, obj in spec.objects.items()
            if obj.frame != "rail"
        }
        self.pose: tuple[float, float] | None = None

    def set_pose(self, p: float, theta: float) -> None:
        """Move carriage, camera, turntable and tags to pin hole ``p`` and angle ``theta`` (rad)."""
        mi = self.mi
        world = pose_transforms(self.rig, p, theta, self.errors, self.tag_scale)
        for name, base in self._base.items():
            moved = tf.apply(world[self.spec.objects[name].frame], base)
            self.params[f"{name}.vertex_positions"] = mi.Float(moved.ravel().astype(np.float32))
        for face in self.rig.tags.faces:
            self.params[f"tag_{face.id}.to_world"] = mi.ScalarTransform4f(world[f"tag_{face.id}"])
        for name, light in self.spec.lights.items():
            if light.frame == "rail" or light.type == "constant":
                continue
            placed = light.placed(world[light.frame])
            if light.type == "point":
                self.params[f"light_{name}.position"] = mi.ScalarPoint3f(placed.position)
            else:
                self.params[f"light_{name}.to_world"] = light_transform(placed, mi)
        self.params.update()
        self.camera.set_pose(world["camera"])
        self.pose = (p, theta)

    def render(self, crop_offset: tuple[int, int] = (0, 0), seed: int = 0) -> np.ndarray:
        """Render the film's rectangle at ``crop_offset`` (px, top-left in the full image).

        Returns
        -------
        numpy.ndarray
            Linear RGB radiance, float32, shape (height, width, 3).
        """
        w, h = self.film_size
        rows, cols = np.mgrid[0:h, 0:w]
        pixels = np.stack([cols.ravel() + crop_offset[0], rows.ravel() + crop_offset[1]], axis=1)
        return self.render_pixels(pixels, seed).reshape(h, w, 3)


def sensor_dict(
    film_size: tuple[int, int], rfilter: dict[str, Any], sampler: str, spp: int
) -> dict[str, Any]:
    """The dict of simgap's OpenCV sensor (:mod:`simgap.render.camera`), linear RGB film (px)."""
    return {
        "type": SENSOR_PLUGIN,
        "film": {
            "type": "hdrfilm",
            "width": int(film_size[0]),
            "height": int(film_size[1]),
            "rfilter": copy.deepcopy(rfilter),
            "pixel_format": "rgb",
            "component_format": "float32",
        },
        "sampler": {"type": sampler, "sample_count": int(spp)},
    }


def launches(pixels: np.ndarray, seed: int, spp: int, *stream: int):
    """Split ``pixels`` (N, 2) into kernel launches of at most :data:`SAMPLES_PER_LAUNCH` samples.

    Yields ``(start, padded, launch_seed)``: the chunk's first index, its pixels as float32 padded
    to at least two (a one-element array would become a literal of the kernel, recompiled per
    value) and the launch's seed, drawn from ``seed``, the launch's number and ``stream`` (another
    pass over the same pixels takes another stream).
    """
    step = max(SAMPLES_PER_LAUNCH // spp, 2)
    for k, start in enumerate(range(0, len(pixels), step)):
        chunk = pixels[start : start + step]
        padded = np.resize(chunk, (max(len(chunk), 2), 2)).astype(np.float32)
        launch_seed = np.random.SeedSequence([int(seed), k, *stream]).generate_state(1)[0]
        yield start, padded, int(launch_seed)


def filter_offsets(rfilter: dict[str, Any], sample, mi: ModuleType):
    """Sample offsets from the pixel centre (px) drawn from a reconstruction filter.

    Filter importance sampling (Ernst et al. 2006): a pixel's value is the plain mean of radiance
    samples whose offsets follow the filter's (separable, normalised) weight, which equals the
    weighted mean a film computes, without negative weights or splatting; the sampler's
    stratification of ``sample`` carries over through the warps. ``box``: uniform over the
    pixel's square (the offsets ``sample - 0.5`` exactly); ``tent``: Mitsuba's
    ``square_to_tent`` scaled by the radius; ``gaussian``: ``square_to_std_normal`` scaled by the
    standard deviation.

    Parameters
    ----------
    rfilter : dict
        The scene's ``rfilter`` (checked: :data:`simgap.scene.spec.RFILTERS`).
    sample : mitsuba.Point2f
        Uniform samples in the unit square.
    mi : module
        The Mitsuba module (variant set).
    """
    kind = rfilter["type"]
    if kind == "tent":
        return mi.warp.square_to_tent(sample) * float(rfilter.get("radius", 1.0))
    if kind == "gaussian":
        return mi.warp.square_to_std_normal(sample) * float(rfilter.get("stddev", 0.5))
    return sample - 0.5


def pose_transforms(
    rig: Rig, p: float, theta: float, errors: FixtureErrors = NOMINAL, tag_scale: float = 1.0
) -> dict[str, np.ndarray]:
    """Rail-frame 4x4 transforms of everything that moves at (p, theta), for the true fixture.

    ``carriage``, ``eyepoint`` and ``turntable`` (the frames objects are attached to; ``rail``
    is the identity), ``camera`` (rail from the OpenCV camera frame: x right, y down, z along
    the optical axis) and ``tag_<id>`` (rail from a sticker's 2 x 2 rectangle, z its normal:
    the sticker's side scaled by ``tag_scale``). Renderer-agnostic (m, dimensionless).
    """
    frames = {
        "rail": np.eye(4),
        "carriage": rig.rail_from_carriage(p, errors),
        "eyepoint": rig.rail_from_eyepoint(p, errors),
        "turntable": rig.rail_from_turntable(theta, errors),
    }
    frames["camera"] = frames["eyepoint"] @ tf.make(tf.GLOBAL_FROM_CV)
    half = rig.sticker_size() * tag_scale / 2
    for face in rig.tags.faces:
        rail_from_tag = frames["turntable"] @ rig.turntable_from_tag(face.id, errors)
        frames[f"tag_{face.id}"] = rail_from_tag @ np.diag([half, half, 1.0, 1.0])
    return frames


def projected_sticker_outlines(
    rig: Rig,
    p: float,
    theta: float,
    errors: FixtureErrors = NOMINAL,
    camera: CameraModel | None = None,
    tag_scale: float = 1.0,
    points_per_side: int = 1,
) -> dict[int, np.ndarray]:
    """Image outlines of the stickers facing the camera, by tag id.

    Parameters
    ----------
    rig, p, theta, errors, camera, tag_scale
        As :class:`FixtureScene` (``camera`` default: the rig's), pin hole and angle (rad).
    points_per_side : int
        Points projected along each side: 1 gives the four corners, more follow the sides'
        curvature under lens distortion.

    Returns
    -------
    dict of int to ndarray (4 * points_per_side, 2)
        Pixel coordinates (px) around each facing sticker, starting at its top-left corner.
    """
    half = rig.sticker_size() * tag_scale / 2
    corners = np.array([[-half, half, 0], [half, half, 0], [half, -half, 0], [-half, -half, 0]])
    t = np.arange(points_per_side)[:, None] / points_per_side
    ends = np.roll(corners, -1, axis=0)
    outline = np.concatenate([a + t * (b - a) for a, b in zip(corners, ends, strict=True)])
    cv_from_eye = tf.make(tf.GLOBAL_FROM_CV.T)
    cam = camera or rig.camera
    outlines = {}
    for face in rig.tags.faces:
        if rig.view_angle(face.id, p, theta, errors) <= 0:
            continue
        cv_from_tag = cv_from_eye @ rig.eyepoint_from_tag(face.id, p, theta, errors)
        pts = tf.apply(cv_from_tag, outline)
        outlines[face.id] = cam.project(pts).reshape(-1, 2)
    return outlines


def projected_sticker_boxes(
    rig: Rig, p: float, theta: float, **options: Any
) -> dict[int, tuple[float, float, float, float]]:
    """Pixel bounding boxes ``(u0, v0, u1, v1)`` of the stickers facing the camera, by tag id.

    ``options`` (``errors``, ``camera``, ``tag_scale``) are those of
    :func:`projected_sticker_outlines`.
    """
    outlines = projected_sticker_outlines(rig, p, theta, **options)
    return {k: (*uv.min(axis=0), *uv.max(axis=0)) for k, uv in outlines.items()}
