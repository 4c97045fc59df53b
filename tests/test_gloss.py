"""The glossy-laminate candidate: glints free of exposure, the lobe against view angle, renders."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simgap.analysis.candidates import (
    CLIPPED_DN,
    GLINT_MIN_GAIN,
    HEIGHT_M,
    HELD_OFFSETS_M,
    MIN_TAGS,
    OFFSET_M,
    ROUGHNESS_RANGE,
    GlossCandidate,
    TagLevels,
    beckmann,
    fit_levels,
    fit_ratios,
    fresnel_veil,
    held_inside,
    laminate_explains,
    lobe_geometry,
    predicted_levels,
)
from simgap.effects import make_effect
from simgap.pipeline.experiment import load_experiment
from simgap.pose.image_stats import STAT_INDEX, STATS, linearise
from tests.grid_items import grid_items


def _grid() -> np.ndarray:
    """Eyepoint-from-tag poses of tag 0 at every other pin hole and its facing stops."""
    rig = load_experiment("experiments/baseline.yaml").rig_model
    stops = np.deg2rad(np.r_[0:61:10, 300:351:10])
    ps, thetas = np.meshgrid(np.arange(0, 15, 2), stops, indexing="ij")
    return rig.eyepoints_from_tags(np.zeros(ps.size, int), ps.ravel(), thetas.ravel())


def _stats(ink: np.ndarray, paper: np.ndarray) -> np.ndarray:
    out = np.full((len(ink), len(STATS)), np.nan)
    out[:, STAT_INDEX["ink_linear"]], out[:, STAT_INDEX["paper_linear"]] = ink, paper
    out[:, STAT_INDEX["ink_dn"]], out[:, STAT_INDEX["paper_dn"]] = 30.0, 200.0
    return out


def _levels(eye_from_tag: np.ndarray, x: np.ndarray, rng: np.random.Generator) -> TagLevels:
    """Real levels drawn from the level model at ``x`` over simulated ones, with noise."""
    paper = rng.uniform(0.25, 0.45, len(eye_from_tag))
    none = np.zeros(len(paper), bool)
    sim = TagLevels(paper, paper, 0.035 * paper, paper, none, none, none, eye_from_tag)
    ink, real_paper = predicted_levels(sim, x)
    # noise: a tenth of a stop on ink, a twentieth on paper (the floors are 0.5 and 0.3 stop)
    ink = ink * 2.0 ** (0.1 * rng.standard_normal(ink.size))
    real_paper = real_paper * 2.0 ** (0.05 * rng.standard_normal(ink.size))
    clipped = real_paper >= 1.0
    # an ink at or below 2 DN is crushed: its level is read as that bound (TagLevels.of)
    bound = float(linearise(CLIPPED_DN[0]))
    crushed = ink <= bound
    return TagLevels(
        np.where(crushed, bound, ink), np.minimum(real_paper, 1.0), sim.sim_ink, sim.sim_paper,
        clipped, none, crushed, eye_from_tag,
    )  # fmt: skip


def test_the_laminate_is_recovered_and_a_matte_light_is_no_laminate():
    eye_from_tag = _grid()
    rng = np.random.default_rng(1)
    # exposure -0.5 EV, ink 1.2x (a transfer curve), a light beside the lens, a laminate of
    # roughness 0.1 mirroring it from 5 cm right of and 2 cm above the lens
    truth = np.array([-0.5, np.log2(1.2), 0.01, 2e-3, 0.1, 0.05, 0.02, 0.0])
    fit = fit_levels(_levels(eye_from_tag, truth, rng))
    # measured: alpha 0.095, offsets 0.046 and 0.015 m, glint scale 1.78e-3 (the offsets and
    # the roughness trade off a little: all three widen or shift the lobe)
    assert fit.alpha == pytest.approx(0.1, rel=0.1)
    assert fit.offset_x_m == pytest.approx(0.05, abs=0.01)
    assert fit.offset_z_m == pytest.approx(0.02, abs=0.01)
    assert fit.glint_scale == pytest.approx(2e-3, rel=0.15)
    assert fit.rms_light - fit.rms_laminate >= GLINT_MIN_GAIN
    matte = fit_levels(_levels(eye_from_tag, np.r_[truth[:3], 0.0, truth[4:]], rng))
    assert matte.rms_light - matte.rms_laminate < GLINT_MIN_GAIN


@pytest.mark.slow
def test_a_rendered_laminate_under_a_lens_side_light_is_named_with_its_roughness(tmp_path):
    """Real Mitsuba renders: a laminate of roughness 0.1 under a 0.3 W/sr light 4 cm beside the
    lens against the matte simulation, on 24 configurations with both tags' frontal stops.

    Marked slow (125 s on 2 cores): ``simgap validate --effects tag_gloss`` renders and fits
    the same candidate on every drawn camera; the ratio and level models are tested by default
    on synthetic levels above. Run it with ``pytest -m slow tests/test_gloss.py``.
    """
    from simgap.diagnosis.sim_runner import SimRunner
    from simgap.pipeline.simulator import Simulator

    exp = load_experiment("experiments/baseline.yaml")
    runner = SimRunner(exp, Simulator(tmp_path))
    items = grid_items(runner.rig, (0, 4, 8, 13), (0, 10, 30, 180, 190, 210))
    base = exp.variant_states()[0][1]
    candidate = GlossCandidate()
    truth = {
        "alpha": 0.1,
        "light_intensity_w_sr": 0.3,
        "light_offset_x_m": 0.04,
        "light_offset_z_m": 0.0,
    }
    items.real_stats = runner.stats(candidate.apply(base, truth), items)
    items.real_detected = runner.detected(candidate.apply(base, truth), items)
    items.sim_stats = runner.stats(base, items)
    items.sim_detected = runner.detected(base, items)
    fit = candidate.fit(runner, base, items)
    # measured: supported (the ratios' glint gains 1.47 floors; the levels at its geometry fit
    # within 0.06 floors against the matte light's 1.36), alpha 0.112, intensity 0.33 W/sr,
    # offset 0.027 m (height not fitted: 0); with the geometry from the levels (before the
    # ratios): alpha 0.108, 0.36 W/sr, offset (0.034, -0.069) m; all path traced at 16 spp.
    # Rendered converged (the baseline's since issue 28): alpha 0.118, 0.40 W/sr, offset 0.016
    # m (the laminate's ink levels 0-6 % above a 64-spp path render's, its paper within 3 %).
    # The roughness, the light's place and its intensity trade off where few tags sample the
    # lobe (module docstring): 30 % on the roughness
    assert fit.extra["supported"] and fit.extra["at_bound"] == ()
    assert fit.params["alpha"] == pytest.approx(0.1, rel=0.3)
    # the intensity measured 0.40 W/sr on the machine of the converged renders' first runs and
    # 0.46 W/sr on an AVX-512 machine with the same code and pins (alpha 0.118 and offset 0.016 m
    # alike on both): the bar is 60 %, beyond both
    assert fit.params["light_intensity_w_sr"] == pytest.approx(0.3, rel=0.6)
    # beyond its nuisance (module docstring, step 7): the exposure, print and black level it was
    # fitted with, rendered without the laminate, match the levels and detections worse;
    # measured 0.33 against 5.98 floors^2 (RMS 0.57 against 2.44: a gain of 1.9 floors, seven
    # times the 0.25 asked)
    with_laminate, without = fit.extra["misfit_laminate"], fit.extra["misfit_without_laminate"]
    assert laminate_explains(with_laminate, without)
    assert np.sqrt(without) - np.sqrt(with_laminate) == pytest.approx(1.87, abs=0.5)


def _lit_otherwise(
    eye_from_tag: np.ndarray, glint_scale: float, rng: np.random.Generator
) -> TagLevels:
    """Real levels under another camera's lights (each tag lit 0.6-1.6x the simulation's), an
    exposure of -0.5 EV, flare, and a laminate of roughness 0.2 mirroring a light 6 cm left of
    and 2 cm below the lens (``glint_scale`` 0: no laminate)."""
    paper = rng.uniform(0.25, 0.45, len(eye_from_tag))
    ink = 0.035 * paper
    lighting = 2.0 ** rng.uniform(-0.7, 0.7, len(paper))
    cos_h, cos_o, _, distance = lobe_geometry(eye_from_tag, -0.06, -0.02)
    glint = glint_scale * beckmann(cos_h, 0.2) / (distance**2 * np.maximum(cos_o, 0.05))
    gain, flare = 2.0**-0.5, 0.004
    real_paper = (gain * paper * lighting + glint + flare) * 2.0 ** (
        0.05 * rng.standard_normal(paper.size)
    )
    real_ink = (gain * ink * lighting + glint + flare) * 2.0 ** (
        0.1 * rng.standard_normal(paper.size)
    )
    none = np.zeros(len(paper), bool)
    return TagLevels(real_ink, real_paper, ink, paper, none, none, none, eye_from_tag)


def test_the_glint_is_placed_from_ink_to_paper_ratios_whatever_the_lights():
    """Another camera's lights scale each tag's ink and paper alike (here 0.6-1.6x per tag), a
    glint adds to both: the ratio model places the light and the roughness where the level model
    has to absorb the lights, and finds no glint under the same lights without a laminate.
    Measured: ratio alpha 0.194, offset -0.057 m (the height is not fitted: 0), gain 0.44
    floors (the level model: gain 0.08, below the support of 0.25, its light 3 cm above the lens
    instead of 2 below); without a laminate gain 0.005. Bounds: the roughness within 15 %, the
    offset within 1 cm."""
    eye_from_tag = _grid()
    rng = np.random.default_rng(4)
    levels = _lit_otherwise(eye_from_tag, 2e-4, rng)
    fit = fit_ratios(levels, ROUGHNESS_RANGE, OFFSET_M)
    assert fit is not None and fit.tags == len(eye_from_tag)
    alpha, offset_x, offset_z = fit.geometry
    assert alpha == pytest.approx(0.2, rel=0.15)
    assert offset_x == pytest.approx(-0.06, abs=0.01)
    assert offset_z == HEIGHT_M
    assert fit.gain >= GLINT_MIN_GAIN
    level = fit_levels(levels)
    assert level.rms_light - level.rms_laminate < GLINT_MIN_GAIN
    matte = fit_ratios(_lit_otherwise(eye_from_tag, 0.0, rng), ROUGHNESS_RANGE, OFFSET_M)
    assert matte is not None and matte.gain < GLINT_MIN_GAIN


@pytest.mark.parametrize("veil", [0.002, 0.004, 0.008])
def test_a_laminate_veil_is_told_from_flare(veil):
    """A laminate mirrors the room into the lens with its Fresnel reflectance, which grows
    towards grazing views (``fresnel_veil``); a camera's flare adds the same level to every
    tag. Over the same matte levels under another camera's lights, a veil of 0.002-0.008 full
    scale (no glint) is supported and measured, a flare of 0.005-0.02 is not. Measured: veil
    0.0019 / 0.0039 / 0.0079 with gains 0.33 / 0.56 / 0.77 floors; flare gains below 0.003
    floors, the flare fitted as flare. Bounds: the veil within 10 %, the flare's gain a tenth
    of the support."""
    eye_from_tag = _grid()
    cos_o = lobe_geometry(eye_from_tag, 0.0)[1]
    base = _lit_otherwise(eye_from_tag, 0.0, np.random.default_rng(5))
    added = veil * fresnel_veil(cos_o)
    lit = dataclasses.replace(
        base, real_ink=base.real_ink + added, real_paper=base.real_paper + added
    )
    fit = fit_ratios(lit, ROUGHNESS_RANGE, OFFSET_M)
    assert fit is not None and fit.gain >= GLINT_MIN_GAIN
    assert fit.veil == pytest.approx(veil, rel=0.1)
    flare = 5.0 * veil / 2.0
    flared = dataclasses.replace(
        base, real_ink=base.real_ink + flare, real_paper=base.real_paper + flare
    )
    fit = fit_ratios(flared, ROUGHNESS_RANGE, OFFSET_M)
    assert fit is not None and fit.gain < 0.1 * GLINT_MIN_GAIN


def test_too_few_unclipped_papers_leave_the_glint_to_the_level_model():
    eye_from_tag = _grid()
    levels = _lit_otherwise(eye_from_tag, 2e-4, np.random.default_rng(4))
    clipped = np.arange(len(levels)) >= MIN_TAGS - 1
    levels = TagLevels(
        levels.real_ink, levels.real_paper, levels.sim_ink, levels.sim_paper, clipped,
        np.zeros(len(levels), bool), np.zeros(len(levels), bool), levels.eye_from_tag,
    )  # fmt: skip
    assert fit_ratios(levels, ROUGHNESS_RANGE, OFFSET_M) is None


class _Items:
    """The image statistics of comparable tags, as :class:`~simgap.analysis.gap.Items`."""

    def __init__(self, real_stats: np.ndarray, sim_stats: np.ndarray) -> None:
        self.real_stats, self.sim_stats = real_stats, sim_stats

    def required(self, name: str) -> np.ndarray:
        return getattr(self, name)


class _Runner:
    """The one method of the :class:`~simgap.analysis.candidates.Runner` the signature needs."""

    def __init__(self, eye_from_tag: np.ndarray) -> None:
        self._eye = eye_from_tag

    def eye_from_tag(self, items: object) -> np.ndarray:
        return self._eye


def test_a_laminate_whose_light_has_no_intensity_is_not_supported(monkeypatch):
    """No light is no glint: where the intensity step finds no light (0 W/sr, or a numerical
    zero of 1e-17 W/sr as on fresh seed 84 trial 10, which named such a laminate on a capture
    with nothing hidden, its veil standing in for a brighter print), the fit is not supported,
    however well the ratios called for a glint; the same levels with a light found are, where
    the laminate explains more than its nuisance alone (step 7). No render: the intensity step
    and the nuisance's render are stubbed."""
    from simgap.effects.state import VariantState

    eye_from_tag = _grid()
    truth = np.array([-0.5, np.log2(1.2), 0.01, 2e-3, 0.1, 0.05, 0.02, 0.0])
    levels = _levels(eye_from_tag, truth, np.random.default_rng(1))
    items = _Items(
        _stats(levels.real_ink, levels.real_paper), _stats(levels.sim_ink, levels.sim_paper)
    )
    # the laminate's render matches with 0.5 floors^2; its nuisance alone with 4.0 (a laminate)
    # or 0.6 (a print's ink alone: step 7)
    monkeypatch.setattr(GlossCandidate, "nuisance", lambda self, base, *a, **k: base)
    cases = ((0.0, 4.0, False), (1.1e-17, 4.0, False), (0.3, 4.0, True), (0.3, 0.6, False))
    for intensity, without, supported in cases:
        monkeypatch.setattr(
            GlossCandidate, "intensity", lambda self, *a, _w=intensity, **k: (_w, 0.5)
        )
        monkeypatch.setattr(
            GlossCandidate, "render_misfit", staticmethod(lambda *a, _m=without: (_m, None))
        )
        fit = GlossCandidate().fit(_Runner(eye_from_tag), VariantState(), items)
        assert fit.params["light_intensity_w_sr"] == intensity
        assert fit.extra["supported"] is supported


