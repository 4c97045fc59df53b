"""Scene-stage effects: lights, materials, optics and the true camera (each needs a re-render)."""

from __future__ import annotations

import dataclasses
from typing import Literal

import colour
import numpy as np

from simgap.core.rig import CameraModel
from simgap.effects.base import Check, Effect, EffectParams, RelativeScale, param
from simgap.effects.state import RenderQuality, VariantState
from simgap.scene.lights import BT709_LUMINANCE, LightSpec, default_target
from simgap.scene.materials import Coating, Conductor, Diffuse, Plastic
from simgap.scene.spec import TABLE_TOP_Z_M, Ground, SceneSpec

Vec3 = tuple[float, float, float]
#: Conductor name of bare aluminium (Mitsuba's table of measured metals).
ALUMINIUM = "Al"


def cct_to_rgb(cct_k: float | None) -> tuple[float, float, float]:
    """Linear sRGB colour of a blackbody-like source of correlated colour temperature ``cct_k`` (K).

    Uses colour-science (CIE daylight/Planckian locus via ``CCT_to_xy``) and normalises to unit
    luminance; ``None`` gives white (1, 1, 1).
    """
    if cct_k is None:
        return (1.0, 1.0, 1.0)
    xy = colour.temperature.CCT_to_xy(float(cct_k), method="Kang 2002")
    rgb = colour.XYZ_to_sRGB(colour.xy_to_XYZ(xy), apply_cctf_encoding=False)
    rgb = np.clip(rgb, 0.0, None)
    rgb = rgb / float(np.dot(rgb, BT709_LUMINANCE))
    return tuple(float(v) for v in rgb)


def _scene(state: VariantState, **changes) -> VariantState:
    """``state`` with fields of its scene stage replaced."""
    return dataclasses.replace(state, scene=dataclasses.replace(state.scene, **changes))


def _spec(state: VariantState, spec: SceneSpec) -> VariantState:
    """``state`` with another scene description."""
    return _scene(state, spec=spec)


class Lighting(Effect, name="lighting", stage="scene"):
    """The key light: type, placement, power and colour temperature (rail frame, m).

    ``power``: radiance (W m^-2 sr^-1) for ``area``, intensity (W sr^-1) for ``point``/``spot``.
    """

    class Params(EffectParams):
        """Key light parameters."""

        type: Literal["area", "point", "spot"] = "area"
        position: Vec3 = (0.12, -0.30, 0.40)
        target: Vec3 = param(factory=default_target)
        size_m: tuple[float, float] = (0.30, 0.30)
        power: float = param(8.0, ">= 0", lambda v: v >= 0)
        cct_k: float | None = param(None, "1000..25000 K", lambda v: v is None or 1e3 <= v <= 25e3)
        cutoff_deg: float = 30.0

    def apply(self, state: VariantState) -> VariantState:
        """Replace the scene's ``key`` light."""
        p = self.params
        light = LightSpec(
            type=p.type,
            position=p.position,
            target=p.target,
            size=p.size_m,
            radiance=p.power,
            intensity=p.power,
            cutoff_deg=p.cutoff_deg,
            rgb=cct_to_rgb(p.cct_k),
        )
        return _spec(state, state.scene.spec.with_light("key", light))


