"""Scene-stage effects: lights, materials, optics and the true camera (each needs a re-render)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

import colour
import numpy as np

from simgap.core.config import require
from simgap.effects.base import Effect, RelativeScale, register
from simgap.effects.state import RenderQuality, VariantState
from simgap.scene.lights import LightSpec, default_target
from simgap.scene.materials import Coating, Conductor, Diffuse, Plastic
from simgap.scene.spec import SceneSpec

Vec3 = tuple[float, float, float]
#: Conductor name of bare aluminium (Mitsuba's table of measured metals).
ALUMINIUM = "Al"
#: Relative luminance of linear sRGB primaries (ITU-R BT.709).
BT709_LUMINANCE = (0.2126, 0.7152, 0.0722)


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


@register
class Lighting(Effect):
    """The key light: type, placement, power and colour temperature (rail frame, m).

    ``power``: radiance (W m^-2 sr^-1) for ``area``, intensity (W sr^-1) for ``point``/``spot``.
    """

    name = "lighting"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Key light parameters."""

        type: Literal["area", "point", "spot"] = "area"
        position: Vec3 = (0.12, -0.30, 0.40)
        target: Vec3 = field(default_factory=default_target)
        size_m: tuple[float, float] = (0.30, 0.30)
        power: float = 8.0
        cct_k: float | None = None
        cutoff_deg: float = 30.0

        def __post_init__(self) -> None:
            require(self.power >= 0, "power: expected >= 0")
            require(
                self.cct_k is None or 1000 <= self.cct_k <= 25000, "cct_k: expected 1000..25000 K"
            )

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


@register
class Ambient(Effect):
    """Uniform environment light (room ambient): radiance (W m^-2 sr^-1) and colour temperature."""

    name = "ambient"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Ambient light parameters."""

        radiance: float = 0.15
        cct_k: float | None = None

        def __post_init__(self) -> None:
            require(self.radiance >= 0, "radiance: expected >= 0")

    def apply(self, state: VariantState) -> VariantState:
        """Set the scene's ``ambient`` light (a uniform environment)."""
        spec = state.scene.spec
        old = spec.lights.get("ambient", LightSpec("constant"))
        light = dataclasses.replace(
            old, type="constant", radiance=self.params.radiance, rgb=cct_to_rgb(self.params.cct_k)
        )
        return _spec(state, spec.with_light("ambient", light))


@register
class TagMaterial(Effect):
    """Matte printed tag: diffuse albedo of the ink and of the paper (dimensionless, linear)."""

    name = "tag_material"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Ink and paper albedo."""

        ink: float = 0.03
        paper: float = 0.80

        def __post_init__(self) -> None:
            require(0 <= self.ink < self.paper <= 1, "ink/paper: expected 0 <= ink < paper <= 1")

    def apply(self, state: VariantState) -> VariantState:
        """Set ink and paper albedo, keeping the print's coating and texture filter."""
        spec = state.scene.spec
        tag = dataclasses.replace(spec.tag, ink=self.params.ink, paper=self.params.paper)
        return _spec(state, spec.with_tag(tag))


@register
class TagGloss(Effect):
    """Laminated tag: a rough dielectric coating over the print.

    ``alpha`` is the microfacet roughness (dimensionless); ``int_ior`` the laminate's refractive
    index.
    """

    name = "tag_gloss"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Laminate parameters."""

        alpha: float = 0.08
        int_ior: float = 1.49

        def __post_init__(self) -> None:
            require(0 < self.alpha <= 1, "alpha: expected 0 < alpha <= 1")
            require(1 < self.int_ior < 3, "int_ior: expected 1 < int_ior < 3")

    def apply(self, state: VariantState) -> VariantState:
        """Laminate the tag print (ink, paper and texture filter kept)."""
        spec = state.scene.spec
        coating = Coating(alpha=self.params.alpha, int_ior=self.params.int_ior)
        return _spec(state, spec.with_tag(dataclasses.replace(spec.tag, coating=coating)))


@register
class FixtureMaterial(Effect):
    """Material of one fixture part (a material slot of the scene template).

    ``bare``: rough aluminium (a conductor of roughness ``alpha``); ``anodised``: rough plastic
    of base albedo ``reflectance``; ``painted``: diffuse paint of albedo ``reflectance``.
    """

    name = "fixture_material"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Material slot and finish."""

        slot: Literal["node", "aluminium", "turntable", "table", "camera"] = "node"
        finish: Literal["bare", "anodised", "painted"] = "painted"
        reflectance: float = 0.45
        alpha: float = 0.25

        def __post_init__(self) -> None:
            require(0 <= self.reflectance <= 1, "reflectance: expected 0..1")
            require(0 < self.alpha <= 1, "alpha: expected 0 < alpha <= 1")

    def apply(self, state: VariantState) -> VariantState:
        """Replace the slot's material."""
        p = self.params
        material = {
            "bare": Conductor(material=ALUMINIUM, alpha=p.alpha),
            "anodised": Plastic(diffuse_reflectance=p.reflectance, alpha=p.alpha),
            "painted": Diffuse(reflectance=p.reflectance),
        }[p.finish]
        return _spec(state, state.scene.spec.with_material(p.slot, material))


