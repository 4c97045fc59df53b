"""A distant light the simulation lacks (a sun), fitted on the tags' paper levels against facing.

The appearance candidate ``sun`` (:class:`SunCandidate`): a distant light from a direction of
the rail frame (:class:`simgap.effects.scene.Sun`) that the simulation does not have, read from
how much brighter each tag's paper is than simulated against the way the tag faces.

How it is fitted (then rendered once for scoring, like
:mod:`simgap.analysis.candidates._defocus` and :mod:`~simgap.analysis.candidates._gloss`):

1. **Levels.** Per tag of the fit split whose real paper is a level (neither clipped nor crushed,
   :data:`~simgap.analysis.candidates._tag_levels.CLIPPED_DN`), the log ratio
   ``y = log2(real paper / simulated paper)`` (stops), the direct irradiance ``E_lab`` the
   simulation's own lights give its face (:meth:`simgap.analysis.candidates.Runner.irradiance`,
   W m^-2) and its normal ``n`` in the rail frame.
2. **The sun model:** ``y = g + log2(1 + E_h max(0, n . s) / E_lab)``, ``s`` the horizontal
   direction to the sun at azimuth ``a`` (rail frame, as :class:`~simgap.effects.scene.Sun`),
   ``E_h`` the irradiance it gives an upright surface facing it (W m^-2) and ``g`` the capture's own
   exposure (stops). The fixture's tags stand upright, so their levels tell the azimuth and
   ``E_h`` and not the elevation (``E_h = E cos(elevation)``); robust least squares in the
   paper's floor (:data:`~simgap.analysis.thresholds.IMAGE_FLOORS`) from every azimuth of a
   coarse scan, then refined.
3. **Its alternatives**, what moves the papers of tags unevenly without a light: one gain (the
   exposure) and a transfer curve (``y = g + b log2(simulated paper)``: a gamma, a tone curve or
   a black level takes more off darker tags, and the tags facing the simulation's key light are
   the bright ones).
4. **Supported** where one gain leaves at least
   :data:`~simgap.analysis.thresholds.SUN_MIN_GAIN_MISFIT` and the sun explains the
   levels better than the best alternative by
   :data:`~simgap.analysis.thresholds.SIGNATURE_MIN_GAIN` (RMS over the tags, floors). The
   transfer curve is not held to half a floor: where the simulation's key light lights the
   tags facing away from the sun the brightest, the curve follows a sun's levels to within half
   a floor, yet a sun that fits them several times better is the light the curve stands in for
   (docs/results/sun_diagnosis.md). This is also its signature
   (:meth:`SunCandidate.signature_shown`, on every comparable tag): a light on some faces moves
   the median paper level little, so a significant median difference is no condition.
5. **Rendered** as the :class:`~simgap.effects.scene.Sun` at :data:`RENDER_ELEVATION_DEG` with
   ``E = E_h / cos(elevation)`` and the exposure ``g`` (added to any exposure the model already
   holds), so that the candidate is judged with the exposure it was fitted with. The paper
   level's spread over the tags (:func:`simgap.analysis.gap.level_spread`) is the channel that
   credits it.

A light elsewhere in the room (another key light's place) lights the upright tags the same way
as a distant one from its direction: the finding is the light's direction and its irradiance on
the tags, whatever the source.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from simgap.analysis.candidates._appearance import AppearanceCandidate, capped_rms
from simgap.analysis.candidates._fitting import Fit, on_bound
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.candidates._tag_levels import CLIPPED_DN
from simgap.analysis.gap import ImageTest, Items
from simgap.analysis.thresholds import (
    IMAGE_FLOORS,
    SIGNATURE_MIN_GAIN,
    SUN_MIN_GAIN_MISFIT,
)
from simgap.effects import make_effect
from simgap.effects.state import VariantState
from simgap.pose.image_stats import STAT_INDEX

#: Searched range of the horizontal irradiance (W m^-2): up to 100x the simulation's own key
#: light at a frontal tag (a few W m^-2), far below the sun's 1361 W m^-2, which no camera
#: exposed for a lab light would show as anything but clipped paper.
IRRADIANCE_W_M2: tuple[float, float] = (0.0, 300.0)
#: Azimuths of the coarse scan (deg, every 15: a quarter of the width of a face's cosine lobe).
SCAN_AZIMUTHS_DEG = np.arange(0.0, 360.0, 15.0)
#: Elevation the fitted sun is rendered at (deg): upright tags do not tell it (module
#: docstring); 20 deg keeps the table's bounce, which reaches every tag, under E_h sin(20) /
#: cos(20) = 0.36 E_h on the table, and casts no shadow of the camera over the tags it faces.
RENDER_ELEVATION_DEG = 20.0
#: Fewest tags with a paper level for a fit: three parameters and three more.
MIN_SUN_TAGS = 6


@dataclass(frozen=True)
class PaperLevels:
    """What the sun model reads of each tag (module docstring, step 1).

    Attributes
    ----------
    log_ratio : ndarray (N,)
        ``log2(real paper / simulated paper)`` (stops).
    sim_paper : ndarray (N,)
        Simulated linear paper level (fraction of full scale).
    irradiance : ndarray (N,)
        Direct irradiance of the simulation's lights on the tag's face (W m^-2).
    normal : ndarray (N, 3)
        The tag's unit normal in the rail frame.
    """

    log_ratio: np.ndarray
    sim_paper: np.ndarray
    irradiance: np.ndarray
    normal: np.ndarray

    @classmethod
    def of(cls, runner: Runner, items: Items) -> PaperLevels:
        """The levels of ``items`` whose real paper is a level (module docstring, step 1)."""
        real, sim = items.required("real_stats"), items.required("sim_stats")
        i_lin, i_dn = STAT_INDEX["paper_linear"], STAT_INDEX["paper_dn"]
        irradiance = runner.irradiance(items)
        normal = runner.rail_from_tag(items)[:, :3, 2]
        ok = (
            np.isfinite(real[:, i_lin])
            & np.isfinite(sim[:, i_lin])
            & (real[:, i_lin] > 0)
            & (sim[:, i_lin] > 0)
            & (real[:, i_dn] > CLIPPED_DN[0])
            & (real[:, i_dn] < CLIPPED_DN[1])
            & (irradiance > 0)
        )
        return cls(
            np.log2(real[ok, i_lin] / sim[ok, i_lin]), sim[ok, i_lin], irradiance[ok], normal[ok]
        )

    def __len__(self) -> int:
        return len(self.log_ratio)


@dataclass(frozen=True)
class SunFit:
    """The sun model and its alternatives fitted on :class:`PaperLevels` (module docstring).

    Attributes
    ----------
    azimuth_deg : float
        Direction to the sun (deg, rail frame, in [0, 360)).
    horizontal_irradiance_w_m2 : float
        ``E_h`` (W m^-2).
    ev : float
        The capture's exposure fitted with it (stops).
    rms_sun, rms_gain, rms_transfer : float
        RMS misfit of the levels (floors) of the sun model, one gain and a transfer curve.
    tags : int
        Tags fitted.
    """

    azimuth_deg: float
    horizontal_irradiance_w_m2: float
    ev: float
    rms_sun: float
    rms_gain: float
    rms_transfer: float
    tags: int

    @property
    def rms_alternative(self) -> float:
        """The best alternative's RMS misfit (floors)."""
        return min(self.rms_gain, self.rms_transfer)

    @property
    def supported(self) -> bool:
        """The levels call for a sun (module docstring, step 4)."""
        return (
            self.rms_gain >= SUN_MIN_GAIN_MISFIT
            and self.rms_alternative - self.rms_sun >= SIGNATURE_MIN_GAIN
        )