class CameraLight(Effect, name="camera_light", stage="scene"):
    """A small light on the camera beside the lens (an LED or ring light), moving with it.

    An isotropic point light fixed to the eyepoint frame at ``offset_m`` (x right, z up of the
    lens, m) with radiant intensity ``intensity`` (W sr^-1) and colour temperature ``cct_k``.
    Near the optical axis it lights frontal tags head-on, so a glossy laminate mirrors it
    straight into the lens (highlights, lost detections) where a lab light seldom does. For
    scale: 0.24 W sr^-1 gives a tag 0.45 m away the template key light's irradiance at the node
    (1.16 W m^-2, :func:`simgap.scene.lights.irradiance`).
    """

    class Params(EffectParams):
        """Placement beside the lens and intensity."""

        offset_m: tuple[float, float] = param(
            (0.03, 0.0), "|x|, |z| < 0.3 m", lambda v: max(abs(v[0]), abs(v[1])) < 0.3
        )
        intensity: float = param(0.24, ">= 0 W/sr", lambda v: v >= 0)
        cct_k: float | None = param(None, "1000..25000 K", lambda v: v is None or 1e3 <= v <= 25e3)

    def apply(self, state: VariantState) -> VariantState:
        """Add (or replace) the scene's ``camera`` light."""
        p = self.params
        light = LightSpec(
            type="point",
            position=(float(p.offset_m[0]), 0.0, float(p.offset_m[1])),
            target=(0.0, 1.0, 0.0),
            frame="eyepoint",
            intensity=p.intensity,
            rgb=cct_to_rgb(p.cct_k),
        )
        return _spec(state, state.scene.spec.with_light("camera", light))


#: The solar constant: the sun's irradiance above the atmosphere at 1 AU (W m^-2; Kopp & Lean,
#: "A new, lower value of total solar irradiance", Geophys. Res. Lett. 38, L01706, 2011).
SOLAR_CONSTANT_W_M2 = 1361.0
#: The sun's mean angular diameter from 1 AU (deg): 1.3927e6 km at 1.496e8 km (NASA Sun Fact
#: Sheet, nssdc.gsfc.nasa.gov/planetary/factsheet/sunfact.html).
SUN_ANGULAR_DIAMETER_DEG = 0.533
#: The Earth's mean radius (km; NASA Earth Fact Sheet, volumetric mean radius 6371.0 km).
EARTH_RADIUS_KM = 6371.0
#: The Earth's Bond albedo (dimensionless; 0.29-0.30 from CERES, Stephens et al., "The albedo
#: of Earth", Rev. Geophys. 53, 141, 2015).
EARTH_ALBEDO = 0.30
#: Lunar regolith's albedo (dimensionless; the Moon's geometric albedo 0.12, Bond 0.11, NASA
#: Moon Fact Sheet; maria about 0.07, highlands up to 0.2, Heiken et al., *Lunar Sourcebook*,
#: 1991, ch. 9).
REGOLITH_ALBEDO = 0.12


class Sun(Effect, name="sun", stage="scene"):
    """The sun: a distant light of parallel rays from a direction, at an irradiance (W m^-2).

    The direction points from the fixture towards the sun, as ``azimuth_deg`` from the rail
    frame's +Y (along the rail, towards the node) turning towards +X, and ``elevation_deg`` above
    its XY plane (the table). ``irradiance_w_m2`` is what a surface facing the sun receives (in
    orbit the solar constant, 1361). The rays are parallel (Mitsuba's ``directional`` emitter):
    the sun's 0.53 deg disc is left out, so shadow edges are sharp; the fixture's own geometry
    casts them. A surface at angle ``t`` to the rays receives ``E cos(t)``
    (:func:`simgap.scene.lights.irradiance`). The sun's disc is ``angular_diameter_deg``
    wide (0.533 from 1 AU; 0 for parallel rays and perfectly sharp shadows): its shadows have
    penumbrae of that width, about 0.9 mm behind an edge 0.1 m away. Black sky and a camera
    that meters the sunlit scene are other effects (``black_sky``, ``auto_exposure``).
    """

    class Params(EffectParams):
        """Direction (deg, rail frame), irradiance (W m^-2), disc size (deg) and colour."""

        azimuth_deg: float = param(0.0, "-360..360 deg", lambda v: -360 <= v <= 360)
        elevation_deg: float = param(30.0, "-90..90 deg", lambda v: -90 <= v <= 90)
        irradiance_w_m2: float = param(SOLAR_CONSTANT_W_M2, ">= 0 W/m^2", lambda v: v >= 0)
        angular_diameter_deg: float = param(
            SUN_ANGULAR_DIAMETER_DEG, "0..10 deg", lambda v: 0 <= v <= 10
        )
        cct_k: float | None = param(
            5772.0, "1000..25000 K", lambda v: v is None or 1e3 <= v <= 25e3
        )

    def apply(self, state: VariantState) -> VariantState:
        """Add (or replace) the scene's ``sun`` light."""
        p = self.params
        light = distant_light(
            p.azimuth_deg, p.elevation_deg, p.irradiance_w_m2, p.angular_diameter_deg, p.cct_k
        )
        return _spec(state, state.scene.spec.with_light("sun", light))


