"""The "other camera" of a blind validation trial, drawn anew for every trial.

A real camera differs from simgap's simulation in many small ways at once: other lights, another
exposure, a softer or sharper pixel, its own sensor noise and transfer curve, vignetting, other
paint on the fixture, another print of the tags (its ink and paper), the poses an operator chose,
one or two frames a pose. A diagnosis whose rules were fitted to one such camera fails on the
next, so every trial draws its own from the wide ranges below (realistic for a bench camera and
lab lighting), and scores are reported per nuisance bin
(:func:`simgap.diagnosis.trial.nuisance_bins`).

The drawn camera is data (:class:`NuisanceCamera`): its image effects, its scene overrides, its
samples per pixel and its poses. :mod:`simgap.diagnosis.camera_truth` turns it into the exposure
and blur a diagnosis should report for it, measured the way a lab would (a light meter at the
tags, the pixel filter's width), never from the capture itself.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np

from simgap.core.rig import Rig
from simgap.diagnosis.camera_truth import with_exposure
from simgap.scene.lights import LightSpec, default_target, irradiance
from simgap.scene.spec import default_scene_spec

#: Total exposure of the other camera relative to the simulation, light level included (EV):
#: auto exposure and lab lighting put a bench camera this far either way; at +1.5 EV the paper
#: of a near, frontal tag clips.
EXPOSURE_EV = (-1.5, 1.5)
#: Share of that total that comes from the light (irradiance at the aim point, EV): the rest is
#: the camera's exposure setting.
LIGHT_EV = (-0.75, 0.75)
#: Key light types, and where the light stands as seen from the aim point (the node): azimuth
#: about the vertical from the camera side (deg, 0 = straight behind the camera), elevation above
#: the horizontal (deg) and distance (m). Beyond 70 deg of azimuth the tags are lit grazing.
LIGHT_TYPES = ("area", "point", "spot")
LIGHT_AZIMUTH_DEG = (-70.0, 70.0)
LIGHT_ELEVATION_DEG = (10.0, 70.0)
LIGHT_DISTANCE_M = (0.35, 1.0)
#: Side of an area light (m) and the cut-off of a spot (deg; its cone always holds the node).
AREA_SIZE_M = (0.08, 0.5)
SPOT_CUTOFF_DEG = (20.0, 45.0)
#: Correlated colour temperature of the key light and of the ambient (K): tungsten to daylight.
CCT_K = (2700.0, 6500.0)
#: Ambient (room) radiance (W m^-2 sr^-1): a dark lab to a bright office; the template's is 0.15.
AMBIENT_RADIANCE = (0.03, 0.4)
#: Pixel reconstruction filters (:data:`simgap.scene.spec.RFILTERS`): box, tent of this radius
#: (px), Gaussian of this standard deviation (px). The simulation's is a box.
TENT_RADIUS_PX = (0.6, 1.3)
GAUSSIAN_STDDEV_PX = (0.25, 0.6)
#: Samples per pixel of the other camera's renders, path traced (supersampling; squares, as
#: multijitter takes them): a real camera has no render noise, so it is rendered with more
#: samples than simgap's path-traced study had (16). Its Monte Carlo noise (about 1.5-1.9 DN on
#: the stickers) is still above a converged simulation's (0.2-0.5 DN): the other camera's noise
#: is then a little more than its sensor's, as a real camera's is (fixed pattern, compression).
SPP_CHOICES = (49, 64, 81)
#: Sensor: full well (e-, log-uniform) and read noise (e-); linear 1.0 is the full well.
FULL_WELL_E = (1000.0, 20000.0)
READ_NOISE_E = (1.0, 10.0)
#: Transfer curve: sRGB with this probability, else a pure gamma in this range.
SRGB_SHARE = 0.5
GAMMA = (1.8, 2.4)
#: Vignetting strength (fall-off at the image corner).
VIGNETTING = (0.0, 0.35)
#: Diffuse albedo of the node's and the table's paint (the template's: 0.45 and 0.35).
NODE_REFLECTANCE = (0.2, 0.8)
TABLE_REFLECTANCE = (0.15, 0.7)
#: The tag print's ink and paper (diffuse albedo; the simulation's template: 0.03 and 0.80). The
#: ink is drawn uniform in optical density (reflectance ``10 ** -D``), from 1.1 (a weak toner
#: print on office paper, 8 %) to 2.3 (a dense inkjet black on coated stock, 0.5 %): a black
#: that reflects next to nothing, as an independent generator's, and a laser print are both
#: inside, and so are the densities of about 1.4-1.9 that office and offset blacks usually
#: reach. The paper: grey or aged label stock to bright office paper.
INK_DENSITY = (1.1, 2.3)
PAPER_REFLECTANCE = (0.65, 0.9)
#: Poses: how many pin holes (always one of the three nearest and one of the three farthest, so
#: that a trend with distance shows) and turntable stops (from those where a tag faces the
#: camera, each tag's frontal stop always among them), and the share of captures with two
#: frames a pose (the others have one).
PIN_COUNT = (4, 6)
STOP_COUNT = (6, 8)
TWO_FRAMES_SHARE = 0.5
#: Stops (deg) where tag 0 and tag 1 face the camera head-on: always among a capture's stops, as
#: in the paper's grid (a glint of a laminate under a light beside the lens shows only there:
#: docs/results/design_evidence.md#nuisance).
FRONTAL_STOPS_DEG = (0, 180)
#: Turntable stops (deg) where one of the default rig's tags faces the camera well.
FACING_STOPS_DEG = tuple(range(0, 61, 10)) + tuple(range(300, 360, 10)) + tuple(range(120, 241, 10))
#: Effects the simulation never models that every other camera has (always among its effects).
CAMERA_EFFECTS = ("lighting", "ambient", "exposure", "sensor_noise", "gamma", "vignetting")
#: The camera's own image pipeline (:mod:`simgap.effects.camera_pipeline`, and the lens's
#: lateral colour): each stage is present in this share of the cameras, drawn independently,
#: with its parameters from the ranges below (a bench or robot camera's settings: RealSense,
#: machine-vision and phone-module ISPs sharpen, denoise and demosaic by default).
PIPELINE_SHARE: dict[str, float] = {
    "gain_change": 0.3,
    "black_level": 0.4,
    "bayer": 0.5,
    "denoise": 0.4,
    "tone_curve": 0.3,
    "sharpen": 0.5,
    "chromatic_aberration": 0.3,
}
#: Frame-to-frame exposure spread (EV): auto exposure settling, mains flicker.
GAIN_CHANGE_SIGMA_EV = (0.03, 0.15)
#: Black level subtracted beyond the sensor's (fraction of full scale): the ink of a dark
#: print (linear 0.02-0.05 at the simulation's exposure) is partly or wholly crushed to 0 DN.
BLACK_LEVEL = (0.01, 0.06)
#: Demosaicing methods and colour filter layouts (:class:`simgap.effects.camera_pipeline.Bayer`).
DEMOSAIC_METHODS = ("bilinear", "edge_aware")
BAYER_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
#: Bilateral denoising: range kernel (8-bit DN) and spatial kernel (px).
DENOISE_STRENGTH_DN = (4.0, 20.0)
DENOISE_RADIUS_PX = (0.5, 1.5)
#: S-curve of the output LUT: slope and midpoint
#: (:class:`~simgap.effects.camera_pipeline.ToneCurve`).
TONE_CONTRAST = (2.0, 6.0)
TONE_MIDPOINT = (0.35, 0.6)
#: Unsharp mask: amount, radius (px) and threshold (DN); a D435i's default sharpness is not 0.
SHARPEN_AMOUNT = (0.3, 1.5)
SHARPEN_RADIUS_PX = (0.5, 1.5)
SHARPEN_THRESHOLD_DN = (0.0, 4.0)
#: Lateral chromatic aberration: red against green at the image corner (px, either sign).
CHROMATIC_SHIFT_PX = (0.3, 1.5)
#: Share of captures whose poses are mostly frontal: the stops :data:`FRONTAL_HEAVY_STOPS_DEG`
#: and one oblique stop of :data:`OBLIQUE_STOPS_DEG` (the handful of views a user often takes).
FRONTAL_HEAVY_SHARE = 0.25
FRONTAL_HEAVY_STOPS_DEG = (0.0, 10.0, 170.0, 180.0, 190.0)
OBLIQUE_STOPS_DEG = (
    40.0,
    50.0,
    60.0,
    300.0,
    310.0,
    320.0,
    120.0,
    130.0,
    140.0,
    220.0,
    230.0,
    240.0,
)


@dataclass(frozen=True)
class NuisanceCamera:
    """One drawn "other camera" (see module docstring).

    Attributes
    ----------
    effects : dict
        Image and scene effects of the camera (:data:`CAMERA_EFFECTS`), in effect-parameter
        vocabulary (``lighting``, ``ambient``, ``exposure``, ``sensor_noise``, ``gamma``,
        ``vignetting``).
    scene : dict
        Scene-template overrides: pixel filter, texture filtering, node and table paint.
    spp : int
        Samples per pixel of its renders.
    p : tuple of int
        Pin holes of the capture.
    theta_deg : tuple of float
        Turntable stops of the capture (deg).
    frames_per_pose : int
        1 or 2.
    light_ev : float
        The drawn light level at the aim point relative to the template's key light (EV).

    The camera's own image pipeline (:data:`PIPELINE_SHARE`) is among ``effects``; see
    :meth:`pipeline`.
    """

    effects: dict[str, dict[str, Any]]
    scene: dict[str, Any]
    spp: int
    p: tuple[int, ...]
    theta_deg: tuple[float, ...]
    frames_per_pose: int
    light_ev: float

    def pipeline(self) -> dict[str, dict[str, Any]]:
        """The stages of the camera's own image pipeline it has (:data:`PIPELINE_SHARE`)."""
        return {k: v for k, v in self.effects.items() if k in PIPELINE_SHARE}

    def tag_print(self) -> dict[str, float]:
        """The tag print's drawn ``ink`` and ``paper`` albedo (:func:`draw_print`).

        Empty where the camera prints with the simulation's (``--nominal-print``, trials kept
        before prints were drawn).
        """
        tag = self.scene.get("materials", {}).get("tag", {})
        return {k: float(tag[k]) for k in ("ink", "paper") if k in tag}


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(*bounds))


