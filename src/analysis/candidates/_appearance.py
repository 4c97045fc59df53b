"""Appearance candidates: effects that change what the camera sees, fitted on image evidence.

Each candidate's parameters are fitted continuously so that the image statistics of the
simulation with the effect (:mod:`simgap.pose.image_stats`) match the real ones on the fit split;
the candidates and the statistics each is fitted on are listed in
:data:`simgap.analysis.candidates.CANDIDATES`:

==================  =====================================  =====================================
effect              parameters (bounds)                    fitted on
==================  =====================================  =====================================
``blur``            ``sigma_px`` (0.05 - 3 px)             edge width; pipeline re-run per value
``exposure``        ``ev`` (-4 - 4 stops)                  paper level (ink near black is flare
                                                           and print, not exposure): median
                                                           of the tags' ratios, clipped ones
                                                           censored (:mod:`~.exposure`)
``black_level``     ``level`` (0.001 - 0.15 of full        share of a tag's pixels at 0 DN
                    scale)                                 (the camera's crushed shadows)
``sensor_noise``    ``full_well_e``, ``read_noise_e``      photon transfer of the excess noise
                                                           variance (EMVA 1288), least squares
                                                           (:mod:`simgap.analysis.candidates._sensor_noise`)
``defocus``         ``aperture_radius_m``,                 edge width against tag depth, thin-
                    ``focus_distance_m``                   lens blur circle, least squares
                                                           (:mod:`simgap.analysis.candidates._defocus`)
``jpeg``            ``quality`` (5 - 100, integer)         the DC quantisation step of the 8 px
                                                           blocks, else their blockiness;
                                                           pipeline re-run per value
``tag_gloss``       ``alpha`` (0.01 - 0.6), the light's    ink and paper levels against the
                    ``light_intensity_w_sr`` and offsets   half-angle of lens and light (glint
                    (+-0.15 m)                             of a laminate), least squares
                                                           (:mod:`simgap.analysis.candidates._gloss`)
==================  =====================================  =====================================

Image-stage effects (blur, exposure, black level, noise, JPEG) re-process the cached renders;
defocus and the laminate are fitted on the evidence with a physical model and then rendered for
scoring (their change of corners, pose, statistics and detections comes from the full pipeline, like
every candidate's). This module holds the generic one-parameter candidate (a bounded scalar search)
and the gates every appearance candidate passes: the capture must show its signature
(:meth:`AppearanceCandidate.signature_shown`; by default its own statistics differ
significantly, :func:`signature_significant`) and its fit must explain them
(:func:`signature_supported`).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from simgap.analysis.candidates._fitting import Fit, SimulationCandidate, on_bound
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.gap import ImageTest, Items, compare_stat
from simgap.analysis.thresholds import (
    IMAGE_FLOORS,
    RESIDUAL_CAP,
    SIGNATURE_MIN_GAIN,
    SIGNATURE_MIN_MISFIT,
)
from simgap.effects.state import VariantState
from simgap.pose.image_stats import EDGE_WIDTH_STATS, STAT_INDEX
from simgap.pose.jpeg_blocks import quality_for_dc_step

#: Points of the coarse scan that brackets a 1-D fit before the bounded Brent search.
SCAN_POINTS = 16
#: Fewest tags that agree on a DC quantisation step (and at least half of the tags that show one)
#: for the JPEG quality to be read from it. Tags agree or show none: measured on development
#: captures, a quarter to all of a compressed capture's tags showed the true step and no other,
#: the rest none (bright paper and soft edges leave too few distinct unclipped blocks), and no
#: tag of an uncompressed capture showed one (docs/results/design_evidence.md#appearance).
MIN_STEP_TAGS = 3


def evidence_misfit(stats: tuple[str, ...], real: np.ndarray, pred: np.ndarray) -> float:
    """Mean over statistics of the mean squared per-tag misfit in floors, capped (dimensionless).

    Parameters
    ----------
    stats : tuple of str
        Statistic names (see :data:`simgap.analysis.thresholds.IMAGE_FLOORS`).
    real, pred : ndarray (N, S)
        Real and predicted image statistics of the same tags.
    """
    total = []
    for stat in stats:
        i = STAT_INDEX[stat]
        square = capped_mean_square(
            compare_stat(stat, real[:, i], pred[:, i]) / IMAGE_FLOORS[stat][1]
        )
        if np.isfinite(square):
            total.append(square)
    return float(np.mean(total)) if total else float("nan")


def misfit_rms(stats: tuple[str, ...], real: np.ndarray, pred: np.ndarray) -> float:
    """Square root of :func:`evidence_misfit` (floors); 0 when no statistic is measured."""
    return float(np.sqrt(np.nan_to_num(evidence_misfit(stats, real, pred))))


def capped_mean_square(residual: np.ndarray) -> float:
    """Mean of the squared finite residuals (floors), each capped (NaN when none is finite).

    The cap is :data:`~simgap.analysis.thresholds.RESIDUAL_CAP`.
    """
    r = residual[np.isfinite(residual)]
    return float(np.mean(np.minimum(r**2, RESIDUAL_CAP**2))) if r.size else float("nan")


def capped_rms(residual: np.ndarray) -> float:
    """Square root of :func:`capped_mean_square` (floors); 0 when no residual is finite."""
    return float(np.sqrt(np.nan_to_num(capped_mean_square(residual))))


def measuring_only(state: VariantState, stats: tuple[str, ...]) -> VariantState:
    """``state`` with only the edge widths among ``stats`` fitted in its image statistics.

    The edge-spread fits are most of the statistics' time; a search that reads levels, noise or
    blockiness (exposure, JPEG) skips them, and blur skips the all-sides width it does not read.
    The statistics it reads are the same numbers either way.
    """
    widths = tuple(name for name in EDGE_WIDTH_STATS if name in stats)
    estimation = dataclasses.replace(state.estimation, edge_widths=widths)
    return dataclasses.replace(state, estimation=estimation)


def signature_supported(rms_before: float, rms_after: float) -> bool:
    """Whether an effect's own statistics call for it.

    ``rms_before`` and ``rms_after`` are their RMS misfits (floors) before and after the fit; see
    :data:`~simgap.analysis.thresholds.SIGNATURE_MIN_MISFIT` and
    :data:`~simgap.analysis.thresholds.SIGNATURE_MIN_GAIN`.
    """
    return rms_before >= SIGNATURE_MIN_MISFIT and rms_before - rms_after >= SIGNATURE_MIN_GAIN


def signature_significant(candidate: Any, image_tests: list[ImageTest]) -> bool:
    """Whether one of the candidate's own statistics (``fit_stats``) differs significantly.

    ``image_tests`` are the where-step's paired tests over every comparable tag
    (:func:`simgap.analysis.gap.image_tests`). Candidates without own statistics (the
    geometric and calibration ones) always pass.
    """
    own = candidate.fit_stats
    return not own or any(test.significant for test in image_tests if test.stat in own)


class AppearanceCandidate(SimulationCandidate):
    """An effect fitted on image evidence (see module docstring).

    Parameters
    ----------
    effect : str
        Catalogue name.
    fit_stats : tuple of str
        The image statistics it is fitted on, its signature (:func:`signature_significant`).
    param : str
        The parameter fitted by a bounded scalar search (1-D candidates).
    bounds : tuple of float
        Search interval of ``param``.
    xatol : float
        Absolute tolerance of the search.
    """

    kind = "appearance"
    n_params = 1

    def __init__(
        self,
        effect: str,
        fit_stats: tuple[str, ...],
        param: str,
        bounds: tuple[float, float],
        xatol: float,
    ) -> None:
        super().__init__(effect)
        self.fit_stats = fit_stats
        self.param, self.bounds, self.xatol = param, bounds, xatol

    def signature_shown(self, image_tests: list[ImageTest], runner: Runner, items: Items) -> bool:
        """Whether the capture shows this effect's signature, so that it is a candidate.

        ``image_tests`` are the where step's tests over every comparable tag and ``items`` those
        tags; by default one of the effect's own statistics differs significantly
        (:func:`signature_significant`).
        """
        return signature_significant(self, image_tests)

    def params(self, x: float) -> dict[str, Any]:
        """Effect parameters for a value of the fitted parameter."""
        return {self.param: float(x)}

    def misfit(self, runner: Runner, base: VariantState, items: Items, x: float) -> float:
        """Misfit of the fit statistics with the parameter at ``x`` (:func:`evidence_misfit`)."""
        state = measuring_only(self.apply(base, self.params(x)), self.fit_stats)
        return evidence_misfit(
            self.fit_stats, items.required("real_stats"), runner.stats(state, items)
        )

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """Bounded scalar search of the parameter that best matches the image evidence."""
        t0 = time.perf_counter()
        grid, values = self.scan(runner, base, items)
        return self.refine(runner, base, items, grid, values, t0)

    def scan(
        self, runner: Runner, base: VariantState, items: Items
    ) -> tuple[np.ndarray, np.ndarray]:
        """The misfit at :data:`SCAN_POINTS` values evenly over the bounds (grid, misfits)."""
        grid = np.linspace(*self.bounds, SCAN_POINTS)
        return grid, np.array([self.misfit(runner, base, items, x) for x in grid])

    def refine(
        self,
        runner: Runner,
        base: VariantState,
        items: Items,
        grid: np.ndarray,
        values: np.ndarray,
        t0: float,
    ) -> Fit:
        """The fit refined by a bounded Brent search around the scan's (``grid``) minimum.

        The misfit is capped and can be flat far from its minimum: the coarse scan brackets the
        minimum. ``t0``: ``time.perf_counter()`` at the fit's start. Where no scanned misfit is
        finite (no item carries the statistics) the fit is not supported, at the searched value
        nearest no effect.
        """
        if not np.isfinite(values).any():
            # no item has the statistics: nothing fitted, at the searched value nearest none (a
            # blur's range starts above 0 px, which is no valid blur)
            rest = float(np.clip(0.0, *self.bounds))
            return Fit(
                self.effect, self.params(rest), time.perf_counter() - t0, {"supported": False}
            )
        k = int(np.nanargmin(values))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        sol = minimize_scalar(
            lambda x: self.misfit(runner, base, items, x),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": self.xatol},
        )
        x, fun = (sol.x, sol.fun) if sol.fun <= values[k] else (grid[k], values[k])
        return self.fitted(items, x, fun, t0)

    def fitted(self, items: Items, x: float, fun: float, t0: float, **extra: Any) -> Fit:
        """The fit at ``x`` whose misfit is ``fun``, with its support and bound flags.

        ``t0``: ``time.perf_counter()`` at the fit's start; ``extra``: more ``Fit.extra`` entries.
        """
        before = evidence_misfit(
            self.fit_stats, items.required("real_stats"), items.required("sim_stats")
        )
        rms_before = float(np.sqrt(np.nan_to_num(before)))  # misfit_rms, without a second pass
        return Fit(
            self.effect,
            self.params(x),
            time.perf_counter() - t0,
            {
                "train_misfit": float(fun),
                "train_misfit_before": float(before),
                "supported": signature_supported(rms_before, float(np.sqrt(fun))),
                "at_bound": (self.param,) if on_bound(x, *self.bounds) else (),
                **extra,
            },
        )


class JpegCandidate(AppearanceCandidate):
    """JPEG compression: the integer quality (libjpeg scale) of the capture's quantiser.

    Where at least :data:`MIN_STEP_TAGS` tags, and half of those that show one, agree on a DC
    quantisation step (``jpeg_dc_step_dn``, :mod:`simgap.pose.jpeg_blocks`), the quality is the
    libjpeg quality of that step: the quantiser is read back, whatever the camera's noise and
    softness (read from the blockiness instead, qualities were off by 10-40 on blind captures:
    docs/results/design_evidence.md#appearance). Else it is searched on the blockiness: the
    block-boundary steps over the others, the others mostly the camera's noise (a noisy camera's
    JPEG reads less blocky than a clean render's at the same quality). With ``noise`` (the
    sensor-noise candidate) the blockiness is matched on the simulation with the capture's own
    sensor noise, fitted first from the noise statistics where that fit is supported (fitted on
    clean renders, qualities 29 and 46 had read 55 and 56).
    """

    def __init__(self, *args: Any, noise: AppearanceCandidate | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.noise = noise

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """The quality of the capture's DC step, or whose blockiness matches (see class doc)."""
        t0 = time.perf_counter()
        step, tags = agreed_dc_step(items.required("real_stats")[:, STAT_INDEX["jpeg_dc_step_dn"]])
        if tags:
            # the quantiser read back; the capture's noise is then no sensor's to add
            # (simgap.analysis.candidates._sensor_noise: not supported under a JPEG quantiser)
            quality = quality_for_dc_step(step)
            fun = self.misfit(runner, base, items, quality)
            return self.fitted(items, quality, fun, t0, dc_step_dn=step, tags=tags)
        if self.noise is not None:
            noise = self.noise.fit(runner, base, items)
            if noise.extra.get("supported", False):
                base = self.noise.apply(base, noise.params)
        return super().fit(runner, base, items)

    def params(self, x: float) -> dict[str, Any]:
        """Effect parameters: the quality rounded to an integer."""
        return {self.param: int(round(float(x)))}


