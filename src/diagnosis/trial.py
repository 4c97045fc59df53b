"""One blind validation trial: what was hidden, the other camera, the answer, and its score."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from simgap.analysis.candidates import geometric_effects
from simgap.analysis.thresholds import SUN_MIN_GAIN_MISFIT, image_floor
from simgap.core.rig import Rig
from simgap.diagnosis.camera_truth import (
    exposure_truth,
    light_spread_truth,
    moves_edges,
    softness_truth,
)
from simgap.diagnosis.hidden_effects import (
    CAMERA_NAMED,
    HIDDEN,
    REPORTED_AS,
    found,
    hides_catalogue_effects,
)
from simgap.diagnosis.nuisance import FRONTAL_HEAVY_STOPS_DEG, OBLIQUE_STOPS_DEG, NuisanceCamera
from simgap.diagnosis.result import DiagnosisResult
from simgap.diagnosis.trial_score import UNDECIDED, TrialRecord, TrialScore


def _magnitude(params: dict[str, Any], key: str) -> np.ndarray:
    return np.atleast_1d(np.asarray(params.get(key, 0.0), float))


#: The size a sun's azimuth error is relative to (deg): a quarter turn, the half-width of the
#: cosine lobe of an upright face it lights; its 25 % magnitude bar is 22.5 deg.
AZIMUTH_SCALE_DEG = 90.0

#: Bins of the per-nuisance score table (a trial's camera by the truths a diagnosis is scored
#: against): |exposure| (EV), softness (px), full well (e-).
EXPOSURE_BINS_EV = (0.5, 1.0)
SOFTNESS_BINS_PX = (0.2, 0.4)
FULL_WELL_BINS_E = (3000.0, 8000.0)
#: Ink reflectance of the print bins (%; the drawn range is 0.5-8, the simulation's 3).
INK_BINS_PCT = (2.0, 5.0)
#: Unsharp-mask amounts of the sharpening bins (the drawn range is 0.3-1.5).
SHARPEN_AMOUNT_BINS = (0.6, 1.0)


def _bin(value: float, edges: tuple[float, float], unit: str) -> str:
    lo, hi = edges
    if value < lo:
        return f"< {lo:g} {unit}"
    if value < hi:
        return f"{lo:g}-{hi:g} {unit}"
    return f">= {hi:g} {unit}"


#: Share of a tag's pixels at 0 DN from which a capture's blacks count as crushed.
CRUSHED_BLACK_SHARE = 0.1


def crushed_black_share(real: xr.Dataset) -> float | None:
    """The largest share of a tag's sticker pixels at 0 DN over a capture's frames (0-1).

    From the capture's own ``black_clipped_fraction`` statistic; None where the dataset has
    none (written before the statistic existed) or no tag was measured.
    """
    if "image_stats" not in real or "black_clipped_fraction" not in real.stat.values:
        return None
    values = real.image_stats.sel(stat="black_clipped_fraction").values
    return float(np.nanmax(values)) if np.isfinite(values).any() else None


def camera_named(
    crushed_black: float | None,
    light_spread_stops: float | None = None,
    edges_moved: bool = False,
) -> tuple[str, ...]:
    """Effects a diagnosis may name of a capture that was not hidden in it: the camera's own.

    Those every other camera has (:data:`~simgap.diagnosis.hidden_effects.CAMERA_NAMED`);
    where the capture's shadows are crushed (``crushed_black``, :func:`crushed_black_share`, at
    least the floor of ``black_clipped_fraction`` in
    :data:`~simgap.analysis.thresholds.IMAGE_FLOORS`), its black level; and where its lights
    light the tags unevenly against the simulation's (``light_spread_stops``,
    :func:`simgap.diagnosis.camera_truth.light_spread_truth`, at least the paper level's spread
    that calls for a light: :data:`~simgap.analysis.thresholds.SUN_MIN_GAIN_MISFIT`
    floors of ``paper_linear``), a light the simulation lacks (``sun``): its key light stands
    elsewhere, and the direction it lights the tags from is what the finding reads; and where
    its pipeline or print moves the markers' soft edges (``edges_moved``,
    :func:`simgap.diagnosis.camera_truth.moves_edges`), the edges' offset (``edge_offset``).
    """
    floor = image_floor("black_clipped_fraction")
    crushed = crushed_black is not None and crushed_black >= floor
    uneven = (
        light_spread_stops is not None
        and light_spread_stops >= SUN_MIN_GAIN_MISFIT * image_floor("paper_linear")
    )
    return (
        CAMERA_NAMED
        + (("black_level",) if crushed else ())
        + (("sun",) if uneven else ())
        + (("edge_offset",) if edges_moved else ())
    )


def pipeline_bins(camera: NuisanceCamera) -> dict[str, str]:
    """The camera's own image pipeline by stage: present (with its setting) or ``none``.

    Bins of the per-stage score table: demosaicing method, sharpening amount, denoising
    strength, black level, tone curve, lateral colour and frame-to-frame gain.
    """
    stages = camera.pipeline()

    def setting(name: str, text: str) -> str:
        return text if name in stages else "none"

    bayer = stages.get("bayer", {})
    return {
        "demosaicing": setting("bayer", str(bayer.get("method", ""))),
        "sharpening": setting(
            "sharpen",
            _bin(
                float(stages.get("sharpen", {}).get("amount", 0.0)), SHARPEN_AMOUNT_BINS, "amount"
            ),
        ),
        "denoising": setting("denoise", "bilateral"),
        "black level": setting("black_level", "subtracted"),
        "tone curve": setting("tone_curve", "S-curve"),
        "lateral colour": setting("chromatic_aberration", "present"),
        "gain changes": setting("gain_change", "present"),
    }


def _print_ink_bin(camera: NuisanceCamera) -> dict[str, str]:
    """The bin of the camera's print's ink reflectance (%); none where its print was not drawn.

    A camera drawn without a print of its own (``--nominal-print``, or a trial kept before
    prints were drawn) has no such bin, so that its kept score reads as it was written.
    """
    ink = camera.tag_print().get("ink")
    return {} if ink is None else {"print ink": _bin(100.0 * ink, INK_BINS_PCT, "%")}


def nuisance_bins(
    camera: NuisanceCamera,
    rig: Rig,
    crushed_black: float | None = None,
    measured_response: bool = False,
) -> dict[str, str]:
    """The camera's bin in each nuisance dimension.

    Exposure (through the camera's measured response where the capture was read through one,
    ``measured_response``), softness, noise, frames a pose, poses (mostly frontal or spread),
    where drawn the print's ink reflectance (:data:`INK_BINS_PCT`), the stages of the camera's
    own image pipeline (:func:`pipeline_bins`) and, where measured, whether the capture's blacks
    are crushed (:data:`CRUSHED_BLACK_SHARE`).
    """
    frontal = set(camera.theta_deg) <= {*FRONTAL_HEAVY_STOPS_DEG, *OBLIQUE_STOPS_DEG} and (
        sum(t not in FRONTAL_HEAVY_STOPS_DEG for t in camera.theta_deg) <= 1
    )
    bins = {
        "exposure": _bin(
            abs(exposure_truth(camera, rig, measured_response)), EXPOSURE_BINS_EV, "EV"
        ),
        "softness": _bin(softness_truth(camera), SOFTNESS_BINS_PX, "px"),
        "noise": _bin(camera.effects["sensor_noise"]["full_well_e"], FULL_WELL_BINS_E, "e-"),
        "frames": f"{camera.frames_per_pose} a pose",
        "poses": "mostly frontal" if frontal else "spread",
        **_print_ink_bin(camera),
        **pipeline_bins(camera),
    }
    if crushed_black is not None:
        crushed = crushed_black >= CRUSHED_BLACK_SHARE
        bins["crushed blacks"] = (
            f"{'>=' if crushed else '<'} {CRUSHED_BLACK_SHARE:.0%} of a tag at 0 DN"
        )
    return bins


@dataclass
class Trial:
    """One trial: what was hidden, the other camera, and what the diagnosis said.

    ``seconds``: its wall time (s); ``rig``: the rig its camera's truths are read on
    (:meth:`truth`; with ``camera``, needed for the nuisance bins).
    """

    index: int
    hidden: dict[str, dict[str, Any]]
    camera: NuisanceCamera | None = None
    result: DiagnosisResult = field(default_factory=DiagnosisResult)
    seconds: float = 0.0
    rig: Rig | None = None
    #: The largest share of a tag's pixels at 0 DN in the capture (0-1,
    #: :func:`crushed_black_share`).
    crushed_black_share: float | None = None

    def record(self) -> TrialRecord:
        """The trial as its file keeps it: draws, camera, score, diagnosis and seconds."""
        return TrialRecord(
            index=self.index,
            hidden_params=self.hidden,
            camera=self.camera,
            score=self.score(),
            result=self.result,
            seconds=self.seconds,
        )

    def truth(self) -> dict[str, tuple[dict[str, Any], dict[str, float]]]:
        """What a diagnosis should find, by the effect that names it: parameters and scales.

        Per effect: the parameters it should read, and per scored parameter the size an error is
        relative to. The hidden effects' own parameters (relative to themselves), except where
        the other camera has the same kind of effect (:data:`CAMERA_NAMED`): exposure reads the
        camera's total exposure (through its measured response where the capture was read
        through one, ``result.measured_response``) and blur its total softness
        (:func:`exposure_truth`,
        :func:`softness_truth`); a sun is read as its azimuth (the error the shorter way round,
        relative to :data:`AZIMUTH_SCALE_DEG`) and the irradiance an upright tag facing it gets
        (``E cos(elevation)``); a faulty calibration file is read as the lens it
        describes wrongly: no distortion, an error relative to the distortion the file claims
        (beside a hidden lens distortion: the lens's own, relative to itself).
        """
        out: dict[str, tuple[dict[str, Any], dict[str, float]]] = {}
        for name, params in self.hidden.items():
            if name not in HIDDEN:
                continue
            params = dict(params)
            if name == "faulty_calibration":
                if "lens_distortion" in self.hidden:
                    continue  # the lens as it is: its own distortion (scored below)
                scale = {"k1": abs(float(params["k1"]))}
                out[REPORTED_AS[name]] = ({"k1": 0.0}, scale)
                continue
            if name == "sun":  # what upright tags read of it (the sun candidate's parameters)
                elevation = np.radians(float(params["elevation_deg"]))
                horizontal = float(params["irradiance_w_m2"]) * float(np.cos(elevation))
                params = {
                    "azimuth_deg": float(params["azimuth_deg"]),
                    "horizontal_irradiance_w_m2": horizontal,
                }
                scales = {
                    "azimuth_deg": AZIMUTH_SCALE_DEG,
                    "horizontal_irradiance_w_m2": horizontal,
                }
                out[name] = (params, scales)
                continue
            if self.camera is not None and self.rig is not None:
                if name == "exposure":
                    measured = self.result.measured_response
                    params = {"ev": exposure_truth(self.camera, self.rig, measured)}
                if name == "blur":
                    params = {"sigma_px": softness_truth(self.camera, params["sigma_px"])}
            keys = HIDDEN[name][1]
            out[name] = (params, {k: float(np.linalg.norm(_magnitude(params, k))) for k in keys})
        return out

    def score(self) -> TrialScore:
        """How the diagnosis answered this trial (:class:`TrialScore` defines each value).

        Correct: every hidden catalogue effect is named (for a pair: at least one, and the
        recall says how many), and nothing is named that the capture does not have (a geometric
        or calibration effect that was not hidden; an appearance effect that neither was hidden
        nor is the camera's own, :func:`camera_named`); for an effect outside the catalogue,
        "unexplained" and no geometric effect; without a hidden effect, nothing but the camera's
        own appearance. A finding left undecided between look-alikes names none of them (no
        hit), and is spurious only where none of them is hidden or the camera's own. Magnitude
        errors are per scored parameter (``effect.parameter``), relative to :meth:`truth`'s
        scale.
        """
        selected = tuple(self.result.selected)
        findings = self.result.selection.findings if self.result.selection else []
        undecided = {f.effect: tuple(f.look_alikes) for f in findings if f.undecided}
        decided = tuple(e for e in selected if e not in undecided)
        hidden = tuple(self.hidden)
        named = {REPORTED_AS.get(h, h) for h in hidden}
        geometric = tuple(e for e in selected if e in geometric_effects())
        light_spread = (
            light_spread_truth(self.camera, self.rig) if self.camera and self.rig else None
        )
        edges_moved = self.camera is not None and moves_edges(self.camera)
        camera_own = camera_named(self.crushed_black_share, light_spread, edges_moved)
        spurious = tuple(
            e
            for e in selected
            if e not in named
            and e not in camera_own
            and not set(undecided.get(e, ())) & (named | set(camera_own))
        )
        own = [e for e in decided if e in named or e not in camera_own]
        catalogue = hides_catalogue_effects(hidden)
        hits = [found(h, decided) for h in hidden] if catalogue else []
        if not hidden:
            correct = not spurious
        elif not catalogue:
            correct = self.result.unexplained and not geometric
        else:
            correct = (all(hits) if len(hidden) == 1 else any(hits)) and not spurious
        combined, confirmed = self.result.combined, self.result.confirmed
        if confirmed is not None:
            reduction: float | None = confirmed.pose_gap_reduction
        else:
            reduction = combined.scores.pose_gap_reduction if combined else None
        return TrialScore(
            hidden=hidden,
            selected=selected,
            top1=own[0] if own else (decided[0] if decided else UNDECIDED if undecided else "none"),
            unexplained=self.result.unexplained,
            geometric_selected=geometric,
            spurious=spurious,
            on_bound=tuple(self.result.selected_on_bound()),
            nuisance_bins=(
                nuisance_bins(
                    self.camera,
                    self.rig,
                    self.crushed_black_share,
                    self.result.measured_response,
                )
                if self.camera and self.rig
                else {}
            ),
            correct=correct,
            recall=sum(hits) / len(hidden) if catalogue else None,
            magnitude_error=self._magnitude_errors() if catalogue else {},
            pose_gap_reduction=reduction if catalogue else None,
            pose_gap_reduction_interval_90=(
                combined.pose_gap_reduction_interval_90 if catalogue and combined else None
            ),
            crushed_black_share=self.crushed_black_share,
            undecided=undecided,
        )

    def _magnitude_errors(self) -> dict[str, float]:
        """Per scored parameter of each named hidden effect: its error relative to the truth's.

        Keys ``effect.parameter``; the distance between the fitted and the true values over
        :meth:`truth`'s scale.
        """
        selection = self.result.selection
        fitted = {f.effect: f.params for f in selection.findings} if selection else {}
        errors = {}
        for name, (params, scales) in self.truth().items():
            if name not in fitted:
                continue
            for key, scale in scales.items():
                error = _magnitude(fitted[name], key) - _magnitude(params, key)
                if key == "azimuth_deg":  # the shorter way round
                    error = (error + 180.0) % 360.0 - 180.0
                errors[f"{name}.{key}"] = float(np.linalg.norm(error) / scale)
        return errors
