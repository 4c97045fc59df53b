"""A glossy laminate under a light beside the lens, fitted on ink and paper levels against view.

The appearance candidate ``tag_gloss`` (:class:`GlossCandidate`): the tag print under a rough
dielectric coating (:class:`simgap.effects.scene.TagGloss`, Beckmann roughness ``alpha``, the
distribution of Mitsuba's ``roughplastic``) lit by a small light on the camera
(:class:`simgap.effects.scene.CameraLight`: intensity in W sr^-1, offset from the lens in m).
The pair: a laminated sticker mirrors a lens-side LED straight back into the lens at frontal
views, so near frontal tags glint, lose contrast or clip and are lost to the detector, while
oblique ones look as simulated. A laminate seldom sends a lab light into the
lens; a light on the camera over matte prints only brightens near tags (no glint).

How it is fitted (then rendered once for scoring, like :mod:`simgap.analysis.candidates._defocus`):

1. **Levels.** Per tag of the fit split, the real and the simulated (matte, the simulation's
   lights) linear ink and paper levels (:class:`TagLevels`). A clipped real paper is a lower
   bound of its level only, a real ink crushed to 0 DN an upper bound: the tags a black level
   crushed tell it from a darker print, which darkens every tag's ink by the same factor.
2. **The level model** (:func:`predicted_levels`): ``paper = K(G (q + a L + b S))`` and
   ``ink = K(G (h i (1 + a L / q) + b S))``, with ``q, i`` the simulated paper and ink, ``G`` the
   exposure, ``h`` what a transfer curve or a darker print does to dark ink, ``K(v) = max(v -
   k, 0) / (1 - k)`` the camera's black level ``k`` (:func:`simgap.effects.camera_pipeline.
   crushed`: a median commutes with it), ``L = cos(theta_l) / d^2`` the
   light's diffuse geometry, and the glint ``S = D(theta_h; alpha) / (d^2 cos(theta_o))``: a
   mirror reflection adds the same radiance to ink and paper (Walter et al. 2007; Fresnel and
   shadowing near constant over a rough coating's lobe). ``theta_h`` is the angle between the
   tag's normal and the half vector of the directions to the lens and to the light, ``theta_o``
   the view angle, ``d`` the distance to the light (nominal rig). Residuals are log levels in
   the floors of :data:`~simgap.analysis.thresholds.IMAGE_FLOORS`; bounded robust least
   squares fit exposure alone, then a matte light (``a``), then the laminate (``b``,
   ``alpha`` and the light's offset, from six starts) (:func:`fit_levels`); ``G``, ``h`` and
   ``k`` are free in each. A light's offset fitted onto the end of its range is kept only where
   the levels ask for it: otherwise the fit with the light held on the camera body
   (:func:`~simgap.analysis.candidates.held_inside`; two blind laminates on mostly frontal or
   tone-curved captures ran to 15 cm where a light 5 cm from the lens fitted as well,
   docs/results/laminate.md). A black level takes the same level off ink and paper, so it crushes
   the ink and leaves a glint standing on it; ``h`` alone would darken the glint with the ink and
   an exposure stops too low would make up for it (docs/results/laminate.md).
3. **Geometry from the ink-to-paper ratios** where at least
   :data:`~simgap.analysis.candidates.MIN_TAGS` tags have unclipped ink and paper
   (:mod:`simgap.analysis.candidates._glint_ratio`: the capture's own lights cancel in a ratio, a
   glint does not): roughness and the light's horizontal offset, its height not fitted; the level
   model then fits only its scales at that geometry. With fewer (an overexposed capture), the
   level model's own geometry.
4. **Supported** where the glint explains the ratios better than flare and a constant ratio
   by :data:`GLINT_MIN_GAIN` (with too few unclipped papers: where the laminate explains the
   levels better than a matte light by as much), and the light it mirrors has an intensity
   (step 5, at least :data:`MIN_INTENSITY_W_SR`: without one, the coating's veil alone stood in
   for a print's brighter ink on a blind capture with nothing hidden,
   docs/results/design_evidence.md#gloss): a glint that follows the half-angle is the
   laminate's signature (that a level differs at all is the where step's test, which makes it
   a candidate). Three glinting tags of nineteen are 0.95 floors RMS under exposure alone: an
   RMS gate on the levels would miss them.
5. **Intensity.** ``a`` and ``b`` are in the simulation's linear units; one render of the fit
   split with the fitted laminate and a light of :data:`REFERENCE_INTENSITY_W_SR` is fitted with
   the same roughness and offset, each scale over its rendered one estimates the intensity (a
   glint and a light are linear in the intensity; the ratios' glint scale gives a third), and a
   few renders around the estimates pick the intensity whose levels and detections match
   (:meth:`GlossCandidate.intensity`).
6. **Exposure, ink and black level.** The candidate carries the exposure ``G`` it was fitted
   with (``ev``), the ink factor ``h`` (``ink_factor``) and the black level ``k``
   (``black_level``), rendered as the camera's black level where no other effect of the model
   brings one. Where ``h`` is below 1 it is rendered as the
   print's ink albedo times ``h``: in the levels a darker print, a black level and a tone curve
   that darkens the ink look alike, and the albedo is the one of them that lowers the ink and
   leaves the glint on top of it. Without it the rendered glint lifts ink that the capture's
   camera took back, and a right laminate scored worse than none (docs/results/laminate.md). An
   ``h`` above 1 (ink brighter than simulated) is what a veil, flare or transfer curve adds; the
   laminate's render adds its own veil, so it is not rendered (a brighter ink would stand in for
   the glint). The laminate is thus judged with the camera's nuisance it was fitted with.
7. **Beyond its nuisance.** The same nuisance rendered without the laminate (the exposure, the
   black level and the print's ink albedo times ``h``, either way) must match the levels and
   detections worse, by :data:`GLINT_MIN_GAIN` in RMS floors (:func:`laminate_explains`): a
   print whose ink is darker or brighter than simulated is what every drawn print is, and a
   laminate that only carries that (its fitted light a few hundredths of a W/sr, its ink
   factor or its veil taking the print's ink) is no laminate (docs/results/laminate.md).

Only tags near the half-angle's zero (the frontal stops) sample the lobe's width: with few of
them roughness, offset and intensity trade off (development captures: roughness within 1.6x).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from simgap.analysis.candidates._appearance import (
    AppearanceCandidate,
    capped_rms,
    evidence_misfit,
    measuring_only,
)
from simgap.analysis.candidates._black_level import LEVEL_BOUNDS
from simgap.analysis.candidates._fitting import Fit, on_bound
from simgap.analysis.candidates._glint_ratio import (
    HELD_OFFSETS_M,
    STARTS,
    RatioFit,
    fit_ratios,
    held_inside,
)
from simgap.analysis.candidates._lobe import LAMINATE_IOR, MIN_COS, beckmann, lobe_geometry
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.candidates._subset_fit import fit_subset
from simgap.analysis.candidates._tag_levels import TagLevels
from simgap.analysis.gap import ImageTest, Items, detection_groups, detection_score
from simgap.analysis.thresholds import IMAGE_FLOORS, RESIDUAL_CAP, SIGNATURE_MIN_GAIN
from simgap.effects import make_effect
from simgap.effects.camera_pipeline import crushed
from simgap.effects.state import VariantState

#: Searched ranges: laminate roughness (dimensionless; below 0.01 a glint is a mirror image of
#: the LED a few pixels wide, above 0.6 the coating's reflection is spread like paper's) and the
#: light's horizontal and vertical offsets from the lens (m; a light on the camera body: a fit
#: that runs to 15 cm is mimicking a lab light's glint, as every spurious fit did on development
#: captures without a laminate; docs/results/design_evidence.md#gloss).
ROUGHNESS_RANGE: tuple[float, float] = (0.01, 0.6)
OFFSET_M: tuple[float, float] = (-0.15, 0.15)
#: Searched range of the ink factor ``h`` (log2): the ink 16 times darker or brighter than
#: simulated, what a print, a black level or a tone curve does to it. A fit on either end is
#: a proxy for what the level model cannot express (:data:`~simgap.analysis.thresholds.
#: AT_BOUND_SHARE`), as a roughness or offset on its end is.
INK_FACTOR_LOG2: tuple[float, float] = (-4.0, 4.0)
#: Intensity of the light of the calibration render (W sr^-1; the camera light's default: a tag
#: 0.45 m away gets the template key light's irradiance) and the largest intensity reported.
REFERENCE_INTENSITY_W_SR = 0.24
INTENSITY_W_SR: tuple[float, float] = (0.0, 5.0)
#: Weakest light a laminate finding mirrors (W sr^-1): a hundredth of the reference light, which
#: lights a tag 0.45 m away at a hundredth of the key light's irradiance. Below it the intensity
#: step found no glint to scale (its estimates are numerical zeros, 1e-17 W/sr on a blind
#: capture; docs/results/design_evidence.md#gloss); every laminate light fitted on the blind
#: seeds is 0.24 W/sr or more, and validate draws 0.1-0.5 W/sr.
MIN_INTENSITY_W_SR = 0.01 * REFERENCE_INTENSITY_W_SR
#: Smallest black level rendered (fraction of full scale): the black-level candidate's smallest
#: searched level (:data:`~simgap.analysis.candidates._black_level.LEVEL_BOUNDS`); below it
#: nothing is crushed.
MIN_BLACK_LEVEL = LEVEL_BOUNDS[0]
#: Smallest gain (floors) of the laminate over a matte light for a supported fit, and of its
#: render over its nuisance alone (:func:`laminate_explains`): the signature's smallest gain.
GLINT_MIN_GAIN = SIGNATURE_MIN_GAIN


def laminate_effects(params: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The scene effects of a ``tag_gloss`` finding: the laminate and the light beside the lens.

    ``params``: ``alpha``, ``light_intensity_w_sr``, ``light_offset_x_m`` and
    ``light_offset_z_m``.
    """
    offset = (float(params["light_offset_x_m"]), float(params["light_offset_z_m"]))
    return {
        "tag_gloss": {"alpha": float(params["alpha"]), "int_ior": LAMINATE_IOR},
        "camera_light": {"offset_m": offset, "intensity": float(params["light_intensity_w_sr"])},
    }