@register
class Defocus(Effect):
    """Thin-lens depth of field: aperture radius (m) and in-focus distance (m).

    The D435i RGB lens (f ~ 1.9 mm, f/2) has an aperture radius of ~0.5 mm.
    """

    name = "defocus"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Thin lens parameters."""

        aperture_radius_m: float = 0.0005
        focus_distance_m: float = 1.0

        def __post_init__(self) -> None:
            require(0 <= self.aperture_radius_m < 0.01, "aperture_radius_m: expected 0..0.01 m")
            require(self.focus_distance_m > 0.05, "focus_distance_m: expected > 0.05 m")

    def apply(self, state: VariantState) -> VariantState:
        """Set the thin lens."""
        return _scene(
            state,
            aperture_radius_m=self.params.aperture_radius_m,
            focus_distance_m=self.params.focus_distance_m,
        )


@register
class TagScale(Effect):
    """Tags printed at a different size than nominal: relative scale error (e.g. 0.01 = +1 %)."""

    name = "tag_scale"
    stage = "scene"

    Params = RelativeScale

    def apply(self, state: VariantState) -> VariantState:
        """Scale the printed stickers."""
        return _scene(state, tag_scale=state.scene.tag_scale * (1.0 + self.params.scale))


@register
class SamplingQuality(Effect):
    """Renderer quality: samples per pixel, sampler and maximum path depth."""

    name = "render_quality"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Integrator and sampling settings."""

        spp: int = 16
        sampler: Literal["multijitter", "ldsampler", "stratified", "independent", "orthogonal"] = (
            "multijitter"
        )
        max_depth: int = 3

        def __post_init__(self) -> None:
            require(self.spp >= 1, "spp: expected an integer >= 1")
            require(self.max_depth >= 2 or self.max_depth == -1, "max_depth: expected >= 2 or -1")

    def apply(self, state: VariantState) -> VariantState:
        """Set render quality."""
        p = self.params
        return _scene(state, quality=RenderQuality(p.spp, p.sampler, p.max_depth))


@register
class LensDistortion(Effect):
    """Brown-Conrady distortion of the true lens (k1, k2, p1, p2, k3, dimensionless).

    Rendered exactly per ray by the OpenCV sensor (no resampling, no black borders). With
    ``calibrated: true`` the estimator's calibration knows the coefficients too.
    """

    name = "lens_distortion"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Distortion coefficients."""

        k1: float = 0.0
        k2: float = 0.0
        p1: float = 0.0
        p2: float = 0.0
        k3: float = 0.0
        calibrated: bool = False

        def __post_init__(self) -> None:
            require(
                all(abs(v) < 2 for v in (self.k1, self.k2, self.k3)), "k1/k2/k3: expected |k| < 2"
            )
            require(abs(self.p1) < 0.1 and abs(self.p2) < 0.1, "p1/p2: expected |p| < 0.1")

    def apply(self, state: VariantState) -> VariantState:
        """Distort the true camera (and the calibration when calibrated)."""
        p = self.params
        coeffs = (p.k1, p.k2, p.p1, p.p2, p.k3)
        out = _scene(state, camera=state.scene.camera.replace(distortion=coeffs))
        if p.calibrated:
            est = out.estimation
            cal = est.calibration.replace(distortion=coeffs)
            out = dataclasses.replace(out, estimation=dataclasses.replace(est, calibration=cal))
        return out


@register
class FocalLength(Effect):
    """The true focal length differs from the calibration by a relative ``scale`` (0.02 = +2 %)."""

    name = "focal_length"
    stage = "scene"

    Params = RelativeScale

    def apply(self, state: VariantState) -> VariantState:
        """Scale the true camera's fx, fy."""
        cam = state.scene.camera
        s = 1.0 + self.params.scale
        return _scene(state, camera=cam.replace(fx=cam.fx * s, fy=cam.fy * s))


@register
class PrincipalPoint(Effect):
    """The true principal point is offset from the calibration's by (dx_px, dy_px) (px)."""

    name = "principal_point"
    stage = "scene"

    @dataclass(frozen=True)
    class Params:
        """Principal point offset."""

        dx_px: float = 0.0
        dy_px: float = 0.0

        def __post_init__(self) -> None:
            require(
                abs(self.dx_px) < 200 and abs(self.dy_px) < 200,
                "dx_px/dy_px: expected |d| < 200 px",
            )

    def apply(self, state: VariantState) -> VariantState:
        """Move the true camera's principal point."""
        cam = state.scene.camera
        return _scene(
            state, camera=cam.replace(cx=cam.cx + self.params.dx_px, cy=cam.cy + self.params.dy_px)
        )