#: Normal of the surface at which a light's level is set: facing the camera (rail frame).
FACING_CAMERA = (0.0, -1.0, 0.0)


def _key_light(rng: np.random.Generator, light_ev: float) -> dict[str, Any]:
    """A key light of a drawn type and place giving ``light_ev`` at the aim point.

    The level is the irradiance on a surface at the aim point facing the camera, relative to the
    template's key light there (:func:`simgap.scene.lights.irradiance`).
    """
    target = np.asarray(default_target())
    azimuth = np.radians(_uniform(rng, LIGHT_AZIMUTH_DEG))
    elevation = np.radians(_uniform(rng, LIGHT_ELEVATION_DEG))
    distance = _uniform(rng, LIGHT_DISTANCE_M)
    # the camera looks along +y: "behind the camera" is -y from the node
    direction = np.array(
        [
            np.sin(azimuth) * np.cos(elevation),
            -np.cos(azimuth) * np.cos(elevation),
            np.sin(elevation),
        ]
    )
    position = target + distance * direction
    kind = cast(Literal["area", "point", "spot"], str(rng.choice(LIGHT_TYPES)))  # a light type
    size = (_uniform(rng, AREA_SIZE_M), _uniform(rng, AREA_SIZE_M))
    cutoff = _uniform(rng, SPOT_CUTOFF_DEG)
    template = default_scene_spec().lights["key"]
    here, normal = target[None], np.asarray(FACING_CAMERA)[None]
    unit = LightSpec(
        kind,
        tuple(position),
        tuple(target),
        size=size,
        radiance=1.0,
        intensity=1.0,
        cutoff_deg=cutoff,
    )
    level = irradiance(template, here, normal)[0] * 2.0**light_ev
    power = level / irradiance(unit, here, normal)[0]
    return {
        "type": kind,
        "position": [float(v) for v in position],
        "target": [float(v) for v in target],
        "size_m": [float(v) for v in size],
        "power": float(power),
        "cct_k": _uniform(rng, CCT_K),
        "cutoff_deg": cutoff,
    }