@pytest.mark.parametrize("veil", [0.0, 0.004])
def test_a_laminate_whose_ink_median_stays_under_its_floor_is_a_candidate(veil):
    """A veil of 0.004 full scale behind a darker ink (0.85x, as a black level pulls it) lifts
    the oblique tags' ink, but the ink's median difference over every tag stays under its
    0.5-stop floor and no laminate statistic is significant; the ink-to-paper ratios still call
    for a laminate (gain 0.56 floors), so it is a candidate. The same capture without the veil
    is not (gain 0.00). Measured: the ink's median difference +0.31 stop with the veil, -0.19
    without."""
    from simgap.analysis.gap import paired_test

    eye_from_tag = _grid()
    base = _lit_otherwise(eye_from_tag, 0.0, np.random.default_rng(5))
    added = veil * fresnel_veil(lobe_geometry(eye_from_tag, 0.0)[1])
    real = _stats(0.85 * (base.real_ink + added), base.real_paper + added)
    sim = _stats(base.sim_ink, base.sim_paper)
    tests = [
        t
        for stat in ("ink_linear", "paper_linear", "contrast", "highlight_fraction")
        if (t := paired_test(stat, real[:, STAT_INDEX[stat]], sim[:, STAT_INDEX[stat]]))
    ]
    ink = next(t for t in tests if t.stat == "ink_linear")
    assert abs(ink.median_difference) < ink.floor
    assert not any(t.significant for t in tests if t.stat in GlossCandidate().fit_stats)
    shown = GlossCandidate().signature_shown(tests, _Runner(eye_from_tag), _Items(real, sim))
    assert shown is (veil > 0)