def capture_jpeg_quality(real_stats: np.ndarray) -> int | None:
    """The libjpeg quality of the DC quantiser the capture's tags agree on, or None.

    Parameters
    ----------
    real_stats : ndarray (N, S)
        The capture's image statistics; its ``jpeg_dc_step_dn`` (DN) per tag is read
        (:func:`agreed_dc_step`).

    Returns
    -------
    int or None
        The quality (libjpeg scale, 1-100) of the agreed step
        (:func:`simgap.pose.jpeg_blocks.quality_for_dc_step`); None where no step is agreed: no
        compression, or one finer than the smallest step read
        (:data:`simgap.pose.jpeg_blocks.DC_STEPS`).
    """
    step, tags = agreed_dc_step(real_stats[:, STAT_INDEX["jpeg_dc_step_dn"]])
    return quality_for_dc_step(step) if tags else None


def agreed_dc_step(steps: np.ndarray) -> tuple[float, int]:
    """The DC quantisation step the tags agree on (DN), and how many tags show it.

    ``steps``: per tag, its ``jpeg_dc_step_dn`` (NaN where it shows none). The most common step
    when at least :data:`MIN_STEP_TAGS` tags, and half of those that show a step, show it; else
    ``(nan, 0)``.
    """
    values, counts = np.unique(steps[np.isfinite(steps)], return_counts=True)
    if counts.size and counts.max() >= max(MIN_STEP_TAGS, counts.sum() / 2):
        return float(values[np.argmax(counts)]), int(counts.max())
    return float("nan"), 0
