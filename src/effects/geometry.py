"""Geometry effects: the real fixture differs from its CAD (rendered; ground truth stays CAD)."""

from __future__ import annotations

import dataclasses

from simgap.effects.base import Effect, EffectParams, RelativeScale, param, within
from simgap.effects.state import VariantState

Vec3 = tuple[float, float, float]
ZERO3: Vec3 = (0.0, 0.0, 0.0)


def _errors(state: VariantState, **changes) -> VariantState:
    errors = dataclasses.replace(state.scene.errors, **changes)
    return dataclasses.replace(state, scene=dataclasses.replace(state.scene, errors=errors))


class CameraMount(Effect, name="camera_mount", stage="geometry"):
    """Camera mount offset on the carriage: translation (m) and rotation vector (rad)."""

    class Params(EffectParams):
        """Mount offset."""

        translation_m: Vec3 = param(ZERO3, "|t| < 0.05 m", within(0.05))
        rotation_rad: Vec3 = param(ZERO3, "|r| < 0.3 rad", within(0.3))

    def apply(self, state: VariantState) -> VariantState:
        """Offset the eyepoint on its link."""
        p = self.params
        return _errors(state, mount_translation=p.translation_m, mount_rotation=p.rotation_rad)


class TurntableOffset(Effect, name="turntable_offset", stage="geometry"):
    """Turntable zero offset: every stop is rotated by ``angle_rad`` (rad, CCW about +Z)."""

    class Params(EffectParams):
        """Zero offset."""

        angle_rad: float = param(0.0, "|a| < 0.5 rad", lambda v: abs(v) < 0.5)

    def apply(self, state: VariantState) -> VariantState:
        """Offset the turntable zero."""
        return _errors(state, turntable_zero=self.params.angle_rad)


class CarriagePitch(Effect, name="carriage_pitch", stage="geometry"):
    """Carriage pin pitch differs from the rig's (``links.pin_pitch``) by a relative ``scale``.

    ``scale`` is dimensionless: 0.01 = +1 %.
    """

    Params = RelativeScale

    def apply(self, state: VariantState) -> VariantState:
        """Scale the carriage pitch."""
        return _errors(state, pitch_scale=self.params.scale)


class TagOffset(Effect, name="tag_offset", stage="geometry"):
    """Tag stickers mounted off their nominal centre, in each marker's frame (m)."""

    class Params(EffectParams):
        """Mounting offset (x right, y up, z out of the marker)."""

        offset_m: Vec3 = param(ZERO3, "|o| < 0.02 m", within(0.02))

    def apply(self, state: VariantState) -> VariantState:
        """Offset the tags on the node."""
        return _errors(state, tag_offset=self.params.offset_m)
