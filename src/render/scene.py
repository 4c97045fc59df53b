"""The parametric Mitsuba scene of the fixture, built from the template and the rig.

The scene is loaded once; :meth:`FixtureScene.set_pose` moves the carriage, camera and turntable
through ``mi.traverse`` so that every pose reuses the compiled render kernels (DESIGN §4). The scene
frame is the rig's ``rail`` frame (metres).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from simgap.core import transforms as tf
from simgap.core.config import ConfigError, deep_merge, from_mapping, read_yaml, require
from simgap.core.paths import assets_dir, scenes_dir
from simgap.core.rig import NOMINAL, CameraModel, FixtureErrors, Rig
from simgap.render.backend import mitsuba
from simgap.render.camera import PLUGIN_NAME as SENSOR_PLUGIN

DEFAULT_TEMPLATE = "pass_fixture.yaml"
Frame = Literal["rail", "carriage", "eyepoint", "turntable"]


@dataclass(frozen=True)
class ObjectSpec:
    """A mesh from ``assets/`` attached to one rig frame, with a material name."""

    mesh: str
    frame: Frame
    material: str


@dataclass(frozen=True)
class LightSpec:
    """A light in the rail frame.

    Attributes
    ----------
    type : {"area", "point", "spot", "constant"}
        Rectangle area light, isotropic point, spot light or uniform environment.
    position, target : tuple of float
        Light position and aim point (m, rail frame); unused for ``constant``.
    size : tuple of float
        Side lengths of an area light (m).
    radiance : float
        Emitted radiance of ``area`` and ``constant`` lights (W m^-2 sr^-1, linear units).
    intensity : float
        Radiant intensity of ``point`` and ``spot`` lights (W sr^-1).
    cutoff_deg : float
        Spot light cut-off angle (deg).
    rgb : tuple of float
        Linear RGB tint multiplying radiance/intensity (white = 1, 1, 1).
    """

    type: Literal["area", "point", "spot", "constant"]
    position: tuple[float, float, float] = (0.0, -0.3, 0.4)
    target: tuple[float, float, float] = (0.036749, 0.321749, 0.06)
    size: tuple[float, float] = (0.3, 0.3)
    radiance: float = 1.0
    intensity: float = 1.0
    cutoff_deg: float = 30.0
    rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        require(self.radiance >= 0 and self.intensity >= 0, "radiance/intensity: expected >= 0")
        require(0 < self.cutoff_deg < 90, "cutoff_deg: expected 0 < x < 90 (deg)")

    def to_mitsuba(self, mi) -> dict[str, Any]:
        """Return the Mitsuba dictionary of this light."""
        colour = np.asarray(self.rgb, float)
        if self.type == "constant":
            return {
                "type": "constant",
                "radiance": {"type": "rgb", "value": colour * self.radiance},
            }
        look = mi.ScalarTransform4f().look_at(
            origin=list(self.position), target=list(self.target), up=[0, 0, 1]
        )
        if self.type == "area":
            return {
                "type": "rectangle",
                "to_world": look
                @ mi.ScalarTransform4f().scale([self.size[0] / 2, self.size[1] / 2, 1]),
                "emitter": {
                    "type": "area",
                    "radiance": {"type": "rgb", "value": colour * self.radiance},
                },
                "bsdf": {"type": "diffuse", "reflectance": 0.0},
            }
        if self.type == "point":
            return {
                "type": "point",
                "position": list(self.position),
                "intensity": {"type": "rgb", "value": colour * self.intensity},
            }
        return {
            "type": "spot",
            "to_world": look,
            "cutoff_angle": self.cutoff_deg,
            "intensity": {"type": "rgb", "value": colour * self.intensity},
        }


@dataclass(frozen=True)
class SceneSpec:
    """Resolved scene template: integrator, pixel reconstruction filter, objects, materials, lights.

    ``rfilter`` is the film's Mitsuba reconstruction filter (``box`` keeps edges sharpest and
    renders bit-identical; ``gaussian`` with ``stddev`` in px is a softer camera). The tag
    material may set ``texture_filter: bilinear`` (default ``nearest``): the marker texture is
    then upsampled :data:`BILINEAR_UPSAMPLE` times and filtered bilinearly, a print whose cell
    edges are slightly soft.
    """

    integrator: dict[str, Any] = field(default_factory=lambda: {"type": "path", "max_depth": 3})
    rfilter: dict[str, Any] = field(default_factory=lambda: {"type": "box"})
    objects: dict[str, ObjectSpec] = field(default_factory=dict)
    materials: dict[str, dict[str, Any]] = field(default_factory=dict)
    lights: dict[str, LightSpec] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, obj in self.objects.items():
            require(
                obj.material in self.materials,
                f"objects.{name}.material: unknown material {obj.material!r}",
            )
        require("tag" in self.materials, "materials.tag: required (the tag sticker material)")


def apply_overrides(template: dict, overrides: dict) -> dict:
    """Merge scene overrides into a template.

    Mappings merge recursively, except that a material or light override naming a ``type``
    replaces the template's entry (a BSDF's parameters belong to its type); the tag material
    keeps its ``ink`` and ``paper`` albedo across a type change.
    """
    data = dict(template)
    for section in ("materials", "lights"):
        entries = dict(data.get(section, {}))
        for name, entry in (overrides.get(section) or {}).items():
            old = entries.get(name, {})
            if isinstance(entry, dict) and "type" in entry and entry["type"] != old.get("type"):
                keep = {k: old[k] for k in ("ink", "paper") if k in old} if name == "tag" else {}
                entries[name] = {**keep, **entry}
            else:
                entries[name] = deep_merge(old, entry) if isinstance(entry, dict) else entry
        data[section] = entries
    rest = {k: v for k, v in overrides.items() if k not in ("materials", "lights")}
    return deep_merge(data, rest)


def load_scene_spec(overrides: dict | None = None, template: str | Path | None = None) -> SceneSpec:
    """Read a scene template (default ``mitsuba_scenes/pass_fixture.yaml``) with overrides."""
    path = Path(template) if template else scenes_dir() / DEFAULT_TEMPLATE
    data = apply_overrides(read_yaml(path), overrides or {})
    return from_mapping(SceneSpec, data, where=f"{path}: ")


#: Upsampling of the one-texel-per-cell marker texture before bilinear filtering.
BILINEAR_UPSAMPLE = 16


def _tag_material(spec: dict[str, Any], texture: np.ndarray, mi) -> dict[str, Any]:
    """Tag BSDF with the marker texture mapped to ink/paper albedo."""
    spec = dict(spec)
    ink, paper = float(spec.pop("ink", 0.03)), float(spec.pop("paper", 0.8))
    texture_filter = spec.pop("texture_filter", "nearest")
    if texture_filter not in ("nearest", "bilinear"):
        raise ConfigError(
            "materials.tag.texture_filter: expected 'nearest' or 'bilinear', "
            f"got {texture_filter!r}"
        )
    if texture_filter == "bilinear":
        texture = np.kron(texture, np.ones((BILINEAR_UPSAMPLE, BILINEAR_UPSAMPLE), texture.dtype))
    albedo = np.where(texture > 127, paper, ink).astype(np.float32)[..., None]
    bitmap = {
        "type": "bitmap",
        "bitmap": mi.Bitmap(albedo),
        "raw": True,
        "filter_type": texture_filter,
        "to_uv": mi.ScalarTransform4f().translate([0, 1, 0]).scale([1, -1, 1]),
    }
    slot = "reflectance" if spec.get("type", "diffuse") == "diffuse" else "diffuse_reflectance"
    return {**spec, slot: bitmap}


class FixtureScene:
    """The fixture loaded in Mitsuba, posable per (p, theta).

    Parameters
    ----------
    rig : Rig
        Fixture description; its camera model is what the renderer images with.
    spec : SceneSpec
        Materials, lights, objects and integrator.
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
        scene_dict: dict[str, Any] = {
            "type": "scene",
            "integrator": {
                **copy.deepcopy(spec.integrator),
                **({} if max_depth is None else {"max_depth": int(max_depth)}),
            },
            "sensor": {
                "type": SENSOR_PLUGIN,
                "film": {
                    "type": "hdrfilm",
                    "width": int(film_size[0]),
                    "height": int(film_size[1]),
                    "rfilter": copy.deepcopy(spec.rfilter),
                    "pixel_format": "rgb",
                    "component_format": "float32",
                },
                "sampler": {"type": sampler, "sample_count": self.spp},
            },
        }
        bsdfs = {name: m for name, m in spec.materials.items() if name != "tag"}
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
                "bsdf": copy.deepcopy(bsdfs[obj.material]),
            }
        for face in rig.tags.faces:
            texture = cv2.imread(str(assets_dir() / f"tag_{face.id}.png"), cv2.IMREAD_GRAYSCALE)
            if texture is None:
                raise ConfigError(f"assets/tag_{face.id}.png not found (run `simgap assets`)")
            scene_dict[f"tag_{face.id}"] = {
                "type": "rectangle",
                "bsdf": _tag_material(spec.materials["tag"], texture, mi),
            }
        for name, light in spec.lights.items():
            scene_dict[f"light_{name}"] = light.to_mitsuba(mi)
        try:
            # optimize=False: Mitsuba would merge meshes sharing a BSDF, and we move them apart
            self.scene = mi.load_dict(scene_dict, optimize=False)
        except RuntimeError as exc:
            raise ConfigError(f"scene: Mitsuba could not build the scene: {exc}") from exc
        self.params = mi.traverse(self.scene)
        self.camera = self.scene.sensors()[0]
        cam = camera or rig.camera
        self.camera.set_intrinsics(cam.fx, cam.fy, cam.cx, cam.cy, cam.distortion)
        self.camera.set_lens(*lens)
        self._base = {
            name: np.array(self.params[f"{name}.vertex_positions"]).reshape(-1, 3)
            for name, obj in spec.objects.items()
            if obj.frame != "rail"
        }
        self.pose: tuple[float, float] | None = None

    def frames(self, p: float, theta: float) -> dict[str, np.ndarray]:
        """Rail-frame poses of the movable frames at (p, theta) for the true fixture."""
        rig, err = self.rig, self.errors
        return {
            "carriage": rig.rail_from_carriage(p, err),
            "eyepoint": rig.rail_from_eyepoint(p, err),
            "turntable": rig.rail_from_turntable(theta, err),
        }

    def set_pose(self, p: float, theta: float) -> None:
        """Move carriage, camera, turntable and tags to pin hole ``p`` and angle ``theta`` (rad)."""
        mi, rig, err = self.mi, self.rig, self.errors
        frames = self.frames(p, theta)
        for name, base in self._base.items():
            moved = tf.apply(frames[self.spec.objects[name].frame], base)
            self.params[f"{name}.vertex_positions"] = mi.Float(moved.ravel().astype(np.float32))
        half = rig.sticker_size() * self.tag_scale / 2
        for face in rig.tags.faces:
            rail_from_tag = frames["turntable"] @ rig.turntable_from_tag(face.id, err)
            self.params[f"tag_{face.id}.to_world"] = mi.ScalarTransform4f(
                rail_from_tag @ np.diag([half, half, 1.0, 1.0])
            )
        self.params.update()
        self.camera.set_pose(frames["eyepoint"] @ tf.make(tf.GLOBAL_FROM_CV))
        self.pose = (p, theta)

    def render(self, crop_offset: tuple[int, int] = (0, 0), seed: int = 0) -> np.ndarray:
        """Render the film at ``crop_offset`` (px, top-left in the full image).

        Returns
        -------
        numpy.ndarray
            Linear RGB radiance, float32, shape (height, width, 3).
        """
        if self.pose is None:
            raise RuntimeError("set_pose() must be called before render()")
        self.camera.set_crop_offset(*crop_offset)
        img = self.mi.render(self.scene, spp=self.spp, seed=int(seed))
        return np.array(img, dtype=np.float32)


def projected_sticker_boxes(
    rig: Rig,
    p: float,
    theta: float,
    errors: FixtureErrors = NOMINAL,
    camera: CameraModel | None = None,
    tag_scale: float = 1.0,
):
    """Pixel bounding boxes ``(u0, v0, u1, v1)`` of the stickers facing the camera, by tag id."""
    half = rig.sticker_size() * tag_scale / 2
    corners = np.array([[-half, half, 0], [half, half, 0], [half, -half, 0], [-half, -half, 0]])
    cv_from_eye = tf.make(tf.GLOBAL_FROM_CV.T)
    cam = camera or rig.camera
    boxes = {}
    for face in rig.tags.faces:
        if rig.view_angle(face.id, p, theta, errors) <= 0:
            continue
        cv_from_tag = cv_from_eye @ rig.eyepoint_from_tag(face.id, p, theta, errors)
        pts = tf.apply(cv_from_tag, corners)
        uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), cam.matrix, cam.dist_coeffs)
        uv = uv.reshape(-1, 2)
        boxes[face.id] = (*uv.min(axis=0), *uv.max(axis=0))
    return boxes
