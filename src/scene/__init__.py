"""Renderer-agnostic scene description (the Kubric idea): materials, tag print, lights, objects.

Lowest layer above :mod:`simgap.core`: frozen, validated dataclasses that say *what* is in the
scene; :mod:`simgap.render` says how Mitsuba draws it. Scene-stage effects
(:mod:`simgap.effects.scene`) change a :class:`SceneSpec` with typed replacements.
"""

from __future__ import annotations

from simgap.scene.lights import LightSpec
from simgap.scene.materials import Coating, Conductor, Diffuse, Material, Plastic, TagPrint
from simgap.scene.spec import ObjectSpec, SceneSpec, apply_overrides, load_scene_spec

__all__ = [
    "Coating",
    "Conductor",
    "Diffuse",
    "LightSpec",
    "Material",
    "ObjectSpec",
    "Plastic",
    "SceneSpec",
    "TagPrint",
    "apply_overrides",
    "load_scene_spec",
]