def _rfilter(rng: np.random.Generator) -> dict[str, Any]:
    kind = str(rng.choice(("box", "tent", "gaussian")))
    if kind == "tent":
        return {"type": "tent", "radius": _uniform(rng, TENT_RADIUS_PX)}
    if kind == "gaussian":
        return {"type": "gaussian", "stddev": _uniform(rng, GAUSSIAN_STDDEV_PX)}
    return {"type": "box"}


def _poses(rng: np.random.Generator) -> tuple[tuple[int, ...], tuple[float, ...]]:
    pins = int(rng.integers(PIN_COUNT[0], PIN_COUNT[1] + 1))
    near, far = int(rng.integers(0, 3)), int(rng.integers(12, 15))
    middle = rng.choice(np.arange(3, 12), size=pins - 2, replace=False)
    p = tuple(sorted({near, far, *map(int, middle)}))
    stops = int(rng.integers(STOP_COUNT[0], STOP_COUNT[1] + 1))
    # half the stops for each tag's side of the turntable, each tag's frontal stop among them
    front = [s for s in FACING_STOPS_DEG if (s <= 60 or s >= 300) and s != FRONTAL_STOPS_DEG[0]]
    back = [s for s in FACING_STOPS_DEG if 120 <= s <= 240 and s != FRONTAL_STOPS_DEG[1]]
    k = stops // 2
    chosen = (
        list(FRONTAL_STOPS_DEG)
        + list(rng.choice(front, size=k - 1, replace=False))
        + list(rng.choice(back, size=stops - k - 1, replace=False))
    )
    return p, tuple(float(s) for s in sorted(chosen))