def distant_light(
    azimuth_deg: float,
    elevation_deg: float,
    irradiance_w_m2: float,
    angular_diameter_deg: float,
    cct_k: float | None,
) -> LightSpec:
    """A distant disc (or parallel rays, diameter 0) towards a direction of the rail frame.

    Direction as in :class:`Sun`; ``irradiance_w_m2`` on a surface facing its centre.
    """
    return LightSpec(
        type="directional",
        position=tuple(float(v) for v in sun_direction(azimuth_deg, elevation_deg)),
        target=(0.0, 0.0, 0.0),
        irradiance=irradiance_w_m2,
        angular_diameter_deg=angular_diameter_deg,
        rgb=cct_to_rgb(cct_k),
    )


class Earthshine(Effect, name="earthshine", stage="scene"):
    """The sunlit Earth seen from orbit: a large Lambertian disc of reflected sunlight.

    From ``altitude_km`` the Earth fills a cone of half-angle ``asin(R / (R + h))`` (R =
    6371 km: 70.2 deg at 400 km) towards ``azimuth_deg`` / ``elevation_deg`` (rail frame, as
    :class:`Sun`; -90 is straight down). Its radiance is that of a Lambertian reflector of
    ``albedo`` under the sun, ``albedo E / pi``, times the ``lit_fraction`` of the visible disc
    in daylight (a crescent averaged over the disc). A surface facing the Earth receives
    ``pi L sin(a)^2`` (:func:`simgap.scene.lights.disc_radiance`): 361 W m^-2 at 400 km,
    fully lit. The path tracer samples the disc like any area light; the table, if still
    there, shades it from below (``black_sky`` removes it).
    """

    class Params(EffectParams):
        """Direction (deg, rail frame), altitude (km), albedo, lit share and sunlight."""

        azimuth_deg: float = param(0.0, "-360..360 deg", lambda v: -360 <= v <= 360)
        elevation_deg: float = param(-90.0, "-90..90 deg", lambda v: -90 <= v <= 90)
        altitude_km: float = param(400.0, "100..400000 km", lambda v: 100 <= v <= 4e5)
        albedo: float = param(EARTH_ALBEDO, "0..1", lambda v: 0 <= v <= 1)
        lit_fraction: float = param(1.0, "0..1", lambda v: 0 <= v <= 1)
        solar_irradiance_w_m2: float = param(SOLAR_CONSTANT_W_M2, ">= 0 W/m^2", lambda v: v >= 0)
        cct_k: float | None = param(None, "1000..25000 K", lambda v: v is None or 1e3 <= v <= 25e3)

    def apply(self, state: VariantState) -> VariantState:
        """Add (or replace) the scene's ``earth`` light."""
        p = self.params
        sin_half = EARTH_RADIUS_KM / (EARTH_RADIUS_KM + p.altitude_km)
        diameter = 2 * float(np.degrees(np.arcsin(sin_half)))
        facing = p.lit_fraction * p.albedo * p.solar_irradiance_w_m2 * sin_half**2
        light = distant_light(p.azimuth_deg, p.elevation_deg, facing, diameter, p.cct_k)
        return _spec(state, state.scene.spec.with_light("earth", light))


#: The lab's own lights of the scene template (the key light and the room's ambient
#: environment) and its room (the table with its backdrop wall).
LAB_LIGHTS = ("key", "ambient")
LAB_OBJECTS = ("table",)