#: A laminate finding's parameters, rendered by the candidate with its fitted nuisance.
_FOUND = {
    "alpha": 0.1,
    "light_intensity_w_sr": 0.3,
    "light_offset_x_m": 0.05,
    "light_offset_z_m": 0.02,
    "ev": -0.5,
}


def test_the_laminate_is_rendered_with_the_ink_it_was_fitted_with():
    """A fitted ink factor ``h`` below 1 is rendered as the print's ink albedo times ``h``.

    Without it the rendered glint lifts ink that the capture's camera took back and a right
    laminate scored worse than none (docs/results/laminate.md).
    """
    eye_from_tag = _grid()
    rng = np.random.default_rng(1)
    # a print 4x darker than the simulation's (or a black level that darkens its ink as much)
    truth = np.array([-0.5, -2.0, 0.01, 2e-3, 0.1, 0.05, 0.02, 0.0])
    fit = fit_levels(_levels(eye_from_tag, truth, rng))
    # measured: log2 h -1.936, black level 1e-4 (a tenth of a stop of ink noise over 104 tags)
    assert fit.x[1] == pytest.approx(-2.0, abs=0.1)

    base = load_experiment("experiments/baseline.yaml").variant_states()[0][1]
    tag = base.scene.spec.tag
    params = dict(_FOUND, ink_factor=2.0 ** fit.x[1])
    rendered = GlossCandidate().apply(base, params).scene.spec.tag
    assert rendered.ink == pytest.approx(tag.ink * 2.0 ** fit.x[1], rel=1e-12)
    assert rendered.paper == tag.paper and rendered.coating is not None
    # an ink brighter than simulated is the laminate's own veil (or flare): not rendered twice
    brighter = GlossCandidate().apply(base, dict(params, ink_factor=1.8)).scene.spec.tag
    assert brighter.ink == tag.ink