def draw_pipeline(
    rng: np.random.Generator, always: Collection[str] = ()
) -> dict[str, dict[str, Any]]:
    """The stages of a camera's own image pipeline, each drawn with :data:`PIPELINE_SHARE`.

    The stages named in ``always`` (keys of :data:`PIPELINE_SHARE`) are present in every camera,
    with their parameters drawn as usual (a targeted validation: every draw of a seed but their
    presence stays what it was).
    """
    samplers: dict[str, Callable[[], dict[str, Any]]] = {
        "gain_change": lambda: {"sigma_ev": _uniform(rng, GAIN_CHANGE_SIGMA_EV)},
        "black_level": lambda: {"level": _uniform(rng, BLACK_LEVEL)},
        "bayer": lambda: {
            "pattern": str(rng.choice(BAYER_PATTERNS)),
            "method": str(rng.choice(DEMOSAIC_METHODS)),
        },
        "denoise": lambda: {
            "strength_dn": _uniform(rng, DENOISE_STRENGTH_DN),
            "radius_px": _uniform(rng, DENOISE_RADIUS_PX),
        },
        "tone_curve": lambda: {
            "contrast": _uniform(rng, TONE_CONTRAST),
            "midpoint": _uniform(rng, TONE_MIDPOINT),
        },
        "sharpen": lambda: {
            "amount": _uniform(rng, SHARPEN_AMOUNT),
            "radius_px": _uniform(rng, SHARPEN_RADIUS_PX),
            "threshold_dn": _uniform(rng, SHARPEN_THRESHOLD_DN),
        },
        "chromatic_aberration": lambda: {
            "shift_px": float(rng.choice([-1.0, 1.0])) * _uniform(rng, CHROMATIC_SHIFT_PX)
        },
    }
    # every stage takes its draws whether present or not, so a share change moves no other draw
    drawn = {
        name: (rng.uniform() < share or name in always, samplers[name]())
        for name, share in PIPELINE_SHARE.items()
    }
    return {name: params for name, (present, params) in drawn.items() if present}