def facing(normal: np.ndarray, azimuth_deg: float) -> np.ndarray:
    """``max(0, n . s)`` per tag for the horizontal direction ``s`` to a sun at ``azimuth_deg``."""
    a = np.radians(azimuth_deg)
    return np.clip(normal @ np.array([np.sin(a), np.cos(a), 0.0]), 0.0, None)


def fit_sun(levels: PaperLevels) -> SunFit | None:
    """The sun model and its alternatives (module docstring, steps 2-3); None on too few tags."""
    if len(levels) < MIN_SUN_TAGS:
        return None
    floor = IMAGE_FLOORS["paper_linear"][1]
    y = levels.log_ratio

    def sun_residual(x: np.ndarray) -> np.ndarray:
        lit = x[1] * facing(levels.normal, x[2]) / levels.irradiance
        return (x[0] + np.log2(1.0 + lit) - y) / floor

    gain = least_squares(lambda x: (x[0] - y) / floor, x0=[float(np.median(y))], loss="soft_l1")
    level = np.log2(levels.sim_paper)
    transfer = least_squares(
        lambda x: (x[0] + x[1] * (level - np.median(level)) - y) / floor,
        x0=[float(np.median(y)), 0.0],
        loss="soft_l1",
    )
    lower, upper = (-8.0, IRRADIANCE_W_M2[0], -720.0), (8.0, IRRADIANCE_W_M2[1], 720.0)
    # the sun only adds light, so the exposure starts at the darkest tag's ratio; one tag's
    # paper can read darker than the searched range (an outlier the soft loss then discounts),
    # and every start lies inside the bounds
    start_ev = float(np.clip(np.min(y), lower[0], upper[0]))
    start_irradiance = float(np.clip(np.median(levels.irradiance), lower[1], upper[1]))
    best = min(
        (
            least_squares(
                sun_residual,
                x0=[start_ev, start_irradiance, float(azimuth)],
                bounds=(lower, upper),
                loss="soft_l1",
            )
            for azimuth in SCAN_AZIMUTHS_DEG
        ),
        key=lambda sol: sol.cost,
    )
    return SunFit(
        azimuth_deg=float(best.x[2] % 360.0),
        horizontal_irradiance_w_m2=float(best.x[1]),
        ev=float(best.x[0]),
        rms_sun=capped_rms(sun_residual(best.x)),
        rms_gain=capped_rms((gain.x[0] - y) / floor),
        rms_transfer=capped_rms(transfer.fun),
        tags=len(levels),
    )