def test_a_black_level_is_fitted_beside_the_laminate_and_rendered_as_the_camera_s():
    """A black level takes the same level off ink and paper: the glint stands on crushed ink.

    The level model fits it beside the exposure (an ink factor alone had put the exposure stops
    too low, docs/results/laminate.md); the candidate renders it as the camera's black level,
    unless the model already holds one (the black-level candidate's).
    """
    eye_from_tag = _grid()
    rng = np.random.default_rng(1)
    truth = np.array([-0.5, 0.0, 0.01, 2e-3, 0.1, 0.05, 0.02, 0.02])
    levels = _levels(eye_from_tag, truth, rng)
    # the black level crushes most of the ink below a thousandth of full scale
    assert np.count_nonzero(levels.real_ink < 1e-3) > len(levels) / 2
    fit = fit_levels(levels)
    # measured: black level 0.0227, exposure -0.494 EV, roughness 0.104, glint scale 2.12e-3
    # (0.0099 and 0.0424 for 0.01 and 0.04; the ink factor is loose where the ink is crushed)
    assert fit.black_level == pytest.approx(0.02, abs=0.005)
    assert fit.x[0] == pytest.approx(-0.5, abs=0.1)
    assert fit.alpha == pytest.approx(0.1, rel=0.1)
    assert fit.glint_scale == pytest.approx(2e-3, rel=0.15)

    base = load_experiment("experiments/baseline.yaml").variant_states()[0][1]
    params = dict(_FOUND, black_level=fit.black_level)
    ops = dict(GlossCandidate().apply(base, params).image.ops)
    assert ops["black_level"].level == pytest.approx(fit.black_level)
    # a model that brings its own black level keeps it alone
    own = make_effect("black_level", {"level": 0.03}).apply(base)
    levels_applied = [
        p.level
        for name, p in GlossCandidate().apply(own, params).image.ops
        if name == "black_level"
    ]
    assert levels_applied == [0.03]