class BlackSky(Effect, name="black_sky", stage="scene"):
    """Space around the fixture: no room light and no room.

    Removes the lab's key light and ambient environment (:data:`LAB_LIGHTS`), so that only
    the lights other effects add remain (``sun``, ``earthshine``, ``camera_light``), and the
    table with its backdrop (:data:`LAB_OBJECTS`) unless ``keep_table``: the camera sees black
    behind the fixture, and the fixture shades only itself.
    """

    class Params(EffectParams):
        """Whether the table and its backdrop stay."""

        keep_table: bool = False

    def apply(self, state: VariantState) -> VariantState:
        """Remove the lab's lights (and its table)."""
        spec = state.scene.spec.without_lights(*LAB_LIGHTS)
        if not self.params.keep_table:
            spec = spec.without_objects(*LAB_OBJECTS)
        return _spec(state, spec)


class Regolith(Effect, name="regolith", stage="scene"):
    """A planetary surface under the fixture: a Lambertian ground of regolith's albedo.

    Replaces the table and its backdrop (:data:`LAB_OBJECTS`) by a square ground ``size_m``
    across at the table top's height (:data:`simgap.scene.spec.TABLE_TOP_Z_M`: the rail
    stands on it), of diffuse ``albedo`` (0.12, the Moon's; maria 0.07, highlands 0.2). Under
    a low sun its bounce lights the tags' lower edges and fills the fixture's shadows; the
    path tracer needs ``max_depth`` 3 or more for it (the template's 3).
    """

    class Params(EffectParams):
        """Albedo and extent of the ground."""

        albedo: float = param(REGOLITH_ALBEDO, "0..1", lambda v: 0 <= v <= 1)
        size_m: float = param(200.0, "1..10000 m", lambda v: 1 <= v <= 1e4)

    def apply(self, state: VariantState) -> VariantState:
        """Replace the table by the ground."""
        ground = Ground(height_m=TABLE_TOP_Z_M, size_m=self.params.size_m,
                        reflectance=self.params.albedo)  # fmt: skip
        spec = state.scene.spec.without_objects(*LAB_OBJECTS).with_ground(ground)
        return _spec(state, spec)


def sun_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit vector towards the sun in the rail frame (see :class:`Sun`)."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])


def sun_angles(direction) -> tuple[float, float]:
    """Azimuth in [0, 360) and elevation (deg) of a unit vector: :func:`sun_direction` inverted.

    Rounded to 1e-9 deg, so that a grid's values come back as they were given.
    """
    x, y, z = (float(v) for v in direction)
    azimuth = round(float(np.degrees(np.arctan2(x, y))), 9) % 360.0
    return azimuth, round(float(np.degrees(np.arcsin(np.clip(z, -1.0, 1.0)))), 9)


class Ambient(Effect, name="ambient", stage="scene"):
    """Uniform environment light (room ambient): radiance (W m^-2 sr^-1) and colour temperature."""

    class Params(EffectParams):
        """Ambient light parameters."""

        radiance: float = param(0.15, ">= 0", lambda v: v >= 0)
        cct_k: float | None = None

    def apply(self, state: VariantState) -> VariantState:
        """Set the scene's ``ambient`` light (a uniform environment)."""
        spec = state.scene.spec
        old = spec.lights.get("ambient", LightSpec("constant"))
        light = dataclasses.replace(
            old, type="constant", radiance=self.params.radiance, rgb=cct_to_rgb(self.params.cct_k)
        )
        return _spec(state, spec.with_light("ambient", light))


class TagMaterial(Effect, name="tag_material", stage="scene"):
    """Matte printed tag: diffuse albedo of the ink and of the paper (dimensionless, linear)."""

    class Params(EffectParams):
        """Ink and paper albedo."""

        ink: float = 0.03
        paper: float = 0.80
        checks = (Check("ink/paper", "0 <= ink < paper <= 1", lambda p: 0 <= p.ink < p.paper <= 1),)

    def apply(self, state: VariantState) -> VariantState:
        """Set ink and paper albedo, keeping the print's coating and texture filter."""
        spec = state.scene.spec
        tag = dataclasses.replace(spec.tag, ink=self.params.ink, paper=self.params.paper)
        return _spec(state, spec.with_tag(tag))


