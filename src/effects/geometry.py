"""Geometry effects: the real fixture differs from its CAD (rendered; ground truth stays CAD)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from simgap.core.config import require
from simgap.effects.base import Effect, RelativeScale, register
from simgap.effects.state import VariantState

Vec3 = tuple[float, float, float]


def _errors(state: VariantState, **changes) -> VariantState:
    errors = dataclasses.replace(state.scene.errors, **changes)
    return dataclasses.replace(state, scene=dataclasses.replace(state.scene, errors=errors))


@register
class CameraMount(Effect):
    """Camera mount offset on the carriage: translation (m) and rotation vector (rad)."""

    name = "camera_mount"
    stage = "geometry"

    @dataclass(frozen=True)
    class Params:
        """Mount offset."""

        translation_m: Vec3 = (0.0, 0.0, 0.0)
        rotation_rad: Vec3 = (0.0, 0.0, 0.0)

        def __post_init__(self) -> None:
            require(
                all(abs(v) < 0.05 for v in self.translation_m),
                "translation_m: expected |t| < 0.05 m",
            )
            require(
                all(abs(v) < 0.3 for v in self.rotation_rad), "rotation_rad: expected |r| < 0.3 rad"
            )

    def apply(self, state: VariantState) -> VariantState:
        """Offset the eyepoint on its link."""
        return _errors(
            state,
            mount_translation=self.params.translation_m,
            mount_rotation=self.params.rotation_rad,
        )


@register
class TurntableOffset(Effect):
    """Turntable zero offset: every stop is rotated by ``angle_rad`` (rad, CCW about +Z)."""

    name = "turntable_offset"
    stage = "geometry"

    @dataclass(frozen=True)
    class Params:
        """Zero offset."""

        angle_rad: float = 0.0

        def __post_init__(self) -> None:
            require(abs(self.angle_rad) < 0.5, "angle_rad: expected |a| < 0.5 rad")

    def apply(self, state: VariantState) -> VariantState:
        """Offset the turntable zero."""
        return _errors(state, turntable_zero=self.params.angle_rad)


@register
class CarriagePitch(Effect):
    """Carriage pin pitch differs from the rig's (``links.pin_pitch``) by a relative ``scale``.

    ``scale`` is dimensionless: 0.01 = +1 %.
    """

    name = "carriage_pitch"
    stage = "geometry"

    Params = RelativeScale

    def apply(self, state: VariantState) -> VariantState:
        """Scale the carriage pitch."""
        return _errors(state, pitch_scale=self.params.scale)


@register
class TagOffset(Effect):
    """Tag stickers mounted off their nominal centre, in each marker's frame (m)."""

    name = "tag_offset"
    stage = "geometry"

    @dataclass(frozen=True)
    class Params:
        """Mounting offset (x right, y up, z out of the marker)."""

        offset_m: Vec3 = (0.0, 0.0, 0.0)

        def __post_init__(self) -> None:
            require(all(abs(v) < 0.02 for v in self.offset_m), "offset_m: expected |o| < 0.02 m")

    def apply(self, state: VariantState) -> VariantState:
        """Offset the tags on the node."""
        return _errors(state, tag_offset=self.params.offset_m)