def _crushed_capture(
    eye_from_tag: np.ndarray, glint: float, seed: int
) -> tuple[np.ndarray, np.ndarray, TagLevels]:
    """Real and simulated statistics of a black level of 0.04 that crushes most tags' ink.

    With a laminate (``glint``, the level model's ``b``) its glint lifts the frontal tags' ink
    above the black level; the others' ink medians are at 1 DN.
    """
    truth = np.array([-0.5, 0.0, 0.01, glint, 0.1, 0.05, 0.02, 0.04])
    levels = _levels(eye_from_tag, truth, np.random.default_rng(seed))
    real = _stats(levels.real_ink, levels.real_paper)
    real[levels.ink_crushed, STAT_INDEX["ink_dn"]] = 1.0
    return real, _stats(levels.sim_ink, levels.sim_paper), levels


def test_crushed_inks_are_bounds_that_tell_a_black_level_from_a_darker_print():
    """Tags whose ink a black level crushed to 0 DN bound their level from above.

    Measured (black level 0.04, 96 of 104 inks crushed): kept as bounds, the level model reads
    the black level 0.0424 / 0.0415, the roughness 0.109 / 0.101 (truth 0.1) and the exposure
    -0.496 / -0.500 EV at seeds 1 / 2; with the crushed tags left out (what the model read
    before), 8 tags are left and the roughness is 0.054 / 0.446. Seed 2 is asserted (seed 1's
    fit takes three times as long).
    """
    eye_from_tag = _grid()
    real, sim, _ = _crushed_capture(eye_from_tag, 2e-3, 2)
    levels = TagLevels.of(real, sim, eye_from_tag)
    assert np.count_nonzero(levels.ink_crushed) == 96
    assert levels.real_ink[levels.ink_crushed] == pytest.approx(linearise(CLIPPED_DN[0]))
    fit = fit_levels(levels)
    assert fit.black_level == pytest.approx(0.04, abs=0.004)
    assert fit.alpha == pytest.approx(0.1, rel=0.1)
    assert fit.x[0] == pytest.approx(-0.5, abs=0.05)
    readable = ~levels.ink_crushed
    without = fit_levels(
        TagLevels(*(getattr(levels, f.name)[readable] for f in dataclasses.fields(levels)))
    )
    assert abs(without.alpha - 0.1) > 0.04


