"""Lights of the scene description, renderer-agnostic: placement (rail frame), power, colour."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Literal

import numpy as np

from simgap.core.config import OMIT_DEFAULT, require
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
    type : {"area", "point", "spot", "constant", "directional"}
        Rectangle area light, isotropic point, spot light, uniform environment, or a distant
        source such as the sun (parallel rays, no fall-off with distance).
    position, target : tuple of float
        Light position and aim point (m, in ``frame``); unused for ``constant``. A directional
        light shines from ``position`` towards ``target``: only their direction counts.
    frame : {"rail", "eyepoint"}
        The rig frame the light is fixed to: ``rail`` (a lab light, still while the carriage
        moves) or ``eyepoint`` (a light on the camera, beside the lens, moving with it; the
        eyepoint frame is the global frame: x right, y forward, z up, metres from the lens).
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
    irradiance : float
        Irradiance of a ``directional`` light on a surface facing it (W m^-2; the sun above the
        atmosphere: 1361).
    """

    type: Literal["area", "point", "spot", "constant", "directional"]
    position: tuple[float, float, float] = (0.0, -0.3, 0.4)
    target: tuple[float, float, float] = field(default_factory=default_target)
    frame: Literal["rail", "eyepoint"] = "rail"
    size: tuple[float, float] = (0.3, 0.3)
    radiance: float = 1.0
    intensity: float = 1.0
    cutoff_deg: float = 30.0
    rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)
    irradiance: float = field(default=0.0, metadata=OMIT_DEFAULT)

    def __post_init__(self) -> None:
        require(self.radiance >= 0 and self.intensity >= 0, "radiance/intensity: expected >= 0")
        require(self.irradiance >= 0, "irradiance: expected >= 0 (W m^-2)")
        require(0 < self.cutoff_deg < 90, "cutoff_deg: expected 0 < x < 90 (deg)")
        require(
            self.type != "directional" or self.frame == "rail",
            "frame: a directional light is distant: expected the rail frame",
        )

    def placed(self, rail_from_frame: np.ndarray) -> LightSpec:
        """The light with its position and target in the rail frame (m), ``frame`` ``rail``.

        ``rail_from_frame`` is the 4x4 pose of the light's frame at the configuration (the
        identity for a rail light).
        """
        if self.frame == "rail":
            return self
        m = np.asarray(rail_from_frame, float)
        position = m[:3, :3] @ np.asarray(self.position) + m[:3, 3]
        target = m[:3, :3] @ np.asarray(self.target) + m[:3, 3]
        return replace(
            self,
            position=tuple(float(v) for v in position),
            target=tuple(float(v) for v in target),
            frame="rail",
        )


#: Quadrature points per side of an area light in :func:`irradiance` (midpoint rule; the
#: error is below 0.1 % for lights farther than their size, as every template light is).
AREA_QUADRATURE = 8
#: Relative luminance of linear sRGB primaries (ITU-R BT.709): the grey level a tinted light gives.
BT709_LUMINANCE = (0.2126, 0.7152, 0.0722)


def irradiance(light: LightSpec, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Direct irradiance a light gives at surface points, without occlusion (W m^-2, luminance).

    What a light meter held at each point would read from this light alone: ``constant``
    environments give ``pi L`` (the whole hemisphere above the surface, unoccluded); ``point``
    ``I cos(t) / d^2``; ``spot`` the same inside its cone (Mitsuba's spot falls off between
    three quarters of the cut-off and the cut-off; linearly here); ``area`` the rectangle's
    ``integral L cos(t_s) cos(t_r) / d^2 dA`` (midpoint rule, :data:`AREA_QUADRATURE` points a
    side; one-sided, emitting towards its target). Shadows and inter-reflections are left out.

    Parameters
    ----------
    light : LightSpec
        The light, placed in the rail frame (:meth:`LightSpec.placed`; m).
    points, normals : ndarray (N, 3)
        Surface points (m, rail frame) and their unit normals.

    Returns
    -------
    ndarray (N,)
        Irradiance weighted by the light's luminance (W m^-2).
    """
    points, normals = np.atleast_2d(points).astype(float), np.atleast_2d(normals).astype(float)
    tint = float(np.dot(light.rgb, BT709_LUMINANCE))
    if light.type == "constant":
        return np.full(len(points), np.pi * light.radiance * tint)
    position, target = np.asarray(light.position, float), np.asarray(light.target, float)
    if light.type == "directional":  # E cos(t) towards the source, whatever the distance
        towards = (position - target) / np.linalg.norm(position - target)
        return light.irradiance * tint * np.clip(normals @ towards, 0.0, None)
    if light.type == "area":
        forward = target - position
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, (0.0, 0.0, 1.0))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        k = (np.arange(AREA_QUADRATURE) + 0.5) / AREA_QUADRATURE - 0.5
        a, b = np.meshgrid(k * light.size[0], k * light.size[1])
        sources = position + a.ravel()[:, None] * right + b.ravel()[:, None] * up  # (Q, 3)
        d = sources[None] - points[:, None]  # (N, Q, 3) from the surface to the light
        dist2 = np.sum(d * d, axis=-1)
        unit = d / np.sqrt(dist2)[..., None]
        cos_r = np.clip(np.einsum("nqk,nk->nq", unit, normals), 0.0, None)
        cos_s = np.clip(-unit @ forward, 0.0, None)
        area = light.size[0] * light.size[1] / AREA_QUADRATURE**2
        return light.radiance * tint * np.sum(cos_r * cos_s / dist2, axis=1) * area
    d = position - points
    dist2 = np.sum(d * d, axis=-1)
    unit = d / np.sqrt(dist2)[:, None]
    out = light.intensity * tint * np.clip(np.sum(unit * normals, axis=-1), 0.0, None) / dist2
    if light.type == "spot":
        axis = (target - position) / np.linalg.norm(target - position)
        angle = np.degrees(np.arccos(np.clip(-unit @ axis, -1.0, 1.0)))
        full = 0.75 * light.cutoff_deg
        out *= np.clip((light.cutoff_deg - angle) / (light.cutoff_deg - full), 0.0, 1.0)
    return out
