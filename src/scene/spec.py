"""The scene description: objects on the rig's frames, their materials, the tag print, lights.

:func:`load_scene_spec` reads a template from ``mitsuba_scenes/`` (default
``pass_fixture.yaml``), merges an experiment's ``scene:`` overrides into it
(:func:`apply_overrides`) and returns a typed, frozen :class:`SceneSpec`. Scene-stage effects change
that description with :func:`dataclasses.replace`; the renderer converts it
(:mod:`simgap.render.mitsuba_scene`). The description never names a renderer plugin except in the
``integrator`` and ``rfilter`` settings, which are passed to the renderer as they are.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from simgap.core.config import (
    OMIT_DEFAULT,
    ConfigError,
    check_finite,
    deep_merge,
    from_mapping,
    read_yaml,
)
from simgap.core.paths import scenes_dir
from simgap.scene.lights import LightSpec
from simgap.scene.materials import (
    Material,
    TagPrint,
    material_from_mapping,
    tag_print_from_mapping,
)

DEFAULT_TEMPLATE = "pass_fixture.yaml"
#: Frames of the rig's transform tree an object can be attached to (:mod:`simgap.core.rig`).
RigFrame = Literal["rail", "carriage", "eyepoint", "turntable"]
#: Template material name of the tag stickers (added from the rig's tag faces).
TAG_MATERIAL = "tag"
_SECTIONS = ("integrator", "rfilter", "objects", "materials", "lights")


#: Reconstruction filters the renderer draws pixel samples from
#: (:func:`simgap.render.scene.filter_offsets`), and their parameters (px): Mitsuba's
#: ``box`` (the pixel's square), ``tent`` (``radius``, default 1) and ``gaussian`` (``stddev``,
#: default 0.5; Mitsuba truncates it at 4 standard deviations, a 6e-5 share of its mass).
RFILTERS = {"box": (), "tent": ("radius",), "gaussian": ("stddev",)}


def check_rfilter(rfilter: dict[str, Any]) -> None:
    """Raise ConfigError unless ``rfilter`` is one of :data:`RFILTERS` with positive parameters."""
    kind = rfilter.get("type")
    if kind not in RFILTERS:
        raise ConfigError(f"rfilter.type: expected one of {', '.join(RFILTERS)}, got {kind!r}")
    for key, value in rfilter.items():
        if key == "type":
            continue
        if key not in RFILTERS[kind]:
            allowed = ", ".join(RFILTERS[kind]) or "no parameters"
            raise ConfigError(f"rfilter.{key}: unknown key for {kind}; expected {allowed}")
        if not isinstance(value, (int, float)) or not value > 0:
            raise ConfigError(f"rfilter.{key}: expected a number > 0 (px), got {value!r}")


@dataclass(frozen=True)
class ObjectSpec:
    """A mesh from ``assets/`` attached to one rig frame, with a material name."""

    mesh: str
    frame: RigFrame
    material: str


#: Height of the template table's top (m, rail frame z): the rail stands on it
#: (:func:`simgap.render.assets.fixture_meshes`), and a ground replacing the table lies there.
TABLE_TOP_Z_M = -0.02


@dataclass(frozen=True)
class Ground:
    """A flat ground under the fixture: a square of diffuse albedo in the rail frame's XY plane.

    Attributes
    ----------
    height_m : float
        Height of the ground plane (m, rail frame z).
    size_m : float
        Side of the square, centred on the rail frame's origin (m).
    reflectance : float
        Diffuse (Lambertian) albedo (dimensionless, linear).
    """

    height_m: float
    size_m: float
    reflectance: float

    def __post_init__(self) -> None:
        if not (self.size_m > 0 and 0 <= self.reflectance <= 1):
            raise ConfigError(
                f"ground: expected size_m > 0 and 0 <= reflectance <= 1, got {self.size_m!r}, "
                f"{self.reflectance!r}"
            )


@dataclass(frozen=True)
class SceneSpec:
    """Resolved scene: integrator, pixel reconstruction filter, objects, materials, tag, lights.

    Attributes
    ----------
    integrator : dict
        Renderer integrator settings (``{type: path, max_depth: 3}``).
    rfilter : dict
        Pixel reconstruction filter (:data:`RFILTERS`): ``box`` keeps edges sharpest and renders
        bit-identical; ``tent`` (``radius`` px) and ``gaussian`` (``stddev`` px) are softer
        cameras.
    objects : dict of str to ObjectSpec
        Meshes on rig frames, each naming a material of ``materials``.
    materials : dict of str to Material
        Fixture materials by name (the tag's print is ``tag``).
    tag : TagPrint
        The printed stickers (the template's ``materials.tag``).
    lights : dict of str to LightSpec
        Lights by name (``key``, ``ambient`` in the default template).
    ground : Ground, optional
        A ground plane under the fixture (a planetary surface; none in the lab template).
    """

    integrator: dict[str, Any] = field(default_factory=lambda: {"type": "path", "max_depth": 3})
    rfilter: dict[str, Any] = field(default_factory=lambda: {"type": "box"})
    objects: dict[str, ObjectSpec] = field(default_factory=dict)
    materials: dict[str, Material] = field(default_factory=dict)
    tag: TagPrint = field(default_factory=TagPrint)
    lights: dict[str, LightSpec] = field(default_factory=dict)
    ground: Ground | None = field(default=None, metadata=OMIT_DEFAULT)

    def __post_init__(self) -> None:
        for name, obj in self.objects.items():
            if obj.material not in self.materials:
                raise ConfigError(f"objects.{name}.material: unknown material {obj.material!r}")

    def with_material(self, name: str, material: Material) -> SceneSpec:
        """The scene with material ``name`` replaced (or added)."""
        return _replace(self, materials={**self.materials, name: material})

    def with_light(self, name: str, light: LightSpec) -> SceneSpec:
        """The scene with light ``name`` replaced (or added)."""
        return _replace(self, lights={**self.lights, name: light})

    def with_tag(self, tag: TagPrint) -> SceneSpec:
        """The scene with another tag print."""
        return _replace(self, tag=tag)

    def without_lights(self, *names: str) -> SceneSpec:
        """The scene without the lights ``names`` (those it has)."""
        return _replace(self, lights={k: v for k, v in self.lights.items() if k not in names})

    def without_objects(self, *names: str) -> SceneSpec:
        """The scene without the objects ``names`` (those it has)."""
        return _replace(self, objects={k: v for k, v in self.objects.items() if k not in names})

    def with_ground(self, ground: Ground | None) -> SceneSpec:
        """The scene with a ground plane (None: without)."""
        return _replace(self, ground=ground)


def _replace(spec: SceneSpec, **changes: Any) -> SceneSpec:
    return dataclasses.replace(spec, **changes)


def apply_overrides(template: dict, overrides: dict) -> dict:
    """Merge scene overrides into a template (both plain YAML data).

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
                keep = (
                    {k: old[k] for k in ("ink", "paper") if k in old}
                    if name == TAG_MATERIAL
                    else {}
                )
                entries[name] = {**keep, **entry}
            else:
                entries[name] = deep_merge(old, entry) if isinstance(entry, dict) else entry
        data[section] = entries
    rest = {k: v for k, v in overrides.items() if k not in ("materials", "lights")}
    return deep_merge(data, rest)


def _mapping(value: Any, where: str) -> Mapping[str, Any]:
    """``value`` if it is a mapping, else a ConfigError naming ``where``."""
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: expected a mapping, got {value!r}")
    return value


def _typed(cls: type, value: Any, where: str) -> Any:
    """``cls`` from a template mapping (strict: :func:`simgap.core.config.from_mapping`)."""
    return from_mapping(cls, _mapping(value, where), where=where)


def scene_spec_from_mapping(data: Mapping[str, Any], where: str = "") -> SceneSpec:
    """Build a :class:`SceneSpec` from resolved template data.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming ``where`` and the key path of an unknown key, a wrong type or a bad value.
    """
    unknown = sorted(set(map(str, data)) - set(_SECTIONS))
    if unknown:
        raise ConfigError(
            f"{where}{unknown[0]}: unknown key; expected one of {', '.join(_SECTIONS)}"
        )
    settings = {}
    for key in ("integrator", "rfilter"):
        if key in data:
            settings[key] = copy.deepcopy(dict(_mapping(data[key], f"{where}{key}")))
            check_finite(settings[key], f"{where}{key}")
    if "rfilter" in settings:
        try:
            check_rfilter(settings["rfilter"])
        except ConfigError as exc:
            raise ConfigError(f"{where}{exc}") from None
    objects = {
        str(name): _typed(ObjectSpec, obj, f"{where}objects.{name}")
        for name, obj in _mapping(data.get("objects", {}), f"{where}objects").items()
    }
    materials = dict(_mapping(data.get("materials", {}), f"{where}materials"))
    if TAG_MATERIAL not in materials:
        raise ConfigError(f"{where}materials.tag: required (the tag sticker material)")
    tag = tag_print_from_mapping(materials.pop(TAG_MATERIAL), f"{where}materials.tag")
    fixture = {
        str(name): material_from_mapping(m, f"{where}materials.{name}")
        for name, m in materials.items()
    }
    lights = {
        str(name): _typed(LightSpec, light, f"{where}lights.{name}")
        for name, light in _mapping(data.get("lights", {}), f"{where}lights").items()
    }
    try:
        return SceneSpec(**settings, objects=objects, materials=fixture, tag=tag, lights=lights)
    except ConfigError as exc:
        raise ConfigError(f"{where}{exc}") from None


def load_scene_spec(
    overrides: dict | None = None, template: str | Path | None = None
) -> SceneSpec:
    """Read a scene template (default ``mitsuba_scenes/pass_fixture.yaml``) with overrides.

    Parameters
    ----------
    overrides : dict, optional
        An experiment's ``scene:`` section (template vocabulary).
    template : str or Path, optional
        Another template file.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the template file and the key path.
    """
    if not overrides and template is None:
        return default_scene_spec()
    return _load(Path(template) if template else scenes_dir() / DEFAULT_TEMPLATE, overrides or {})


def _load(path: Path, overrides: dict) -> SceneSpec:
    data = apply_overrides(read_yaml(path), overrides)
    return scene_spec_from_mapping(data, where=f"{path}: ")


@lru_cache(maxsize=1)
def default_scene_spec() -> SceneSpec:
    """The default template without overrides (read once per process; the spec is frozen)."""
    return _load(scenes_dir() / DEFAULT_TEMPLATE, {})
