"""What the blind validation hides: catalogue effects and effects outside the catalogue.

Catalogue effects come with their magnitude samplers. The "other camera" every trial is rendered
through is :mod:`simgap.diagnosis.nuisance`. Used by :mod:`simgap.diagnosis.validate`; the
tables are data, extended as the catalogue grows.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from typing import Any

import numpy as np

from simgap.analysis.candidates import laminate_effects

Sampler = Callable[[np.random.Generator], dict[str, Any]]


def _signed(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(lo, hi))


def _lens(rng: np.random.Generator) -> dict[str, Any]:
    """Barrel or pincushion distortion: k1 alone, or with k2 and k3 of a wide-angle module.

    Half the draws have higher orders of the kind an Intel RealSense D435's colour lens
    calibrates to (k1 0.16, k2 -0.48, k3 0.42): k2 against k1's sign, k3 with it.
    """
    k1 = _signed(rng, 0.08, 0.2)
    if rng.uniform() < 0.5:
        return {"k1": k1}
    sign = float(np.sign(k1))
    k2, k3 = -sign * float(rng.uniform(0.1, 0.5)), sign * float(rng.uniform(0.0, 0.45))
    return {"k1": k1, "k2": k2, "k3": k3}


def _gloss(rng: np.random.Generator) -> dict[str, Any]:
    """A laminated print under a small light on the camera (an LED or ring light beside the lens).

    Roughness of a gloss to satin laminate film; the light 2-8 cm to either side of the lens and
    up to 4 cm above or below it, 0.1-0.5 W sr^-1 (a tag 0.45 m away gets 0.4-2x the template
    key light's irradiance from it). Rendered as the scene effects of
    :func:`simgap.analysis.candidates.laminate_effects`.
    """
    return {
        "alpha": float(rng.uniform(0.05, 0.3)),
        "light_intensity_w_sr": float(rng.uniform(0.1, 0.5)),
        "light_offset_x_m": _signed(rng, 0.02, 0.08),
        "light_offset_z_m": float(rng.uniform(-0.04, 0.04)),
    }


def _sun(rng: np.random.Generator) -> dict[str, Any]:
    """A distant light the simulation lacks: a sun over the camera's side of the fixture.

    From azimuths 100-260 deg (rail frame, :class:`simgap.effects.scene.Sun`; the fixture's
    camera looks along +Y from azimuth 180, so these light faces it can see: a sun behind the
    tags lights none, and no image shows it), 5-50 deg up, 1.5-4 W m^-2 on a surface facing it
    (1-3x the 1.0-1.4 W m^-2 the simulation's key light gives a frontal tag).
    """
    return {
        "azimuth_deg": float(rng.uniform(100.0, 260.0)),
        "elevation_deg": float(rng.uniform(5.0, 50.0)),
        "irradiance_w_m2": float(rng.uniform(1.5, 4.0)),
    }


#: Hidden effects and how their magnitudes are drawn (realistic hardware ranges), with the
#: parameters whose fitted values are scored (empty: not a magnitude effect).
HIDDEN: dict[str, tuple[Sampler, tuple[str, ...]]] = {
    # focal length and print scale from below 1 %, where a camera's demosaicing moves a frontal
    # tag's corners about as much as the effect does (benchmarks/demosaicing_geometry.py)
    "focal_length": (lambda r: {"scale": _signed(r, 0.005, 0.03)}, ("scale",)),
    "principal_point": (
        lambda r: {"dx_px": _signed(r, 4, 12), "dy_px": _signed(r, 4, 12)},
        ("dx_px", "dy_px"),
    ),
    "lens_distortion": (_lens, ("k1",)),
    # the calibration file claims a distortion the lens does not have (the paper's "faulty
    # calibration file"): the right answer is the lens as it is, lens_distortion near zero
    "faulty_calibration": (lambda r: {"k1": _signed(r, 0.05, 0.12)}, ("k1",)),
    "camera_mount": (
        lambda r: {"translation_m": tuple(_signed(r, 0.001, 0.004) for _ in range(3))},
        ("translation_m",),
    ),
    "turntable_offset": (lambda r: {"angle_rad": _signed(r, 0.015, 0.04)}, ("angle_rad",)),
    "carriage_pitch": (lambda r: {"scale": _signed(r, 0.01, 0.03)}, ("scale",)),
    "tag_scale": (lambda r: {"scale": _signed(r, 0.008, 0.04)}, ("scale",)),
    # appearance: the paper's own suspects (lighting, focus, the camera's image formation)
    "blur": (lambda r: {"sigma_px": float(r.uniform(0.6, 1.8))}, ("sigma_px",)),
    "exposure": (lambda r: {"ev": _signed(r, 0.8, 2.0)}, ("ev",)),
    "sensor_noise": (
        lambda r: {
            "full_well_e": float(r.uniform(400, 1500)),
            "read_noise_e": float(r.uniform(6, 20)),
        },
        ("full_well_e",),
    ),
    "defocus": (
        lambda r: {
            "aperture_radius_m": float(r.uniform(6e-4, 1.2e-3)),
            "focus_distance_m": float(r.uniform(0.8, 2.5)),
        },
        ("aperture_radius_m", "focus_distance_m"),
    ),
    "jpeg": (lambda r: {"quality": int(r.integers(25, 76))}, ("quality",)),
    "tag_gloss": (_gloss, ("alpha", "light_intensity_w_sr")),
    # scored on its azimuth and the irradiance an upright tag facing it gets (E cos(elevation)):
    # the tags stand upright and tell neither the elevation nor E apart
    # (simgap.analysis.candidates._sun; simgap.diagnosis.trial.Trial.truth)
    "sun": (_sun, ("azimuth_deg", "horizontal_irradiance_w_m2")),
}
#: Hidden effects that are no catalogue effect, and the effect that names them.
REPORTED_AS: dict[str, str] = {"faulty_calibration": "lens_distortion"}
#: Appearance effects among :data:`HIDDEN` (scored per effect).
APPEARANCE = ("blur", "exposure", "sensor_noise", "defocus", "jpeg", "tag_gloss", "sun")
#: Appearance effects every other camera has some of (:mod:`simgap.diagnosis.nuisance`: its
#: exposure and light, its sensor, its pixel filter): naming them is never wrong, and a hidden one
#: sets the camera's own (exposure: its total exposure; sensor noise: its sensor) or adds to it
#: (blur: in quadrature with its filter's softness). Their magnitudes are scored against the
#: camera's totals (:func:`simgap.diagnosis.camera_truth.exposure_truth`, ``softness_truth``).
CAMERA_NAMED = ("blur", "exposure", "sensor_noise")
#: Effects outside the diagnosis catalogue: the answer must be "unexplained". Motion blur of the
#: turntable still turning while the shutter is open (horizontal).
OUTSIDE: dict[str, Sampler] = {
    "motion_blur": lambda r: {"length_px": float(r.uniform(4.0, 7.0)), "angle_deg": 0.0},
}

#: Frames per pose of a pseudo-real capture when the camera's draw is overridden (tests): one
#: render, the camera's noise drawn anew for each (two exposures of a still fixture).
CAPTURE_REPEATS = 2


def rendered_effects(hidden: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """The scene, geometry and image effects that render ``hidden`` into a pseudo-real capture.

    A hidden exposure is the camera's total exposure and a faulty calibration is in the
    calibration file, not the render (:func:`simgap.diagnosis.validate.pseudo_real_experiment`);
    a glossy laminate is the laminate and the light beside the lens.
    """
    out: dict[str, dict[str, Any]] = {}
    for name, params in hidden.items():
        if name == "exposure" or name in REPORTED_AS:
            continue
        out.update(laminate_effects(params) if name == "tag_gloss" else {name: params})
    return out


def hides_catalogue_effects(hidden: Collection[str]) -> bool:
    """Whether a trial hiding the effects ``hidden`` hides catalogue ones.

    Not when it hides nothing, nor when it hides only effects outside the catalogue
    (:data:`OUTSIDE`).
    """
    return bool(hidden) and not set(hidden) <= set(OUTSIDE)


def found(hidden: str, selected: Sequence[str]) -> bool:
    """Whether a hidden effect is among the selected ones (itself or as :data:`REPORTED_AS`)."""
    return REPORTED_AS.get(hidden, hidden) in selected
