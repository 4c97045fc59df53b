"""What a diagnosis should report for a drawn "other camera", measured as a lab would.

The truths a blind validation trial is scored against where the other camera has the same kind
of effect as the hidden one (:data:`simgap.diagnosis.hidden_effects.CAMERA_NAMED`): its total
exposure (:func:`exposure_truth`: the exposure setting, a light meter at the tags, the print's
paper and the transfer curve) and its softness (:func:`softness_truth`: the pixel filter's width
beyond the simulation's box), never read from the capture itself; how unevenly its lights light
the tags against the simulation's (:func:`light_spread_truth`); whether it moves the markers'
edges (:func:`moves_edges`); and :func:`with_exposure`, which
sets a camera's exposure so that its total is a drawn one. The cameras are drawn by
:mod:`simgap.diagnosis.nuisance`.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import colour
import numpy as np

from simgap.core.rig import Rig
from simgap.effects import make_effect
from simgap.effects.state import SceneState, VariantState
from simgap.pose.camera_response import CameraResponse, estimate_response
from simgap.pose.image_stats import linearise
from simgap.scene.lights import lights_irradiance
from simgap.scene.spec import default_scene_spec

if TYPE_CHECKING:  # annotation only: the draws import this module, not the reverse
    from simgap.diagnosis.nuisance import NuisanceCamera


def with_exposure(camera: NuisanceCamera, total_ev: float, rig: Rig) -> NuisanceCamera:
    """``camera`` with its exposure setting chosen so that :func:`exposure_truth` is ``total_ev``.

    The transfer curve's apparent change depends on the level, so the setting is found by a
    few fixed-point steps (it converges in three to the last 0.001 EV).
    """
    meter = light_meter_ev(camera, rig) + print_ev(camera)
    setting = total_ev - meter
    for _ in range(4):
        level = PAPER_LEVEL * 2.0 ** (setting + meter)
        setting = total_ev - meter - transfer_ev(camera, level)
    effects = {**camera.effects, "exposure": {"ev": float(setting)}}
    return dataclasses.replace(camera, effects=effects)


def _tag_points(rig: Rig, p: tuple[int, ...], theta_deg: tuple[float, ...]) -> tuple:
    """Rail-frame centres and normals of the tags facing the camera at the poses."""
    points, normals = [], []
    for pin in p:
        for t in np.radians(theta_deg):
            for tag in rig.tags.ids:
                if not rig.is_visible(tag, pin, t):
                    continue
                m = rig.rail_from_tag(tag, t)
                points.append(m[:3, 3])
                normals.append(m[:3, 2])
    return np.array(points), np.array(normals)


def _light_ratios(camera: NuisanceCamera, rig: Rig) -> np.ndarray:
    """Per facing tag of the capture, log2 of its direct irradiance over the simulation's.

    Key and ambient (:func:`simgap.scene.lights.lights_irradiance`; shadows and
    inter-reflections left out).
    """
    base = VariantState(scene=SceneState(spec=default_scene_spec()))
    state = base
    for name in ("lighting", "ambient"):
        state = make_effect(name, camera.effects[name]).apply(state)
    points, normals = _tag_points(rig, camera.p, camera.theta_deg)
    ratio = lights_irradiance(state.scene.spec.lights.values(), points, normals) / (
        lights_irradiance(base.scene.spec.lights.values(), points, normals)
    )
    return np.log2(ratio)


def light_meter_ev(camera: NuisanceCamera, rig: Rig) -> float:
    """How much more light the other camera's scene puts on the tags than the simulation's (EV).

    The median over the capture's facing tags of the log2 ratio of direct irradiance (key and
    ambient, :func:`simgap.scene.lights.irradiance`; shadows and inter-reflections left out).
    """
    return float(np.median(_light_ratios(camera, rig)))


def light_spread_truth(camera: NuisanceCamera, rig: Rig) -> float:
    """How unevenly the other camera's lights light its tags against the simulation's (stops).

    The RMS over the capture's facing tags of the log2 ratio of direct irradiance (as
    :func:`light_meter_ev`) less its median: 0 where the capture's key and ambient light every
    tag by the same factor (one exposure), larger where its key light stands elsewhere and lights
    the tags' faces differently, which the diagnosis may read as a light the simulation lacks
    (the ``sun`` candidate).
    """
    log_ratio = _light_ratios(camera, rig)
    return float(np.sqrt(np.mean((log_ratio - np.median(log_ratio)) ** 2)))


def print_ev(camera: NuisanceCamera) -> float:
    """How much brighter the other camera's tag paper is than the simulation's (EV).

    ``log2`` of the paper albedo of its print (the scene override ``materials.tag.paper``, where
    drawn: :func:`simgap.diagnosis.nuisance.draw_print`) over the simulation template's; 0 for
    the template's print. The paper level is what an exposure finding reads, so a greyer paper
    is a darker exposure.
    """
    paper = camera.tag_print().get("paper")
    return 0.0 if paper is None else float(np.log2(paper / default_scene_spec().tag.paper))


def transfer_ev(camera: NuisanceCamera, paper_linear: float) -> float:
    """Apparent exposure change of the camera's transfer curve at the paper's level (EV).

    The diagnosis linearises a capture ingested without a measured response with the sRGB
    curve; a camera encoding with a pure
    gamma, subtracting a black level or applying a tone curve makes the paper look brighter or
    darker by this much: the level through those pixel-wise stages (their own code), rounded to
    the delivered DN and linearised with sRGB. 0 for a plain sRGB camera (quantisation aside).
    """
    level = float(np.clip(paper_linear, 1e-4, 1.0))
    srgb = camera.effects["gamma"].get("encoding", "gamma") == "srgb"
    if srgb and not {"black_level", "tone_curve"} & set(camera.effects):
        return 0.0
    dn = np.round(float(pixel_codes(camera, np.array([level]))[0]))
    return float(np.log2(max(float(linearise(dn)), 1e-4) / level))


def pixel_codes(camera: NuisanceCamera, linear: np.ndarray) -> np.ndarray:
    """The other camera's 8-bit codes (float, 0-255) of linear exposures: its pixel-wise stages.

    Its black level, its encoding (sRGB or a pure gamma) and its tone curve, in the camera's
    order (:mod:`simgap.effects.camera_pipeline`), each by its own code; the spatial stages
    (demosaicing, denoising, sharpening) and the noise left out.
    """
    gamma = camera.effects["gamma"]
    black, tone = camera.effects.get("black_level"), camera.effects.get("tone_curve")
    # (the ignores: make_effect returns the Effect base class; black_level is an ImageEffect,
    # with process, and tone_curve a ToneCurve, with curve)
    x = np.asarray(linear, np.float32)
    if black is not None:
        x = make_effect("black_level", black).process(x, None)  # type: ignore[attr-defined]
    x = np.clip(x, 0.0, 1.0)
    if gamma.get("encoding", "gamma") == "srgb":
        encoded = np.asarray(colour.cctf_encoding(x, function="sRGB"), float)
    else:
        encoded = np.asarray(x, float) ** (1.0 / float(gamma.get("gamma", 2.2)))
    if tone is not None:
        encoded = make_effect("tone_curve", tone).curve(encoded)  # type: ignore[attr-defined]
    return 255.0 * np.asarray(encoded, float)


#: The lab's exposure bracket (:func:`lab_response`): eight photos a stop apart of a grey ramp
#: over 0.2-100 % of full scale at the middle one, each code with Gaussian noise of this standard
#: deviation (DN; a lab averages frames), quantised.
LAB_BRACKET_STOPS = tuple(range(-4, 4))
LAB_RAMP = (2e-3, 1.0)
LAB_NOISE_DN = 0.5


def lab_response(camera: NuisanceCamera) -> CameraResponse:
    """The response a lab measures of the other camera from an exposure bracket.

    The camera's pixel-wise stages (:func:`pixel_codes`) photograph a grey ramp at
    :data:`LAB_BRACKET_STOPS`, and Debevec's estimate reads the response back
    (:func:`simgap.pose.camera_response.estimate_response`), as ``simgap camera-response``
    does of a real camera's bracket. The same camera gives the same response.
    """
    rng = np.random.default_rng(0)
    ramp = np.geomspace(*LAB_RAMP, 512)[None, :] * np.exp(rng.normal(0.0, 0.2, (64, 1)))
    times = [2.0**k for k in LAB_BRACKET_STOPS]
    photos = [
        np.clip(
            np.round(pixel_codes(camera, ramp * t) + rng.normal(0.0, LAB_NOISE_DN, ramp.shape)),
            0,
            255,
        ).astype(np.uint8)
        for t in times
    ]
    return estimate_response(photos, times)


#: Paper level (linear) of the simulation's default scene at a mid-range frontal tag, at which
#: :func:`transfer_ev` is evaluated (measured: the median over tags of the baseline simulation's
#: linearised paper level is 0.34-0.35 over blind validation trials;
#: docs/results/design_evidence.md#camera_truth).
PAPER_LEVEL = 0.34


def exposure_truth(camera: NuisanceCamera, rig: Rig, measured_response: bool = False) -> float:
    """The exposure change (EV) that matches the simulation's paper level to this camera's.

    Camera exposure setting + light meter (:func:`light_meter_ev`) + paper (:func:`print_ev`) +
    transfer curve (:func:`transfer_ev` at the paper's level): what an exposure finding should
    read. With ``measured_response`` (the capture read through the camera's measured response,
    :func:`lab_response`) the levels are linear exposures and the transfer curve adds nothing.
    """
    setting = float(camera.effects["exposure"]["ev"])
    meter = light_meter_ev(camera, rig) + print_ev(camera)
    if measured_response:
        return setting + meter
    return setting + meter + transfer_ev(camera, PAPER_LEVEL * 2.0 ** (setting + meter))


#: Stages of a camera's pipeline that move where a soft dark-to-light edge reads as an edge
#: (:class:`simgap.effects.camera_pipeline.EdgeOffset`): those that change the levels across it
#: (a black level, a tone curve) or resample it (demosaicing, denoising, sharpening). A gain
#: change scales the levels and lateral colour moves edges by their place in the image, not by
#: a marker's edge.
EDGE_MOVING_STAGES = frozenset({"black_level", "tone_curve", "bayer", "denoise", "sharpen"})


def moves_edges(camera: NuisanceCamera) -> bool:
    """Whether the other camera moves the markers' soft edges against the simulation.

    True where its pipeline has a stage of :data:`EDGE_MOVING_STAGES`, it encodes with another
    curve than the simulation's sRGB, or it prints the tags with another ink or paper
    (:func:`print_ev`'s print): each moves the level at which the soft edge is read, and with it
    the edge (what an ``edge_offset`` finding reads).
    """
    other_curve = camera.effects["gamma"].get("encoding", "gamma") != "srgb"
    return (
        bool(EDGE_MOVING_STAGES & set(camera.pipeline())) or other_curve or bool(camera.tag_print())
    )


#: Variance of the simulation's own pixel footprint along one axis (px^2): a box of one pixel.
BOX_VARIANCE_PX2 = 1.0 / 12.0


def filter_variance_px2(rfilter: dict[str, Any]) -> float:
    """Variance of a reconstruction filter along one axis (px^2).

    Box: 1/12; tent of radius r: r^2 / 6; Gaussian of standard deviation s: s^2.
    """
    kind = rfilter.get("type", "box")
    if kind == "tent":
        return float(rfilter.get("radius", 1.0)) ** 2 / 6.0
    if kind == "gaussian":
        return float(rfilter.get("stddev", 0.5)) ** 2
    return BOX_VARIANCE_PX2


def softness_truth(camera: NuisanceCamera, blur_sigma_px: float = 0.0) -> float:
    """The Gaussian blur (px) that matches the simulation's edges to this camera's.

    The camera's pixel filter beyond the simulation's box, combined in quadrature with a blur it
    has (``blur_sigma_px``); 0 when the camera is as sharp as the simulation.
    """
    extra = filter_variance_px2(camera.scene["rfilter"]) - BOX_VARIANCE_PX2
    return float(np.sqrt(max(extra + blur_sigma_px**2, 0.0)))


__all__ = [
    "EDGE_MOVING_STAGES",
    "PAPER_LEVEL",
    "exposure_truth",
    "filter_variance_px2",
    "lab_response",
    "light_meter_ev",
    "moves_edges",
    "pixel_codes",
    "print_ev",
    "softness_truth",
    "transfer_ev",
    "with_exposure",
]