def predicted_levels(levels: TagLevels, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ink and paper linear levels of the level model (module docstring, step 2) at ``x``.

    ``x = (log2 G, log2 h, a, b, alpha, offset_x_m, offset_z_m, k)``. A level the black level
    takes to 0 is returned as a millionth of full scale over ``1 - k`` (its log stays
    finite).
    """
    gain, ink_factor, a, b, alpha, black = 2.0 ** x[0], 2.0 ** x[1], x[2], x[3], x[4], x[7]
    cos_h, cos_o, cos_l, distance = lobe_geometry(levels.eye_from_tag, x[5], x[6])
    light = a * cos_l / distance**2
    glint = b * beckmann(cos_h, alpha) / (distance**2 * np.maximum(cos_o, MIN_COS))
    paper = gain * (levels.sim_paper + light + glint)
    ink = gain * (ink_factor * levels.sim_ink * (1.0 + light / levels.sim_paper) + glint)
    return crushed(ink, black, floor=1e-6), crushed(paper, black, floor=1e-6)


def level_residuals(levels: TagLevels, x: np.ndarray) -> np.ndarray:
    """Log-level residuals of ink and paper in their floors.

    A clipped level counts only from below, a crushed ink only from above (each a bound).
    """
    ink, paper = predicted_levels(levels, x)
    r_ink = np.log2(ink / levels.real_ink) / IMAGE_FLOORS["ink_linear"][1]
    r_paper = np.log2(paper / levels.real_paper) / IMAGE_FLOORS["paper_linear"][1]
    r_paper = np.where(levels.clipped, np.minimum(r_paper, 0.0), r_paper)
    r_ink = np.where(levels.ink_clipped, np.minimum(r_ink, 0.0), r_ink)
    r_ink = np.where(levels.ink_crushed, np.maximum(r_ink, 0.0), r_ink)
    return np.concatenate([r_ink, r_paper])


@dataclass(frozen=True)
class LevelFit:
    """The level model fitted without light, with a matte light, and with the laminate.

    Attributes
    ----------
    x : ndarray (8,)
        ``(log2 G, log2 h, a, b, alpha, offset_x_m, offset_z_m, k)`` of the laminate model.
    rms_exposure, rms_light, rms_laminate : float
        RMS misfits (floors) of the exposure-only, the matte light and the laminate models.
    tags : int
        Tags fitted.
    """

    x: np.ndarray
    rms_exposure: float
    rms_light: float
    rms_laminate: float
    tags: int

    @property
    def alpha(self) -> float:
        """Laminate roughness."""
        return float(self.x[4])

    @property
    def offset_x_m(self) -> float:
        """The light's horizontal offset from the lens (m)."""
        return float(self.x[5])

    @property
    def offset_z_m(self) -> float:
        """The light's vertical offset from the lens (m)."""
        return float(self.x[6])

    @property
    def glint_scale(self) -> float:
        """``b``: the glint's scale (simulation's linear units x m^2 sr)."""
        return float(self.x[3])

    @property
    def black_level(self) -> float:
        """``k``: the camera's black level beyond the simulation's (fraction of full scale)."""
        return float(self.x[7])


def fit_levels(levels: TagLevels, fixed: tuple[float, float, float] | None = None) -> LevelFit:
    """Robust least squares of the level model: exposure, + matte light, + laminate.

    With ``fixed`` (alpha, offset x, offset z) only the scales are fitted (the calibration
    render). A free offset fitted onto the end of :data:`OFFSET_M` (either one) is kept only
    where the levels ask for it (:func:`~simgap.analysis.candidates.held_inside`).
    """
    if len(levels) < 4:
        nan = float("nan")
        at_rest = np.array([0, 0, 0, 0, ROUGHNESS_RANGE[1], 0.0, 0.0, 0.0])
        return LevelFit(at_rest, nan, nan, nan, len(levels))

    def solve(x0: np.ndarray, free: np.ndarray, lower, upper) -> tuple[np.ndarray, float]:
        x = fit_subset(lambda v: level_residuals(levels, v), x0, free, lower, upper)
        return x, capped_rms(level_residuals(levels, x))

    a_scale = float(np.median(levels.sim_paper)) * 0.1  # a light of a tenth of the key at 0.3 m
    black_max = LEVEL_BOUNDS[1]
    h_low, h_high = INK_FACTOR_LOG2
    base = np.array([0.0, 0.0, 0.0, 0.0, ROUGHNESS_RANGE[1], 0.0, 0.0, 0.0])
    inf = np.inf
    # exposure without, then with the black level: started at none, the joint fit can stall
    x_exp, _ = solve(base, np.array([1, 1, 0, 0, 0, 0, 0, 0], bool), (-6, h_low), (6, h_high))
    x_exp, rms_exp = solve(
        x_exp, np.array([1, 1, 0, 0, 0, 0, 0, 1], bool), (-6, h_low, 0), (6, h_high, black_max)
    )
    start = x_exp.copy()
    start[2] = a_scale
    scales = np.array([1, 1, 1, 0, 0, 0, 0, 1], bool)
    x_light, rms_light = solve(start, scales, (-6, h_low, 0, 0), (6, h_high, inf, black_max))
    if fixed is not None:
        start = x_light.copy()
        start[4:7] = fixed
        start[3] = a_scale
        scales[3] = True
        x, rms = solve(start, scales, (-6, h_low, 0, 0, 0), (6, h_high, inf, inf, black_max))
        return LevelFit(x, rms_exp, rms_light, rms, len(levels))
    lower = (-6, h_low, 0, 0, ROUGHNESS_RANGE[0], OFFSET_M[0], OFFSET_M[0], 0)
    upper = (6, h_high, inf, inf, ROUGHNESS_RANGE[1], OFFSET_M[1], OFFSET_M[1], black_max)

    def from_starts(offsets: tuple[float, ...], free: np.ndarray) -> list[tuple[np.ndarray, float]]:
        """The laminate fitted from each roughness start x each horizontal offset, level."""
        lo, hi = tuple(np.asarray(lower)[free]), tuple(np.asarray(upper)[free])
        fits = []
        for alpha in STARTS[0]:
            for offset in offsets:
                start = x_light.copy()
                start[3], start[4], start[5], start[6] = a_scale * alpha, alpha, offset, 0.0
                fits.append(solve(start, free, lo, hi))
        return fits

    # the first of equal misfits: the matte light before any laminate
    fits = [(x_light, rms_light), *from_starts(STARTS[1], np.ones(8, bool))]
    best, best_rms = min(fits, key=lambda fit: fit[1])
    held = []
    if on_bound(float(best[5]), *OFFSET_M) or on_bound(float(best[6]), *OFFSET_M):
        held = from_starts(HELD_OFFSETS_M, np.array([1, 1, 1, 1, 1, 0, 0, 1], bool))
    best, best_rms = held_inside((best, best_rms), held)
    return LevelFit(best, rms_exp, rms_light, best_rms, len(levels))


def glint_supported(fit: LevelFit, ratio: RatioFit | None) -> bool:
    """Whether a glint is the laminate's signature in the levels (module docstring, step 4).

    With a ``ratio`` fit (enough tags with unclipped ink and paper), the ratios decide
    (:attr:`RatioFit.supported`); without one, the level model: the laminate lowers its misfit
    below a matte light's by :data:`GLINT_MIN_GAIN` with a glint of positive scale.
    """
    if ratio is not None:
        return ratio.supported
    return fit.rms_light - fit.rms_laminate >= GLINT_MIN_GAIN and fit.glint_scale > 0


def laminate_explains(with_laminate: float, without: float) -> bool:
    """Whether a rendered laminate explains the levels beyond its nuisance alone (step 7).

    ``with_laminate`` and ``without`` are :meth:`GlossCandidate.render_misfit`'s mean squares
    (floors^2) of the laminate's render and of its exposure, print and black level without it;
    the laminate's RMS must be lower by :data:`GLINT_MIN_GAIN` (floors).
    """
    return bool(np.sqrt(without) - np.sqrt(with_laminate) >= GLINT_MIN_GAIN)


class GlossCandidate(AppearanceCandidate):
    """A laminate under a light beside the lens, fitted on the glints (see module docstring)."""

    n_params = 3

    def __init__(self) -> None:
        # its signature: ink brightened (the glint) and contrast lost, or highlights
        stats = ("ink_linear", "contrast", "highlight_fraction")
        super().__init__("tag_gloss", stats, "alpha", ROUGHNESS_RANGE, 0.0)

    def signature_shown(self, image_tests: list[ImageTest], runner: Runner, items: Items) -> bool:
        """Whether the capture shows a laminate, so that it is a candidate.

        One of its statistics differs significantly
        (:func:`~simgap.analysis.candidates.signature_significant`), or the levels call for one
        (:func:`glint_supported`, the rule the fit decides on: the ink-to-paper ratios of every
        comparable tag, or with too few of them the level model).

        A laminate lifts the ink only where the view meets a light's glint or grazes its veil;
        the ink's median over every tag can then stay under its floor (a crushing black level
        pulls the other way), while the ratios, which the capture's own lights, exposure and
        tone leave alone, show the pattern of the view (docs/results/laminate.md).
        """
        if super().signature_shown(image_tests, runner, items):
            return True
        if items.real_stats is None or items.sim_stats is None:
            return False
        levels = TagLevels.of(
            items.required("real_stats"), items.required("sim_stats"), runner.eye_from_tag(items)
        )
        ratio = fit_ratios(levels, ROUGHNESS_RANGE, OFFSET_M)
        if ratio is not None:
            return ratio.supported
        return glint_supported(fit_levels(levels), None)

    def apply(self, base: VariantState, params: dict[str, Any]) -> VariantState:
        """The state with the laminate, the light beside the lens and the fitted nuisance.

        The nuisance: the exposure (``ev``), the ink factor (``ink_factor``: the print's ink
        albedo over the simulation's, only where it darkens the ink) and the black level
        (``black_level``, fraction of full scale; where ``base`` has none of its own) the levels
        were fitted with (module docstring, step 6).
        """
        ink_factor = min(float(params.get("ink_factor", 1.0)), 1.0)
        return self.nuisance(base, params, ink_factor, laminate_effects(params))

    def nuisance(
        self,
        base: VariantState,
        params: dict[str, Any],
        ink_factor: float,
        laminate: dict[str, dict[str, Any]] | None = None,
    ) -> VariantState:
        """``base`` with the fitted nuisance (and the ``laminate``'s effects where given).

        The exposure ``ev``, the print's ink albedo times ``ink_factor`` and the black level
        (where ``base`` has none of its own) of ``params``. Without a laminate, what its fit
        would be were the levels a print's and a camera's alone (:meth:`fit`).
        """
        state = base
        effects = dict(laminate or {})
        black = float(params.get("black_level", 0.0))
        if black >= MIN_BLACK_LEVEL and not any(
            name == "black_level" for name, _ in base.image.ops
        ):
            effects["black_level"] = {"level": black}
        # the exposure the levels were fitted with: a light beside the lens brightens near tags,
        # so an exposure fitted without it is another (and added to it, counts that twice)
        effects["exposure"] = {"ev": float(params.get("ev", 0.0))}
        tag = base.scene.spec.tag
        effects["tag_material"] = {"ink": tag.ink * ink_factor, "paper": tag.paper}
        for name, values in effects.items():
            state = make_effect(name, values).apply(state)
        return state

    def intensity(
        self,
        runner: Runner,
        base: VariantState,
        items: Items,
        params: dict[str, Any],
        fit: LevelFit,
        ratio: RatioFit | None = None,
    ) -> tuple[float, float]:
        """The light's intensity (W sr^-1) whose renders match the real levels best, and its misfit.

        One render with :data:`REFERENCE_INTENSITY_W_SR` gives the simulation's scales of the
        matte light and of the glint; the real ones over them give two estimates (the level
        model's nuisance lights bias them differently: on development captures each was off
        by up to 3x, in opposite directions), and with a ``ratio`` fit the glint's scale in
        the ink-to-paper ratios a third (:mod:`simgap.analysis.candidates._glint_ratio`). The
        estimates, their geometric mean and a factor 2 beyond either are rendered, and the one whose
        ink, paper and contrast
        (:func:`~simgap.analysis.candidates.evidence_misfit`) and detections
        (:func:`~simgap.analysis.gap.detection_score`, one more statistic in the mean of
        squares, capped like them) match the real best is kept: a glint too bright, its levels
        matched by an exposure too low, loses tags the capture kept (measured on a blind
        capture: docs/results/design_evidence.md#gloss). The misfit is :meth:`render_misfit`'s
        (a mean square, floors^2; inf where nothing was rendered).
        """

        def misfit(intensity: float) -> tuple[float, np.ndarray]:
            state = self.apply(base, dict(params, light_intensity_w_sr=intensity))
            return self.render_misfit(runner, state, items)

        ref_misfit, rendered = misfit(REFERENCE_INTENSITY_W_SR)
        geometry = tuple(fit.x[4:7])
        rendered_levels = TagLevels.of(
            rendered, items.required("sim_stats"), runner.eye_from_tag(items)
        )
        ref = fit_levels(rendered_levels, geometry)
        scales = [(fit.glint_scale, ref.glint_scale), (fit.x[2], ref.x[2])]
        if ratio is not None:
            ref_ratio = fit_ratios(rendered_levels, ROUGHNESS_RANGE, OFFSET_M, geometry)
            if ref_ratio is not None:
                scales.append((ratio.glint_scale, ref_ratio.glint_scale))
        estimates = [
            REFERENCE_INTENSITY_W_SR * real / sim for real, sim in scales if real > 0 and sim > 0
        ]
        if not estimates:
            return 0.0, float("inf")
        low, high = min(estimates), max(estimates)
        tried = {REFERENCE_INTENSITY_W_SR: ref_misfit}
        for intensity in (low, high, np.sqrt(low * high), low / 2.0, high * 2.0):
            intensity = float(min(intensity, INTENSITY_W_SR[1]))
            if intensity not in tried:
                tried[intensity] = misfit(intensity)[0]
        finite = {k: v for k, v in tried.items() if np.isfinite(v)}
        if not finite:
            return 0.0, float("inf")
        best = min(finite, key=finite.__getitem__)
        return float(best), float(finite[best])

    @staticmethod
    def render_misfit(
        runner: Runner, state: VariantState, items: Items
    ) -> tuple[float, np.ndarray]:
        """How far ``state``'s renders of ``items`` are from the capture, and their statistics.

        The ink, paper and contrast (:func:`~simgap.analysis.candidates.evidence_misfit`) and
        the detections (:func:`~simgap.analysis.gap.detection_score`, one more statistic in
        the mean of squares, capped like them): a mean square in floors^2.
        """
        stats = ("ink_linear", "paper_linear", "contrast")
        state = measuring_only(state, ())
        rendered = runner.stats(state, items)
        detection = 0.0
        if items.real_detected is not None:  # no detections: the levels alone
            rendered_detected = runner.detected(state, items)
            score = detection_score(items.real_detected, rendered_detected, detection_groups(items))
            detection = min(float(score), RESIDUAL_CAP)
        levels = evidence_misfit(stats, items.required("real_stats"), rendered)
        return (len(stats) * levels + detection**2) / (len(stats) + 1), rendered

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """The level model on the fit split, then the intensity whose renders match best."""
        t0 = time.perf_counter()
        eye_from_tag = runner.eye_from_tag(items)
        levels = TagLevels.of(
            items.required("real_stats"), items.required("sim_stats"), eye_from_tag
        )
        # the glint's geometry from the ink-to-paper ratios where enough papers are unclipped
        # (the capture's lights cancel in them), its scales from the levels at that geometry
        ratio = fit_ratios(levels, ROUGHNESS_RANGE, OFFSET_M)
        fit = fit_levels(levels) if ratio is None else fit_levels(levels, ratio.geometry)
        params = {
            "alpha": fit.alpha,
            "light_intensity_w_sr": 0.0,
            "light_offset_x_m": fit.offset_x_m,
            "light_offset_z_m": fit.offset_z_m,
            "ev": float(fit.x[0]),
            "ink_factor": float(2.0 ** fit.x[1]),
            "black_level": fit.black_level,
        }
        supported = glint_supported(fit, ratio)
        with_laminate = without = float("nan")
        if supported:
            intensity, with_laminate = self.intensity(runner, base, items, params, fit, ratio)
            params["light_intensity_w_sr"] = intensity
            # no light is no glint: a laminate without one is only its coating's veil over ink
            # and paper, which a brighter print, flare or a transfer curve make as well
            supported = intensity >= MIN_INTENSITY_W_SR
            if supported:
                # the laminate must explain more than its nuisance alone: a print whose ink
                # differs (either way: the veil lifts the ink as a brighter print does)
                state = self.nuisance(base, params, float(params["ink_factor"]))
                without = self.render_misfit(runner, state, items)[0]
                supported = laminate_explains(with_laminate, without)
        top = INTENSITY_W_SR[1]
        at_bound = tuple(
            name
            for name, hit in (
                ("alpha", on_bound(fit.alpha, *ROUGHNESS_RANGE)),
                ("light_offset_x_m", on_bound(fit.offset_x_m, *OFFSET_M)),
                ("light_offset_z_m", on_bound(fit.offset_z_m, *OFFSET_M)),
                ("ink_factor", on_bound(float(fit.x[1]), *INK_FACTOR_LOG2)),
                # no light is no glint (not supported), not a bound: only the bright end is
                ("light_intensity_w_sr", on_bound(params["light_intensity_w_sr"], -top, top)),
            )
            if hit
        )
        return Fit(
            self.effect,
            params,
            time.perf_counter() - t0,
            {
                "supported": bool(supported),
                "tags": fit.tags,
                "level_rms_exposure": fit.rms_exposure,
                "level_rms_light": fit.rms_light,
                "level_rms_laminate": fit.rms_laminate,
                "ratio_gain": float("nan") if ratio is None else ratio.gain,
                "misfit_laminate": with_laminate,
                "misfit_without_laminate": without,
                "at_bound": at_bound,
            },
        )
