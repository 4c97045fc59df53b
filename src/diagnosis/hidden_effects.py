"""What the blind validation hides, and the nuisance image formation of "other hardware".

Hidden effects with their magnitude samplers, effects outside the catalogue, and the image
formation that makes pseudo-real captures come from another camera.

Used by :mod:`simgap.diagnosis.validate`; the tables are data, extended as the catalogue grows.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from simgap.scene.spec import default_scene_spec

Sampler = Callable[[np.random.Generator], dict[str, Any]]


def _signed(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(lo, hi))


def _lighting(rng: np.random.Generator) -> dict[str, Any]:
    """Another key light in the template's key light's place: dim or harsh.

    Dim: the template's area light at a quarter to a half of its radiance (8 W m^-2 sr^-1).
    Harsh: a point light in its place, intensity 2-4 W/sr (hard shading, brighter paper).
    """
    key = default_scene_spec().lights["key"]
    place = {"position": list(key.position), "target": list(key.target)}
    if rng.uniform() < 0.5:
        return {"type": "area", **place, "power": float(rng.uniform(2.0, 4.0))}
    return {"type": "point", **place, "power": float(rng.uniform(2.0, 4.0))}


#: Hidden effects and how their magnitudes are drawn (realistic hardware ranges), with the
#: parameter whose fitted value is scored (None: not a magnitude effect).
HIDDEN: dict[str, tuple[Sampler, str | None]] = {
    "focal_length": (lambda r: {"scale": _signed(r, 0.01, 0.03)}, "scale"),
    "principal_point": (
        lambda r: {"dx_px": _signed(r, 4, 12), "dy_px": _signed(r, 4, 12)},
        "dx_px",
    ),
    "lens_distortion": (lambda r: {"k1": _signed(r, 0.08, 0.2)}, "k1"),
    "camera_mount": (
        lambda r: {"translation_m": (_signed(r, 0.001, 0.003), 0.0, _signed(r, 0.001, 0.003))},
        "translation_m",
    ),
    "turntable_offset": (lambda r: {"angle_rad": _signed(r, 0.015, 0.04)}, "angle_rad"),
    "carriage_pitch": (lambda r: {"scale": _signed(r, 0.01, 0.03)}, "scale"),
    "tag_scale": (lambda r: {"scale": _signed(r, 0.015, 0.04)}, "scale"),
    # appearance: the paper's own suspects (lighting, focus, the camera's image formation)
    "blur": (lambda r: {"sigma_px": float(r.uniform(0.9, 1.8))}, "sigma_px"),
    "exposure": (lambda r: {"ev": _signed(r, 0.8, 2.0)}, "ev"),
    "sensor_noise": (
        lambda r: {
            "full_well_e": float(r.uniform(400, 1500)),
            "read_noise_e": float(r.uniform(8, 20)),
        },
        "full_well_e",
    ),
    "defocus": (
        lambda r: {
            "aperture_radius_m": float(r.uniform(6e-4, 1.2e-3)),
            "focus_distance_m": float(r.uniform(1.0, 2.5)),
        },
        "aperture_radius_m",
    ),
    "jpeg": (lambda r: {"quality": int(r.integers(25, 76))}, "quality"),
    "lighting": (_lighting, None),
}
#: Appearance effects among :data:`HIDDEN` (scored per effect).
APPEARANCE = ("blur", "exposure", "sensor_noise", "defocus", "jpeg", "lighting")
#: Hidden effects the diagnosis reports as another catalogue effect that leaves the same
#: evidence: a grey camera sees a dimmer or harsher key light as a change of the ink and paper
#: levels, which is an exposure change (one image-stage parameter) unless the shading across
#: tags changes beyond the level floors. Scored as correct when that effect is reported.
REPORTED_AS: dict[str, str] = {"lighting": "exposure"}
#: Effects outside the diagnosis catalogue: the answer must be "unexplained". Motion blur of the
#: turntable still turning while the shutter is open (horizontal).
OUTSIDE: dict[str, Sampler] = {
    "motion_blur": lambda r: {"length_px": float(r.uniform(4.0, 7.0)), "angle_deg": 0.0},
}

#: What makes the pseudo-real data "other hardware" even without a hidden effect: another light
#: and sensor noise ...
NUISANCE_EFFECTS: dict[str, dict[str, Any]] = {
    "lighting": {"type": "area", "position": [0.2, -0.25, 0.45], "power": 7.0, "cct_k": 4500},
    "sensor_noise": {"full_well_e": 9000, "read_noise_e": 3},
}
#: ... and another image formation and background (scene-template overrides) ...
NUISANCE_SCENE: dict[str, Any] = {
    "rfilter": {"type": "gaussian", "stddev": 0.3},
    "materials": {
        "tag": {"texture_filter": "bilinear"},
        "table": {"type": "diffuse", "reflectance": 0.6},
        "node": {"type": "diffuse", "reflectance": 0.55},
    },
}
#: ... rendered with more samples per pixel (supersampling; a square number for multijitter).
#: A real camera has no render noise, and a capture noisier than the simulation cannot tell
#: that noise from shot noise. Flat-paper noise of the pseudo-real renders with the lights
#: weighted by their irradiance (measured 2026-11-22): 5.5 % at 25 spp, 3.4 % at 64 spp, against
#: the simulation's 3.2 % at 16 spp (the Gaussian pixel filter mixes neighbouring pixels'
#: samples and undoes the sampler's stratification).
NUISANCE_SPP = 64
#: Frames per pose of a pseudo-real capture: one render, the camera's noise drawn anew for each
#: (what two exposures of a still fixture give). The diagnosis compares the first with the
#: simulation and reads the temporal noise from the pair (EMVA 1288): the spatial noise of flat
#: cells alone cannot tell shot noise from fixed patterns (seed 25: full wells 1.4-2.2x too large).
CAPTURE_REPEATS = 2


def found(hidden: str, selected: list[str]) -> bool:
    """Whether a hidden effect is among the selected ones (itself or as :data:`REPORTED_AS`)."""
    return hidden in selected or REPORTED_AS.get(hidden) in selected
