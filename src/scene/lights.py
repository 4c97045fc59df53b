"""Lights of the scene description, renderer-agnostic: placement (rail frame), power, colour."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Literal

import numpy as np

from simgap.core.config import OMIT_DEFAULT, require
from simgap.core.rig import load_rig
from simgap.core.transforms import perpendicular_axes

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
    angular_diameter_deg : float
        Angular diameter of a ``directional`` light's disc as seen from the fixture (deg): 0 is
        a point-like source of parallel rays (sharp shadows); the sun is 0.53, the Earth from
        low orbit about 140. A disc of uniform radiance :func:`disc_radiance`, so that a
        surface facing it receives ``irradiance``; it casts penumbrae of its own width.
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
    angular_diameter_deg: float = field(default=0.0, metadata=OMIT_DEFAULT)

    def __post_init__(self) -> None:
        require(self.radiance >= 0 and self.intensity >= 0, "radiance/intensity: expected >= 0")
        require(self.irradiance >= 0, "irradiance: expected >= 0 (W m^-2)")
        require(
            0 <= self.angular_diameter_deg < MAX_DISC_DIAMETER_DEG,
            f"angular_diameter_deg: expected 0 <= x < {MAX_DISC_DIAMETER_DEG:g} (deg)",
        )
        require(
            self.angular_diameter_deg == 0 or self.type == "directional",
            "angular_diameter_deg: only a directional light has a disc",
        )
        require(0 < self.cutoff_deg < 90, "cutoff_deg: expected 0 < x < 90 (deg)")
        require(
            self.type != "directional" or self.frame == "rail",
            "frame: a directional light is distant: expected the rail frame",
        )

    def towards(self) -> np.ndarray:
        """Unit vector from the light's target towards its position (rail frame if placed)."""
        d = np.asarray(self.position, float) - np.asarray(self.target, float)
        return d / np.linalg.norm(d)

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


#: Largest angular diameter of a distant disc (deg): beyond it the disc would be a hemisphere.
MAX_DISC_DIAMETER_DEG = 179.0


def disc_radiance(irradiance_w_m2: float, angular_diameter_deg: float) -> float:
    """Radiance of a uniform disc that gives ``irradiance_w_m2`` to a surface facing it.

    A uniform source of radiance ``L`` filling a cone of half-angle ``a`` about a surface's
    normal gives it ``pi L sin(a)^2`` (W m^-2; the irradiance of a spherical or disc source,
    e.g. Modest, *Radiative Heat Transfer*, 3rd ed., 2013, view factor of a disc), so
    ``L = E / (pi sin(a)^2)`` (W m^-2 sr^-1).
    """
    half = np.radians(angular_diameter_deg) / 2
    return float(irradiance_w_m2 / (np.pi * np.sin(half) ** 2))


#: Rings and azimuths of the quadrature over a disc's directions in :func:`irradiance`, used
#: where part of the disc lies below a surface's horizon (elsewhere the cosine law is exact).
DISC_QUADRATURE = (48, 96)


def _disc_cosine(light: LightSpec, towards: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """The mean of ``max(cos, 0)`` over a directional light's disc, per normal (N,).

    While the whole disc is above a surface's horizon its irradiance is ``E cos(t)``
    (``t``: the angle between the normal and the disc's centre), exactly: the integral of a
    cosine over a symmetric cone is the cosine of its axis times the cone's projected solid
    angle. Where the horizon cuts the disc the mean of the clipped cosine is integrated over
    the disc's solid angle (midpoint rule in the cosine of the angle from the centre and in
    azimuth, :data:`DISC_QUADRATURE`).
    """
    cos_t = normals @ towards
    half = np.radians(light.angular_diameter_deg) / 2
    if half == 0:
        return np.clip(cos_t, 0.0, None)
    rings, azimuths = DISC_QUADRATURE
    u = 1 - (1 - np.cos(half)) * (np.arange(rings) + 0.5) / rings  # cos of the angle from centre
    phi = 2 * np.pi * (np.arange(azimuths) + 0.5) / azimuths
    e1, e2 = perpendicular_axes(towards)
    sin_u = np.sqrt(1 - u**2)
    dirs = (
        u[:, None, None] * towards
        + (sin_u[:, None] * np.cos(phi))[..., None] * e1
        + (sin_u[:, None] * np.sin(phi))[..., None] * e2
    ).reshape(-1, 3)  # equal solid angles
    clipped = np.clip(normals @ dirs.T, 0.0, None).mean(axis=1)
    # the cone's projected solid angle over its solid angle: E cos(t) is pi L sin^2 * cos(t)
    projected = np.pi * np.sin(half) ** 2 / (2 * np.pi * (1 - np.cos(half)))
    whole = cos_t >= np.sin(half)  # the disc's rim stays above the horizon
    return np.where(whole, cos_t, clipped / projected)


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
    side; one-sided, emitting towards its target); ``directional`` ``E cos(t)``, a disc's part
    below the horizon left out (:func:`_disc_cosine`). Shadows and inter-reflections are left
    out.

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
    if light.type == "directional":  # E cos(t) towards the source, whatever the distance
        return light.irradiance * tint * _disc_cosine(light, light.towards(), normals)
    position, target = np.asarray(light.position, float), np.asarray(light.target, float)
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


def lights_irradiance(
    lights: Iterable[LightSpec],
    points: np.ndarray,
    normals: np.ndarray,
    rail_from_eyepoint: np.ndarray | None = None,
) -> np.ndarray:
    """Direct irradiance of several lights at surface points, summed (W m^-2, luminance).

    Each light as :func:`irradiance` reads it (shadows and inter-reflections left out); a light
    on the camera (``frame`` ``eyepoint``) is placed at each point's configuration first
    (:meth:`LightSpec.placed`).

    Parameters
    ----------
    lights : iterable of LightSpec
        The lights (a scene's ``lights.values()``).
    points, normals : ndarray (N, 3)
        Surface points (m, rail frame) and their unit normals.
    rail_from_eyepoint : ndarray (N, 4, 4), optional
        The camera's pose at each point's configuration (m); needed only where a light is on
        the camera.

    Returns
    -------
    ndarray (N,)
        Summed irradiance (W m^-2).
    """
    points, normals = np.atleast_2d(points).astype(float), np.atleast_2d(normals).astype(float)
    total = np.zeros(len(points))
    for light in lights:
        if light.frame == "rail":
            total += irradiance(light, points, normals)
            continue
        if rail_from_eyepoint is None:
            raise ValueError("lights_irradiance: a light on the camera needs rail_from_eyepoint")
        for i, m in enumerate(rail_from_eyepoint):
            total[i] += irradiance(light.placed(m), points[i : i + 1], normals[i : i + 1])[0]
    return total