class TagGloss(Effect, name="tag_gloss", stage="scene"):
    """Laminated tag: a rough dielectric coating over the print.

    ``alpha`` is the microfacet roughness (dimensionless); ``int_ior`` the laminate's refractive
    index.
    """

    class Params(EffectParams):
        """Laminate parameters."""

        alpha: float = param(0.08, "0 < alpha <= 1", lambda v: 0 < v <= 1)
        int_ior: float = param(1.49, "1 < int_ior < 3", lambda v: 1 < v < 3)

    def apply(self, state: VariantState) -> VariantState:
        """Laminate the tag print (ink, paper and texture filter kept)."""
        spec = state.scene.spec
        coating = Coating(alpha=self.params.alpha, int_ior=self.params.int_ior)
        return _spec(state, spec.with_tag(dataclasses.replace(spec.tag, coating=coating)))


class FixtureMaterial(Effect, name="fixture_material", stage="scene"):
    """Material of one fixture part (a material slot of the scene template).

    ``bare``: rough aluminium (a conductor of roughness ``alpha``); ``anodised``: rough plastic
    of base albedo ``reflectance``; ``painted``: diffuse paint of albedo ``reflectance``.
    """

    class Params(EffectParams):
        """Material slot and finish."""

        slot: Literal["node", "aluminium", "turntable", "table", "camera"] = "node"
        finish: Literal["bare", "anodised", "painted"] = "painted"
        reflectance: float = param(0.45, "0..1", lambda v: 0 <= v <= 1)
        alpha: float = param(0.25, "0 < alpha <= 1", lambda v: 0 < v <= 1)

    def apply(self, state: VariantState) -> VariantState:
        """Replace the slot's material."""
        p = self.params
        material = {
            "bare": Conductor(material=ALUMINIUM, alpha=p.alpha),
            "anodised": Plastic(diffuse_reflectance=p.reflectance, alpha=p.alpha),
            "painted": Diffuse(reflectance=p.reflectance),
        }[p.finish]
        return _spec(state, state.scene.spec.with_material(p.slot, material))


class Defocus(Effect, name="defocus", stage="scene"):
    """Thin-lens depth of field: aperture radius (m) and in-focus distance (m).

    The D435i RGB lens (f ~ 1.9 mm, f/2) has an aperture radius of ~0.5 mm.
    """

    class Params(EffectParams):
        """Thin lens parameters."""

        aperture_radius_m: float = param(0.0005, "0..0.01 m", lambda v: 0 <= v < 0.01)
        focus_distance_m: float = param(1.0, "> 0.05 m", lambda v: v > 0.05)

    def apply(self, state: VariantState) -> VariantState:
        """Set the thin lens."""
        return _scene(
            state,
            aperture_radius_m=self.params.aperture_radius_m,
            focus_distance_m=self.params.focus_distance_m,
        )


class TagScale(Effect, name="tag_scale", stage="scene"):
    """Tags printed at a different size than nominal: relative scale error (e.g. 0.01 = +1 %)."""

    Params = RelativeScale

    def apply(self, state: VariantState) -> VariantState:
        """Scale the printed stickers."""
        return _scene(state, tag_scale=state.scene.tag_scale * (1.0 + self.params.scale))


class SamplingQuality(Effect, name="render_quality", stage="scene"):
    """Renderer quality: samples per pixel, sampler, maximum path depth and render mode.

    Every parameter not given takes its default here, not the experiment's: ``render_quality:
    {spp: 64}`` path traces at 64 spp whatever the experiment's ``render.mode``.
    """

    class Params(EffectParams):
        """Integrator and sampling settings."""

        spp: int = param(16, "an integer >= 1", lambda v: v >= 1)
        sampler: Literal["multijitter", "ldsampler", "stratified", "independent", "orthogonal"] = (
            "multijitter"
        )
        max_depth: int = param(3, ">= 2 or -1", lambda v: v >= 2 or v == -1)
        mode: Literal["path", "converged"] = "path"

    def apply(self, state: VariantState) -> VariantState:
        """Set render quality."""
        p = self.params
        return _scene(state, quality=RenderQuality(p.spp, p.sampler, p.max_depth, p.mode))