def test_a_tag_whose_paper_is_crushed_too_is_left_out():
    """A tag black through and through (its paper's median at 0 DN: a black level over an unlit
    tag) has no level to compare: it is left out, and the level model stays finite (it raised
    "residuals are not finite" on a validation capture with such a tag)."""
    eye_from_tag = _grid()
    real, sim, _ = _crushed_capture(eye_from_tag, 2e-3, 2)
    real[:3, STAT_INDEX["paper_dn"]] = 0.0
    real[:3, STAT_INDEX["paper_linear"]] = 0.0
    levels = TagLevels.of(real, sim, eye_from_tag)
    assert len(levels) == len(real) - 3
    fit = fit_levels(levels)
    assert np.isfinite([fit.rms_exposure, fit.rms_light, fit.rms_laminate]).all()


@pytest.mark.parametrize(("glint", "shown"), [(2e-3, True), (0.0, False)])
def test_with_too_few_readable_inks_the_level_model_makes_the_laminate_a_candidate(glint, shown):
    """Where too few tags have readable ink and paper for the ratios, the level model decides
    whether a laminate is a candidate, as it decides whether its fit is supported.

    Black level 0.04; two of the 8 tags whose ink the glint lifted have clipped papers, so 6
    are readable (under :data:`MIN_TAGS`). Measured at seeds 1-3: the laminate lowers the
    level model's misfit below a matte light's by 0.65-0.69 floors with a glint, by 0.05-0.07
    without (the support is :data:`GLINT_MIN_GAIN`, 0.25); seed 3 is asserted.
    """
    eye_from_tag = _grid()
    real, sim, levels = _crushed_capture(eye_from_tag, glint, 3)
    readable = np.flatnonzero(~levels.ink_crushed)
    real[readable[:2], STAT_INDEX["paper_dn"]] = 255.0
    assert fit_ratios(TagLevels.of(real, sim, eye_from_tag), ROUGHNESS_RANGE, OFFSET_M) is None
    candidate = GlossCandidate()
    assert candidate.signature_shown([], _Runner(eye_from_tag), _Items(real, sim)) is shown