def sun_effects(params: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The scene effect of a ``sun`` finding: the sun at :data:`RENDER_ELEVATION_DEG`.

    ``params``: ``azimuth_deg`` and ``horizontal_irradiance_w_m2``; the rendered irradiance on a
    surface facing the sun is ``E_h / cos(elevation)``.
    """
    elevation = RENDER_ELEVATION_DEG
    return {
        "sun": {
            "azimuth_deg": float(params["azimuth_deg"]),
            "elevation_deg": elevation,
            "irradiance_w_m2": float(params["horizontal_irradiance_w_m2"])
            / float(np.cos(np.radians(elevation))),
        }
    }


class SunCandidate(AppearanceCandidate):
    """A distant light the simulation lacks, from the paper levels against facing (module doc)."""

    n_params = 3

    def __init__(self) -> None:
        super().__init__(
            "sun", ("paper_linear",), "horizontal_irradiance_w_m2", IRRADIANCE_W_M2, 0.0
        )

    def signature_shown(self, image_tests: list[ImageTest], runner: Runner, items: Items) -> bool:
        """Whether the levels of every comparable tag call for a sun (module docstring, step 4).

        ``image_tests`` are not read: a light on some faces can leave the median paper level
        where it was.
        """
        if items.real_stats is None or items.sim_stats is None:
            return False
        fit = fit_sun(PaperLevels.of(runner, items))
        return fit is not None and fit.supported

    def apply(self, base: VariantState, params: dict[str, Any]) -> VariantState:
        """The state with the sun and the exposure it was fitted with (``ev``, added)."""
        state = base
        effects = sun_effects(params)
        effects["exposure"] = {"ev": float(params.get("ev", 0.0))}
        for name, values in effects.items():
            state = make_effect(name, values).apply(state)
        return state

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """The sun model on the fit split (module docstring)."""
        t0 = time.perf_counter()
        fit = fit_sun(PaperLevels.of(runner, items))
        if fit is None:
            params = {"azimuth_deg": 0.0, "horizontal_irradiance_w_m2": 0.0, "ev": 0.0}
            return Fit(self.effect, params, time.perf_counter() - t0, {"supported": False})
        params = {
            "azimuth_deg": fit.azimuth_deg,
            "horizontal_irradiance_w_m2": fit.horizontal_irradiance_w_m2,
            "ev": fit.ev,
        }
        top = IRRADIANCE_W_M2[1]
        at_bound = (
            ("horizontal_irradiance_w_m2",)
            if on_bound(fit.horizontal_irradiance_w_m2, -top, top)
            else ()
        )
        return Fit(
            self.effect,
            params,
            time.perf_counter() - t0,
            {
                "supported": fit.supported,
                "tags": fit.tags,
                "level_rms_sun": fit.rms_sun,
                "level_rms_gain": fit.rms_gain,
                "level_rms_transfer": fit.rms_transfer,
                "at_bound": at_bound,
            },
        )