class LensDistortion(Effect, name="lens_distortion", stage="scene"):
    """Distortion of the true lens: its k1, k2, p1, p2, k3 (dimensionless; :meth:`apply`).

    Rendered exactly per ray by the OpenCV sensor (no resampling, no black borders). With
    ``calibrated: true`` the estimator's calibration knows the coefficients too.
    """

    class Params(EffectParams):
        """Distortion coefficients."""

        k1: float = param(0.0, "|k| < 2", lambda v: abs(v) < 2, key="k1/k2/k3")
        k2: float = param(0.0, "|k| < 2", lambda v: abs(v) < 2, key="k1/k2/k3")
        p1: float = param(0.0, "|p| < 0.1", lambda v: abs(v) < 0.1, key="p1/p2")
        p2: float = param(0.0, "|p| < 0.1", lambda v: abs(v) < 0.1, key="p1/p2")
        k3: float = param(0.0, "|k| < 2", lambda v: abs(v) < 2, key="k1/k2/k3")
        calibrated: bool = False

    def apply(self, state: VariantState) -> VariantState:
        """Distort the true camera (and the calibration when calibrated).

        The coefficients replace the camera model's own of the same names; a richer model
        (rational, thin prism, tilted) keeps its others, and a fisheye (``equidistant``) takes
        ``k1``-``k3`` as its own (its ``p1``, ``p2`` must be 0).
        """
        p = self.params
        camera = _with_lens(state.scene.camera, p)
        out = _scene(state, camera=camera)
        if p.calibrated:
            est = out.estimation
            cal = est.calibration.replace(
                distortion=camera.distortion, distortion_model=camera.distortion_model
            )
            out = dataclasses.replace(out, estimation=dataclasses.replace(est, calibration=cal))
        return out


def _with_lens(camera: CameraModel, p: LensDistortion.Params) -> CameraModel:
    """``camera`` whose lens has the coefficients of ``p`` (see :meth:`LensDistortion.apply`)."""
    coeffs = list(camera.distortion)
    if camera.is_fisheye:
        if p.p1 or p.p2:
            raise ValueError(
                "lens_distortion: p1/p2: expected 0 on a fisheye (equidistant) camera, whose "
                f"model has no tangential terms, got {p.p1:g}, {p.p2:g}"
            )
        coeffs[:3] = (p.k1, p.k2, p.k3)
    else:
        coeffs[:5] = (p.k1, p.k2, p.p1, p.p2, p.k3)
    return camera.replace(distortion=tuple(coeffs))


class FocalLength(Effect, name="focal_length", stage="scene"):
    """The true focal length differs from the calibration by a relative ``scale`` (0.02 = +2 %)."""

    Params = RelativeScale

    def apply(self, state: VariantState) -> VariantState:
        """Scale the true camera's fx, fy."""
        cam = state.scene.camera
        s = 1.0 + self.params.scale
        return _scene(state, camera=cam.replace(fx=cam.fx * s, fy=cam.fy * s))


class PrincipalPoint(Effect, name="principal_point", stage="scene"):
    """The true principal point is offset from the calibration's by (dx_px, dy_px) (px)."""

    class Params(EffectParams):
        """Principal point offset."""

        dx_px: float = param(0.0, "|d| < 200 px", lambda v: abs(v) < 200, key="dx_px/dy_px")
        dy_px: float = param(0.0, "|d| < 200 px", lambda v: abs(v) < 200, key="dx_px/dy_px")

    def apply(self, state: VariantState) -> VariantState:
        """Move the true camera's principal point."""
        cam = state.scene.camera
        return _scene(
            state, camera=cam.replace(cx=cam.cx + self.params.dx_px, cy=cam.cy + self.params.dy_px)
        )
