"""The Mitsuba converter: scene description (:mod:`simgap.scene`) -> Mitsuba plugin dictionaries.

The only place that knows Mitsuba's BSDF and emitter plugin names. Every parameter is written
explicitly (Mitsuba's defaults included), so a description renders the same as the template
entry it was read from.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np

from simgap.scene.lights import LightSpec, disc_radiance
from simgap.scene.materials import Coating, Conductor, Diffuse, Material, Plastic, TagPrint

#: Upsampling of the one-texel-per-cell marker texture before bilinear filtering.
BILINEAR_UPSAMPLE = 16
#: 8-bit texture values above this are paper (white), the others ink.
PAPER_THRESHOLD = 127
#: Distance from the aim point of the emitting disk that renders a directional light with an
#: angular diameter (m): the fixture (under 2 m across) then sees its centre within 1e-4 rad
#: of the stated direction everywhere (the sun's disc is 4.7e-3 rad wide), and the disk's
#: vertices (float32, 1e-3 m steps at this distance) keep its angular size to 1e-7.
DISTANT_DISC_M = 1.0e4


def _rough(name: str, alpha: float | None) -> dict[str, Any]:
    """``{"type": "rough<name>", "alpha": a}``, or the smooth ``<name>`` when ``alpha`` is None."""
    return {"type": name} if alpha is None else {"type": f"rough{name}", "alpha": alpha}


def bsdf(material: Material) -> dict[str, Any]:
    """The Mitsuba BSDF dictionary of a fixture material."""
    if isinstance(material, Diffuse):
        return {"type": "diffuse", "reflectance": material.reflectance}
    if isinstance(material, Plastic):
        return {
            **_rough("plastic", material.alpha),
            "diffuse_reflectance": material.diffuse_reflectance,
            "int_ior": material.int_ior,
        }
    if isinstance(material, Conductor):
        return {**_rough("conductor", material.alpha), "material": material.material}
    raise TypeError(f"no Mitsuba BSDF for {type(material).__name__}")


def print_albedo(tag: TagPrint, texture: np.ndarray) -> np.ndarray:
    """The print's albedo texture (float32, rows x columns) that the tag BSDF looks up.

    One texel per cell of the marker (``texture``, uint8): ink where the cell is dark, paper
    where it is light; ``bilinear`` filtering first repeats each cell
    :data:`BILINEAR_UPSAMPLE` times per side, so that only a cell's rim blends.
    """
    if tag.texture_filter == "bilinear":
        texture = np.kron(texture, np.ones((BILINEAR_UPSAMPLE, BILINEAR_UPSAMPLE), texture.dtype))
    return np.where(texture > PAPER_THRESHOLD, tag.paper, tag.ink).astype(np.float32)


def tag_bsdf(tag: TagPrint, albedo: np.ndarray, mi: ModuleType) -> dict[str, Any]:
    """Tag BSDF: the print's albedo texture (:func:`print_albedo`) as a bitmap.

    The bitmap's v is flipped (``to_uv``): a ``rectangle`` maps uv = ((x+1)/2, (y+1)/2) while
    bitmap row 0 is the image's top (docs/conventions.md §4).
    """
    bitmap = {
        "type": "bitmap",
        "bitmap": mi.Bitmap(np.asarray(albedo, np.float32)[..., None]),
        "raw": True,
        "filter_type": tag.texture_filter,
        "to_uv": mi.ScalarTransform4f().translate([0, 1, 0]).scale([1, -1, 1]),
    }
    coating: Coating | None = tag.coating
    if coating is None:
        return {"type": "diffuse", "reflectance": bitmap}
    return {
        **_rough("plastic", coating.alpha),
        "int_ior": coating.int_ior,
        "diffuse_reflectance": bitmap,
    }


def sampling_weight(light: LightSpec) -> float:
    """How often the integrator picks this light: its irradiance at its aim point (W m^-2).

    Mitsuba picks one light per shading point, by default uniformly, and divides by the chance:
    with a key light and a dim ambient environment every other sample looked at the ambient
    and the key's contribution doubled in the others. A pixel's mean then depends on how many
    of its samples chose the key: on flat paper two levels 7.8 % apart at 25 spp, 8 % relative
    noise once a Gaussian pixel filter mixes neighbouring pixels' samples (measured:
    docs/results/design_evidence.md#mitsuba_scene). Picking lights in proportion to the light
    they give removes most of it (Mitsuba's ``sampling_weight``). Constant environment:
    ``pi L``; area light: ``L A / d^2``; point and spot: ``I / d^2`` (``d``: distance to the aim
    point); directional: ``E``.
    """
    tint = float(np.mean(light.rgb))
    if light.type == "constant":
        return max(np.pi * light.radiance * tint, 1e-9)
    if light.type == "directional":
        return max(light.irradiance * tint, 1e-9)
    d2 = float(np.sum((np.asarray(light.position) - np.asarray(light.target)) ** 2))
    area = light.size[0] * light.size[1]
    power = light.radiance * area if light.type == "area" else light.intensity
    return max(power * tint / max(d2, 1e-6), 1e-9)


def light_transform(light: LightSpec, mi: ModuleType):
    """The ``to_world`` of an area or spot light placed in the rail frame.

    ``look_at`` its target; an area light's rectangle is scaled to its size.
    """
    look = mi.ScalarTransform4f().look_at(
        origin=list(light.position), target=list(light.target), up=[0, 0, 1]
    )
    if light.type == "area":
        return look @ mi.ScalarTransform4f().scale([light.size[0] / 2, light.size[1] / 2, 1])
    return look


#: Angular diameter (deg) from which a distant disc is rendered as a sphere rather than a flat
#: disk. Mitsuba samples a disk uniformly by area, which over a wide cone is far from uniform
#: by solid angle (the density at the rim is ``cos(a)^3`` of the centre's: 0.04 for the Earth
#: from low orbit, whose rendered irradiance was then 5 % low at 16 spp); a sphere it samples
#: uniformly in its cone. But the cone's ``1 - cos(a)`` in single precision loses the sun's
#: 0.53 deg disc (0.3 % too bright as a sphere, 0.005 % as a disk; measured on a tag's paper,
#: tests/test_sun.py).
SPHERE_MIN_DIAMETER_DEG = 20.0


def distant_disc(light: LightSpec, mi: ModuleType) -> dict[str, Any]:
    """A directional light with an angular diameter, as an emitting disk or sphere far away.

    Centred :data:`DISTANT_DISC_M` from the light's target along its direction, it fills
    exactly the light's cone as seen from the target, with the uniform radiance
    :func:`~simgap.scene.lights.disc_radiance` that gives ``irradiance`` to a surface facing
    it. The path tracer samples it like any area light, so its shadows have penumbrae of the
    disc's angular width (0.53 deg for the sun: 0.9 mm behind an edge 0.1 m away). A narrow
    one is a one-sided ``disk`` facing the target (radius ``D tan(a)`` for the half-angle
    ``a``), a wide one (:data:`SPHERE_MIN_DIAMETER_DEG`) a ``sphere`` (radius ``D sin(a)``):
    see there why.
    """
    target, towards = np.asarray(light.target, float), light.towards()
    half = np.radians(light.angular_diameter_deg) / 2
    centre = target + DISTANT_DISC_M * towards
    emitting = {
        "emitter": {
            "type": "area",
            "radiance": {
                "type": "rgb",
                "value": np.asarray(light.rgb, float)
                * disc_radiance(light.irradiance, light.angular_diameter_deg),
            },
            "sampling_weight": sampling_weight(light),
        },
    }
    if light.angular_diameter_deg >= SPHERE_MIN_DIAMETER_DEG:
        radius = DISTANT_DISC_M * float(np.sin(half))
        return {"type": "sphere", "center": list(centre), "radius": radius, **emitting}
    up = [0.0, 0.0, 1.0] if abs(towards[2]) < 0.9 else [0.0, 1.0, 0.0]
    radius = DISTANT_DISC_M * float(np.tan(half))
    to_world = mi.ScalarTransform4f().look_at(
        origin=list(centre), target=list(target), up=up
    ) @ mi.ScalarTransform4f().scale([radius, radius, 1.0])
    return {
        "type": "disk",
        "to_world": to_world,
        **emitting,
        "bsdf": {"type": "diffuse", "reflectance": 0.0},
    }


def emitter(light: LightSpec, mi: ModuleType) -> dict[str, Any]:
    """The Mitsuba dictionary of a light (an emitter, or an emitting rectangle for ``area``).

    ``light`` is placed in the rail frame (:meth:`~simgap.scene.lights.LightSpec.placed`); a
    light on the camera is moved with it by :class:`simgap.render.scene.FixtureScene`.
    """
    colour = np.asarray(light.rgb, float)
    weight = sampling_weight(light)
    if light.type == "constant":
        return {
            "type": "constant",
            "radiance": {"type": "rgb", "value": colour * light.radiance},
            "sampling_weight": weight,
        }
    if light.type == "area":
        return {
            "type": "rectangle",
            "to_world": light_transform(light, mi),
            "emitter": {
                "type": "area",
                "radiance": {"type": "rgb", "value": colour * light.radiance},
                "sampling_weight": weight,
            },
            "bsdf": {"type": "diffuse", "reflectance": 0.0},
        }
    if light.type == "directional" and light.angular_diameter_deg > 0:
        return distant_disc(light, mi)
    if light.type == "directional":  # Mitsuba's: the direction the light travels
        return {
            "type": "directional",
            "direction": [float(t - p) for t, p in zip(light.target, light.position, strict=True)],
            "irradiance": {"type": "rgb", "value": colour * light.irradiance},
            "sampling_weight": weight,
        }
    if light.type == "point":
        return {
            "type": "point",
            "position": list(light.position),
            "intensity": {"type": "rgb", "value": colour * light.intensity},
            "sampling_weight": weight,
        }
    return {
        "type": "spot",
        "to_world": light_transform(light, mi),
        "cutoff_angle": light.cutoff_deg,
        "intensity": {"type": "rgb", "value": colour * light.intensity},
        "sampling_weight": weight,
    }