def draw_print(rng: np.random.Generator) -> dict[str, float]:
    """The tag print of one other camera: ``ink`` and ``paper`` albedo (scene-template keys).

    The ink from :data:`INK_DENSITY` (uniform in optical density, reflectance ``10 ** -D``), the
    paper from :data:`PAPER_REFLECTANCE`.
    """
    return {
        "ink": float(10.0 ** -_uniform(rng, INK_DENSITY)),
        "paper": _uniform(rng, PAPER_REFLECTANCE),
    }


def _frontal_heavy_stops(rng: np.random.Generator) -> tuple[float, ...]:
    """:data:`FRONTAL_HEAVY_STOPS_DEG` and one drawn oblique stop (deg), sorted."""
    oblique = float(rng.choice(OBLIQUE_STOPS_DEG))
    return tuple(sorted((*FRONTAL_HEAVY_STOPS_DEG, oblique)))


def draw_nuisance(
    rng: np.random.Generator,
    rig: Rig,
    pipeline_rng: np.random.Generator | None = None,
    always: Collection[str] = (),
    print_rng: np.random.Generator | None = None,
) -> NuisanceCamera:
    """Draw one other camera from the ranges of this module.

    The camera's exposure setting is chosen so that its total exposure (:func:`exposure_truth`:
    setting, light meter and transfer curve) is the drawn one, within :data:`EXPOSURE_EV`.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws the lights, exposure, sensor, transfer curve, vignetting, scene and poses.
    rig : Rig
        The fixture (for the light meter).
    pipeline_rng : numpy.random.Generator, optional
        Draws the camera's own image pipeline (:func:`draw_pipeline`) and whether its poses are
        mostly frontal (:data:`FRONTAL_HEAVY_SHARE`), from a stream of its own so that the other
        draws stay those of ``rng``. None: no pipeline stages and the usual poses.
    always : collection of str, optional
        Pipeline stages every camera has (:func:`draw_pipeline`); only with ``pipeline_rng``.
    print_rng : numpy.random.Generator, optional
        Draws the tag print's ink and paper (:func:`draw_print`), from a stream of its own. None:
        the simulation's print.
    """
    total_ev = _uniform(rng, EXPOSURE_EV)
    light_ev = _uniform(rng, LIGHT_EV)
    effects: dict[str, dict[str, Any]] = {
        "lighting": _key_light(rng, light_ev),
        "ambient": {"radiance": _uniform(rng, AMBIENT_RADIANCE), "cct_k": _uniform(rng, CCT_K)},
        "exposure": {"ev": 0.0},
        "sensor_noise": {
            "full_well_e": float(np.exp(rng.uniform(*np.log(FULL_WELL_E)))),
            "read_noise_e": _uniform(rng, READ_NOISE_E),
        },
        "gamma": (
            {"encoding": "srgb"}
            if rng.uniform() < SRGB_SHARE
            else {"encoding": "gamma", "gamma": _uniform(rng, GAMMA)}
        ),
        "vignetting": {"strength": _uniform(rng, VIGNETTING)},
    }
    scene = {
        "rfilter": _rfilter(rng),
        "materials": {
            "tag": {"texture_filter": str(rng.choice(("nearest", "bilinear")))},
            "node": {"type": "diffuse", "reflectance": _uniform(rng, NODE_REFLECTANCE)},
            "table": {"type": "diffuse", "reflectance": _uniform(rng, TABLE_REFLECTANCE)},
        },
    }
    if print_rng is not None:
        scene["materials"]["tag"].update(draw_print(print_rng))
    spp = int(rng.choice(SPP_CHOICES))
    p, theta_deg = _poses(rng)
    frames = 2 if rng.uniform() < TWO_FRAMES_SHARE else 1
    if pipeline_rng is not None:
        effects.update(draw_pipeline(pipeline_rng, always))
        frontal = _frontal_heavy_stops(pipeline_rng)
        if pipeline_rng.uniform() < FRONTAL_HEAVY_SHARE:
            theta_deg = frontal
    camera = NuisanceCamera(effects, scene, spp, p, theta_deg, frames, light_ev)
    return with_exposure(camera, total_ev, rig)


__all__ = [
    "CAMERA_EFFECTS",
    "PIPELINE_SHARE",
    "NuisanceCamera",
    "draw_nuisance",
    "draw_pipeline",
    "draw_print",
]