@pytest.mark.parametrize(
    ("with_laminate", "without", "named"),
    [
        (1.78, 4.76, True),  # blind seed 93 trial 9: a laminate beside an exposure
        (0.52, 3.85, True),  # seed 82 trial 9: a laminate beside a principal point
        (1.00, 3.78, True),  # seed 82 trial 0: a laminate beside a calibration file
        (4.09, 3.92, False),  # seed 93 trial 12: a defocus; the fit carried a darker print
        (1.94, 1.45, False),  # seed 94 trial 5: a lens; the fit's veil took a brighter print
    ],
)
def test_a_laminate_is_named_only_beyond_its_nuisance(with_laminate, without, named):
    """The render-based misfits (floors^2) measured on blind captures (docs/results/laminate.md):
    the true laminates gain 0.85-1.24 floors RMS over their nuisance alone, the two fits that
    only carried the print's ink none."""
    assert laminate_explains(with_laminate, without) is named


@pytest.mark.parametrize(
    ("free_rms", "held_rms", "held"),
    [
        (1.232, 1.421, True),  # blind seed 94 trial 15: a laminate on mostly frontal poses
        (0.893, 0.921, True),  # seed 88 trial 5: a laminate behind an S-curve (ratio model)
        (0.540, 0.802, False),  # seed 93 trial 16: no laminate, a light the fit placed far off
        (0.985, 1.342, False),  # seed 95 trial 15: no laminate, a sun
    ],
)
def test_a_light_fitted_onto_its_end_is_held_on_the_body_where_the_levels_allow(
    free_rms, held_rms, held
):
    """The RMS misfits (floors) of the fits with the light's offset free (on the end of its
    range) and held on the camera body, measured on blind captures (docs/results/laminate.md):
    the held fit is kept within the signature's smallest gain (0.25 floors) of the free one."""
    free_x, held_x = np.array([0.15]), np.array([0.05])
    x, rms = held_inside(
        (free_x, free_rms), [(np.array([0.0]), held_rms + 0.1), (held_x, held_rms)]
    )
    assert (x is held_x) is held
    assert rms == (held_rms if held else free_rms)
    # a fit inside its range has no held alternative: it is kept as it is
    assert held_inside((free_x, free_rms), [])[0] is free_x


def test_a_glint_from_beyond_the_camera_body_stays_on_the_end_of_the_range():
    """A light 18 cm beside the lens, broad lobe (roughness 0.3): the levels ask for the end of
    the searched range (measured: 0.26 floors RMS at 15 cm, 0.74 with the light held 5 cm from
    the lens, the best held fit), so the fit stays on its bound and the candidate is left out as
    before; the held offsets are the lens and the searches' starts."""
    truth = np.array([0.0, 0.0, 0.0, 2e-3, 0.3, 0.18, 0.0, 0.0])
    fit = fit_levels(_levels(_grid(), truth, np.random.default_rng(0)))
    assert fit.offset_x_m == pytest.approx(OFFSET_M[1], abs=1e-3)
    assert HELD_OFFSETS_M == (0.0, -0.05, 0.05)
