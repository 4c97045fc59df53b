"""Lights of the scene description, renderer-agnostic: placement (rail frame), power, colour."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

from simgap.core.config import require
from simgap.core.rig import load_rig

#: Height (m, rail frame) that lights aim at by default: about the middle of the tag node.
AIM_HEIGHT_M = 0.06


@lru_cache(maxsize=1)
def default_target() -> tuple[float, float, float]:
    """Default aim point (m, rail frame): the rig's turntable centre at :data:`AIM_HEIGHT_M`.

    Read from the rig's transform tree (``links.carriage_to_turntable`` at p = 0), never retyped.
    """
    x, y, _ = load_rig().rail_from_turntable(0.0)[:3, 3]
    return (float(x), float(y), AIM_HEIGHT_M)


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
    target: tuple[float, float, float] = field(default_factory=default_target)
    size: tuple[float, float] = (0.3, 0.3)
    radiance: float = 1.0
    intensity: float = 1.0
    cutoff_deg: float = 30.0
    rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        require(self.radiance >= 0 and self.intensity >= 0, "radiance/intensity: expected >= 0")
        require(0 < self.cutoff_deg < 90, "cutoff_deg: expected 0 < x < 90 (deg)")
