"""Gap diagnosis: statistics, exact effect fits, parsimony and the model search."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simgap.analysis import gap as gapmod
from simgap.analysis.candidates import (
    CANDIDATES,
    Fit,
    ProjectionCandidate,
    ProjectionSet,
    project_items,
)
from simgap.analysis.gap import Items
from simgap.analysis.search import ModelSearch, Scored, admissible, parsimonious
from simgap.core.axes import AXES
from simgap.core.rig import load_rig
from simgap.effects import make_effect
from simgap.effects.state import VariantState
from simgap.pose.estimate import estimate_pose, pose_error


def _items(
    rig,
    effects: dict[str, dict],
    noise_px: float = 0.0,
    seed: int = 0,
    shrink_px: float = 0.0,
    smear_px: float = 0.0,
) -> tuple[Items, VariantState]:
    """Exact corners of visible tags: 'sim' nominal, 'real' with the effects (+ noise, px).

    ``shrink_px`` moves the real corners that far towards the marker's centre (a detector edge
    bias, as a softer camera gives); ``smear_px`` moves them that far along the image's x axis
    only, the corners right of the marker's centre (a smear in the direction of motion: the dark
    square reaches further that way).
    """
    base = VariantState(scene=VariantState().scene.__class__(camera=rig.camera))
    true = base
    for effect, params in effects.items():
        true = make_effect(effect, params).apply(true)
    true = true.scene
    rows = np.array(
        [
            (t, p, th)
            for t in (0, 1)
            for p in (0, 5, 10, 14)
            for th in rig.grid.theta[::3]
            if rig.is_visible(t, p, th)
        ]
    )
    n = len(rows)
    empty = np.zeros((n, 4, 2))
    items = Items(
        rows[:, 0].astype(int),
        rows[:, 1].astype(int),
        rows[:, 2],
        np.zeros((n, 6)),
        np.zeros((n, 6)),
        empty,
        empty,
        np.array([5e-4, 5e-4, 5e-4, 8.73e-3, 8.73e-3, 8.73e-3]),  # the practical floor
    )
    sim = project_items(rig, rig.camera, base.scene.errors, 1.0, items)
    real = project_items(rig, true.camera, true.errors, true.tag_scale, items)
    real += np.random.default_rng(seed).normal(0.0, noise_px, real.shape)
    if shrink_px:
        centre = real.mean(axis=1, keepdims=True)
        d = real - centre
        real = centre + d * (1 - shrink_px / np.linalg.norm(d, axis=-1, keepdims=True))
    if smear_px:
        centre = real.mean(axis=1, keepdims=True)
        real[..., 0] += np.where(real[..., 0] > centre[..., 0], smear_px, 0.0)
    cal = rig.camera

    def errors(corners):
        out = []
        for (t, p, th), c in zip(rows, corners, strict=True):
            est = estimate_pose(c, rig.tags.size, cal)
            out.append(pose_error(est.pose, rig.expected_pose(int(t), p, th)))
        return np.array(out)

    items.real_corners, items.sim_corners = real, sim
    items.real_err, items.sim_err = errors(real), errors(sim)
    return items, base


@pytest.mark.parametrize(
    "effect, params, key",
    [
        ("focal_length", {"scale": 0.017}, "scale"),
        ("principal_point", {"dx_px": 6.0, "dy_px": -9.0}, "dx_px"),
        ("turntable_offset", {"angle_rad": 0.03}, "angle_rad"),
        ("carriage_pitch", {"scale": -0.02}, "scale"),
        ("tag_scale", {"scale": 0.025}, "scale"),
    ],
)
def test_projection_fit_recovers_exact_parameters(effect, params, key):
    rig = load_rig()
    items, base = _items(rig, {effect: params})
    cand = CANDIDATES[effect]
    assert isinstance(cand, ProjectionCandidate)
    fit = cand.fit(rig, base, items)
    # noise-free corners: the least-squares optimum is the truth; measured |error| < 1e-6
    assert fit.params[key] == pytest.approx(params[key], rel=1e-3, abs=1e-6)
    assert fit.extra["corner_rms_px"] < 1e-3


def test_joint_fit_separates_principal_point_and_focal_length():
    """Fitted together, each effect takes its own share of the corner shift."""
    rig = load_rig()
    hidden = {"focal_length": {"scale": 0.02}, "principal_point": {"dx_px": 8.0, "dy_px": -6.0}}
    items, base = _items(rig, hidden)
    cands = CANDIDATES
    joint = ProjectionSet([cands["focal_length"], cands["principal_point"]])
    fits = joint.member_fits(joint.fit(rig, base, items))
    assert [f.effect for f in fits] == ["focal_length", "principal_point"]
    # noise-free corners: the joint optimum is the truth (measured |error| < 1e-6)
    assert fits[0].params["scale"] == pytest.approx(0.02, rel=1e-3)
    assert fits[1].params["dx_px"] == pytest.approx(8.0, rel=1e-3)
    assert fits[1].params["dy_px"] == pytest.approx(-6.0, rel=1e-3)


def _scored(effect: str, n_params: int, corner_after: float) -> Scored:
    cand = ProjectionCandidate(effect, [(f"x{i}", 1.0, 1.0) for i in range(n_params)])
    return _with_fits([(cand, Fit(effect, {}))], corner_after)


def _with_fits(fits: list, corner_after: float) -> Scored:
    nan6 = np.full(6, np.nan)
    return Scored(
        fits=fits,
        pose_gap_before=5.0,
        pose_gap_after=0.2,
        median_abs_gap_before=nan6,
        median_abs_gap_after=nan6,
        pose_gap_all_axes_before=5.0,
        pose_gap_all_axes_after=0.2,
        corner_gap_before_px=12.9,
        corner_gap_after_px=corner_after,
    )


def test_a_model_is_admissible_only_where_each_effect_explains_its_own_evidence():
    """Regression (fresh seed 90, trial 2): a laminate fitted alone to a 0.04 W/sr light was
    refitted beside an exposure that entered after it, found no light to mirror (1.8e-13 W/sr:
    its fit not ``supported``) and was still named. A model holding any fit that does not explain
    its own evidence may not be entered, whichever effect was added last."""

    def model(*supported: bool) -> Scored:
        names = ("exposure", "tag_gloss")
        fits = [
            (CANDIDATES[name], Fit(name, {}, 0.0, {"supported": ok}))
            for name, ok in zip(names, supported, strict=True)
        ]
        return _with_fits(fits, 0.3)

    both = model(True, True)
    laminate_alone = dataclasses.replace(both, fits=both.fits[1:])
    assert admissible(laminate_alone, None)
    assert admissible(both, laminate_alone)
    # the exposure enters, the laminate's refit beside it explains nothing of its own
    assert not admissible(model(True, False), laminate_alone)
    assert not admissible(model(False, True), laminate_alone)


def test_parsimony_prefers_the_simpler_of_equivalent_explanations():
    # choose-split corner residuals (px) of blind-validation trial 13 (seed 0): a hidden principal-
    # point shift; the 6-DOF camera mount (a small rotation) fits it 0.012 px better
    tie = [_scored("camera_mount", 6, 0.347), _scored("principal_point", 2, 0.359)]
    assert parsimonious(tie).effects == ["principal_point"]
    # trial 0: a hidden mount translation; tag_offset (3 parameters) is clearly worse
    clear = [_scored("camera_mount", 6, 0.341), _scored("tag_offset", 3, 0.494)]
    assert parsimonious(clear).effects == ["camera_mount"]


def test_selection_finds_a_pair_a_richer_effect_would_mimic():
    """Principal point + focal length on exact corners (0.2 px detector-like noise): the
    6-DOF camera mount explains most alone, but the search ends with the true pair."""
    rig = load_rig()
    hidden = {"principal_point": {"dx_px": 9.0, "dy_px": -7.0}, "focal_length": {"scale": 0.02}}
    items, base = _items(rig, hidden, noise_px=0.2, seed=1)
    idx = np.arange(len(items))
    fit, choose = idx[idx % 3 != 0], idx[idx % 3 == 0]
    search = ModelSearch(rig, base, items, fit, choose, fit, np.ones(6, bool))
    cands = [c for c in CANDIDATES.values() if isinstance(c, ProjectionCandidate)]
    ranking = search.rank(cands, significant=True)
    chosen = search.select(ranking)
    assert chosen.effects == ["principal_point", "focal_length"]
    fitted = {f.effect: f.params for _, f in chosen.fits}
    # 0.2 px noise on ~100 corners: measured errors 0.3 % (scale) and < 0.1 px
    assert fitted["focal_length"]["scale"] == pytest.approx(0.02, rel=0.05)
    assert fitted["principal_point"]["dx_px"] == pytest.approx(9.0, abs=0.3)
    assert chosen.pose_gap_reduction > 0.9
    assert min(search.contributions(chosen).values()) >= 1.0


def test_a_geometric_effect_that_moves_the_pose_away_never_starts_the_selection():
    """Regression (blind seed 23): a tag print scale that followed the corners of a motion blur
    (outside the catalogue) lowered the choose split's corner residual but left every pose 1-5 %
    further from the real one, and was reported instead of "unexplained"."""
    rig = load_rig()
    items, base = _items(rig, {"tag_scale": {"scale": 0.01}}, noise_px=0.1, seed=2)
    idx = np.arange(len(items))
    fit, choose = idx[idx % 3 != 0], idx[idx % 3 == 0]
    search = ModelSearch(rig, base, items, fit, choose, fit, np.ones(6, bool))
    cand = CANDIDATES["tag_scale"]
    scored = search.rank([cand], significant=True)[0]
    # a true print scale brings the pose closer
    assert scored.pose_gap_all_axes_after < scored.pose_gap_all_axes_before
    assert search.select([scored]).effects == ["tag_scale"]
    # the same corners, but the pose 5 % further away than without the effect: no explanation
    before = scored.pose_gap_all_axes_before
    away = dataclasses.replace(scored, pose_gap_all_axes_after=1.05 * before)
    assert search.select([away]) is None
    # blind seed 25, trial 15: the print scale following a motion blur's corners brought the
    # choice split's poses 6 % closer (0.554 -> 0.521; the measure split's moved 42 % away). A
    # geometric effect must bring them MIN_POSE_REDUCTION (10 %) closer; every true one that
    # started a model on seeds 22, 23 and 25 did by 19 % or more
    slightly = dataclasses.replace(scored, pose_gap_all_axes_after=0.94 * before)
    assert search.select([slightly]) is None
    clearly = dataclasses.replace(scored, pose_gap_all_axes_after=0.81 * before)
    assert search.select([clearly]).effects == ["tag_scale"]


def test_pose_relevance_never_swaps_the_explanation_the_corners_single_out():
    """Regression (issue 8): a -3 % focal length seen through a detector edge bias (corners
    0.6 px inside the true ones). The greedy search finds focal_length + tag_scale; the old
    relevance rule refitted the model without focal_length, let tag_scale absorb its pose change,
    judged focal_length irrelevant and reported tag_scale alone (choose-split corners 4.26 px
    instead of 0.19 px). Since seed 32 a print scale must change the sizes in proportion
    (:mod:`simgap.analysis.candidates._size_signature`): the edge offset (measured -0.593 px on
    every tag, slope 0.1 standard errors) is left unexplained, not read as a -1 % print."""
    rig = load_rig()
    items, base = _items(
        rig, {"focal_length": {"scale": -0.03}}, noise_px=0.1, seed=1, shrink_px=0.6
    )
    idx = np.arange(len(items))
    fit, choose = idx[idx % 3 != 0], idx[idx % 3 == 0]
    axes = np.array([False, True, False, False, False, False])
    search = ModelSearch(rig, base, items, fit, choose, fit, axes)
    cands = [c for c in CANDIDATES.values() if isinstance(c, ProjectionCandidate)]
    chosen = search.select(search.rank(cands, significant=True))
    assert chosen.effects == ["focal_length"]
    # measured -0.0310: the edge offset takes 3 % of it
    assert chosen.fits[0][1].params["scale"] == pytest.approx(-0.03, rel=0.05)
    # measured 0.56 px: the 0.6 px edge offset is left (tag_scale alone gives 4.26 px)
    assert chosen.corner_gap_after_px < 0.7
    # without refit, the focal length moves the choose split's depth by ~28 noise units
    assert search.contributions(chosen)["focal_length"] > 10


def _field(gap: np.ndarray, sigma: float = 2e-4) -> gapmod.GapField:
    import xarray as xr

    tags, ps, thetas = [0], np.arange(15), np.deg2rad(np.arange(0, 60, 10))
    da = xr.DataArray(
        gap,
        coords={"tag": tags, "p": ps, "theta": thetas, "axis": list(AXES)},
        dims=("tag", "p", "theta", "axis"),
    )
    ones = xr.ones_like(da.isel(axis=0))
    sig = xr.DataArray(
        [sigma, sigma, sigma, 4e-3, 4e-3, 4e-3], coords={"axis": list(AXES)}, dims="axis"
    )
    return gapmod.GapField(da, sig, ones.astype(bool), ones, ones)


def test_gap_significance_noise_versus_trend():
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 2e-4, (1, 15, 6, 6))
    noise[..., 3:] = rng.normal(0, 4e-3, (1, 15, 6, 3))
    quiet = gapmod.axis_summary(_field(noise))
    assert not any(a.significant for a in quiet.values())
    trend = noise.copy()
    trend[..., 1] += -0.0007 * np.arange(15)[None, :, None]  # ty: -0.7 mm per pin hole
    loud = gapmod.axis_summary(_field(trend))
    assert loud["ty"].significant and not loud["tx"].significant
    # Theil-Sen on 90 points with 0.2 mm noise: slope within 5 %
    assert loud["ty"].slope_per_pin == pytest.approx(-0.0007, rel=0.05)
    small = noise.copy()
    small[..., 1] += 2e-4  # statistically clear but below the practical floor (0.5 mm)
    assert not gapmod.axis_summary(_field(small))["ty"].significant


def test_detection_mismatch_compares_rates_where_the_limit_is_crossed():
    """Losing as many tags as the capture in the same group matches, whichever ones they are."""
    from simgap.analysis.gap import detection_score
    from simgap.analysis.thresholds import DETECTION_UNIT

    real = np.array([1.0, 0.0, 1.0, 0.0, 1.0, 1.0])
    swapped = np.array([0.0, 1.0, 0.0, 1.0, 1.0, 1.0])  # the same losses, other tags
    views = np.array([0, 0, 1, 1, 2, 2])
    # six items: the unit is one item's share (1/6), so four tags swapped are 4 units
    assert detection_score(real, swapped) == pytest.approx(4.0)
    assert detection_score(real, swapped, [views]) == pytest.approx(0.0)
    nothing_lost = np.ones(6)
    assert detection_score(real, nothing_lost, [views]) == pytest.approx(2.0)
    # from twenty items on, the unit is DETECTION_UNIT (5 %)
    many_real, many_pred = np.tile(real, 5), np.tile(swapped, 5)
    assert detection_score(many_real, many_pred) == pytest.approx(4 / 6 / DETECTION_UNIT)


def _search(rig, hidden: dict[str, dict], seed: int = 1, shrink_px: float = 0.0) -> ModelSearch:
    """A model search over exact corners with 0.2 px detector-like noise (:func:`_items`)."""
    items, base = _items(rig, hidden, noise_px=0.2, seed=seed, shrink_px=shrink_px)
    idx = np.arange(len(items))
    fit, choose = idx[idx % 3 != 0], idx[idx % 3 == 0]
    return ModelSearch(rig, base, items, fit, choose, fit, np.ones(6, bool))


def _select(search: ModelSearch) -> Scored | None:
    cands = [c for c in CANDIDATES.values() if isinstance(c, ProjectionCandidate)]
    return search.select(search.rank(cands, significant=True))


def test_a_lens_distortion_the_corners_single_out_is_reported_as_minor():
    """Issue 25: a distortion that moves no pose beyond the floor is still a finding (minor).

    k1 0.05: corners 0.31 -> 0.21 px on the choose split, poses within their noise (0.64 ->
    0.66), pose contribution 0.53 (measured). Before, it could not enter (no pose 10 % closer),
    and a carriage pitch of -0.2 % that moved nothing took its place by parsimony.
    """
    rig = load_rig()
    search = _search(rig, {"lens_distortion": {"k1": 0.05}})
    chosen = _select(search)
    assert chosen.effects == ["lens_distortion"]
    assert search.minor(chosen) == ["lens_distortion"]
    # measured 0.0486 (k1 alone: k2 does not lower the items' corners consistently)
    assert chosen.fits[0][1].params["k1"] == pytest.approx(0.05, abs=0.012)
    # a calibration file that claims a distortion the lens does not have reads the same way
    # (the simulation renders the claimed k1 0.08, the lens has none): measured k1 -0.087
    search = _search(rig, {"lens_distortion": {"k1": -0.08}})
    chosen = _select(search)
    assert chosen.effects == ["lens_distortion"]
    assert chosen.fits[0][1].params["k1"] == pytest.approx(-0.08, abs=0.015)


def test_a_distortion_the_corners_show_is_not_refused_for_pose_noise():
    """A corner-signature effect stays seen while the pose gap moves within its noise.

    Blind seed 34 trial 42: a lens (k1 0.126) fitted to k1 0.110 lowered the corner gap 0.316 ->
    0.218 px while the pose gap of seven tags rose 0.373 -> 0.418 (12 %, within the pose
    channel's quarter-unit tolerance): refused under a 10 % rule, it is seen now. A pose gap
    larger by more than the tolerance still refuses it.
    """
    from simgap.analysis.search import seen_in_corners
    from simgap.analysis.thresholds import EQUIVALENT_REL, EQUIVALENT_UNITS

    rig = load_rig()
    search = _search(rig, {"lens_distortion": {"k1": 0.05}})
    lens = search.evaluate((CANDIDATES["lens_distortion"],))
    before = lens.pose_gap_all_axes_before
    assert seen_in_corners(lens, None)
    # the pose channel's tolerance at this gap; just inside it the lens is seen, just beyond not
    tolerance = max(EQUIVALENT_UNITS, EQUIVALENT_REL * before)
    inside = dataclasses.replace(lens, pose_gap_all_axes_after=before + 0.9 * tolerance)
    beyond = dataclasses.replace(lens, pose_gap_all_axes_after=before + 1.1 * tolerance)
    assert seen_in_corners(inside, None)
    assert not seen_in_corners(beyond, None)


# the 2 px smear runs with the slow tests (20 s): the 3 px one runs the same code by default
@pytest.mark.parametrize("smear_px", [pytest.param(2.0, marks=pytest.mark.slow), 3.0])
def test_geometry_fitted_to_corners_something_else_moved_is_refused(smear_px):
    """A one-sided horizontal smear of the corners is no geometry: the model the search finds
    leaves them more than GEOMETRY_CORNER_GAP_PX off, is refused, and nothing is selected.

    Blind seed 35 trial 6: a 6 px motion blur was answered with a camera mount that moved the
    corners 2.01 -> 1.77 px. Measured here: a lens distortion the corners single out leaves 1.37
    px of 1.48 (2 px smear) and 2.07 px of 2.16 (3 px); a focal length of +1.7 % with 0.2 px
    noise leaves 0.20 px and is kept. (A 1 px smear leaves 0.70 px beside a minor distortion:
    below the threshold, the distortion stays.)
    """
    from simgap.analysis.thresholds import GEOMETRY_CORNER_GAP_PX

    rig = load_rig()
    items, base = _items(rig, {}, noise_px=0.2, seed=1, smear_px=smear_px)
    idx = np.arange(len(items))
    fit, choose = idx[idx % 3 != 0], idx[idx % 3 == 0]
    search = ModelSearch(rig, base, items, fit, choose, fit, np.ones(6, bool))
    chosen = _select(search)
    assert chosen is None
    assert search.refused_geometry.corner_gap_after_px > GEOMETRY_CORNER_GAP_PX
    kept = _search(rig, {"focal_length": {"scale": 0.017}})
    assert _select(kept).effects == ["focal_length"] and kept.refused_geometry is None


def test_a_value_at_the_end_of_its_range_is_on_its_bound():
    """Within ``AT_BOUND_SHARE`` of the range's largest magnitude from an end: on the bound."""
    from simgap.analysis.candidates import on_bound

    assert on_bound(4.95, 0.1, 5.0) and on_bound(0.1, 0.1, 5.0) and not on_bound(2.5, 0.1, 5.0)
    assert on_bound(-0.246, -0.25, 0.25) and not on_bound(0.2, -0.25, 0.25)


@pytest.mark.slow
def test_a_model_with_a_parameter_on_its_search_bound_is_no_finding():
    """A fit that runs into the end of its searched range stands in for something else (a 28 %
    print scale, beyond tag_scale's 25 % range): listed, never selected.

    Marked slow (90 s on 2 cores: a whole selection); ``on_bound`` on its own is tested by
    default (:func:`test_a_value_at_the_end_of_its_range_is_on_its_bound`), and every blind
    validation counts the trials with a selected parameter on its bound. Run it with
    ``pytest -m slow``.
    """
    from simgap.analysis.search import at_bound

    rig = load_rig()
    search = _search(rig, {"tag_scale": {"scale": 0.28}})
    chosen = _select(search)
    bound = {s.effects[0]: s for s in search.on_bound}
    assert "tag_scale" in bound and at_bound(bound["tag_scale"])
    assert bound["tag_scale"].fits[0][1].params["scale"] == pytest.approx(0.25, abs=0.005)
    assert chosen is None or "tag_scale" not in chosen.effects


@pytest.mark.parametrize(
    "translation_m, offset_effects",
    [((0.003, 0.0, 0.0), {"camera_mount"}), ((0.0, 0.0, -0.004), {"camera_mount", "tag_offset"})],
)
def test_a_focal_length_and_a_camera_offset_are_found_together(translation_m, offset_effects):
    """Issue 25: focal length +1.5 % with the camera 3-4 mm off. Both are found, the scale within
    2 % of itself (measured 0.01462-0.01473). Along the turntable axis a camera offset and a
    common offset of every tag are the same geometry (measured: equivalent models, 0.216 against
    0.221 px); the simpler tag offset may then be named, the mount listed beside it."""
    rig = load_rig()
    hidden = {"focal_length": {"scale": 0.015}, "camera_mount": {"translation_m": translation_m}}
    chosen = _select(_search(rig, hidden))
    fitted = {f.effect: f.params for _, f in chosen.fits}
    assert "focal_length" in fitted and len(fitted) == 2
    assert set(fitted) - {"focal_length"} <= offset_effects
    assert fitted["focal_length"]["scale"] == pytest.approx(0.015, rel=0.03)
    offset = fitted.get("camera_mount", {}).get("translation_m")
    offset = offset if offset is not None else fitted["tag_offset"]["offset_m"]
    # measured within 0.07 mm of the 3-4 mm offset
    assert np.linalg.norm(offset) == pytest.approx(np.linalg.norm(translation_m), abs=2e-4)


def test_the_detection_channel_is_capped_like_an_image_statistic():
    """Two of eight tags lost more than the capture (25 %, 5 units) count as the cap, 3 units:
    the blur of blind seed 30's trial 13 lost them and a print scale won on 5 units."""
    from simgap.analysis.gap import evidence_channels
    from simgap.analysis.thresholds import RESIDUAL_CAP

    channels = evidence_channels(0.4, 0.7, 5.0, np.array([1.0, 4.0]), 0.2)
    # corners 0.4 px over the 0.2 px unit, pose as given, detection capped, image stats as given
    np.testing.assert_allclose(channels, [2.0, 0.7, RESIDUAL_CAP, 1.0, 4.0])
    assert evidence_channels(0.4, 0.7, 1.5, np.array([0.0]), 0.2)[2] == 1.5


def test_the_search_reports_its_progress_once_per_model_fitted():
    """The steps the command line draws as bars (issue 29): ``fitting candidates`` counts to the
    number of candidates, ``model search`` (length unknown) one per model fitted; a memoised
    model is not fitted again and not counted."""
    from simgap.core.progress import Steps

    rig = load_rig()
    items, base = _items(rig, {"tag_scale": {"scale": 0.01}}, noise_px=0.1, seed=2)
    idx = np.arange(len(items))
    fit, choose = idx[idx % 3 != 0], idx[idx % 3 == 0]
    seen = []
    search = ModelSearch(
        rig,
        base,
        items,
        fit,
        choose,
        fit,
        np.ones(6, bool),
        steps=Steps(lambda *report: seen.append(report)),
    )
    cands = [CANDIDATES["tag_scale"], CANDIDATES["focal_length"]]
    ranking = search.rank(cands, significant=True)
    assert seen == [("fitting candidates", n, 2) for n in range(3)]
    seen.clear()
    search.rank(cands, significant=True)  # memoised: the bar restarts and nothing is fitted
    assert seen == [("fitting candidates", 0, 2)]
    seen.clear()
    assert search.select(ranking).effects == ["tag_scale"]
    assert seen == [("model search", n, None) for n in range(len(search.tried) - 1)]
    assert len(seen) >= 2  # at least the pair tag_scale + focal_length was fitted


def test_the_confirmation_counts_every_item():
    """``SimRunner.errors`` reports one unit per item (the confirmation re-render's bar) and runs
    each configuration once for all its tags."""
    from types import SimpleNamespace

    from simgap.diagnosis.sim_runner import SimRunner
    from simgap.pose.image_stats import STAT_NAMES
    from simgap.pose.tags import ConfigResult

    rig = load_rig()
    items, base = _items(rig, {})
    runs = []

    def run(exp, state, p, theta, repeat=0):
        runs.append((p, theta))
        n = 2  # tags 0 and 1, errors p mm on tx
        return ConfigResult(
            np.ones(n, bool),
            np.zeros((n, 6)),
            np.tile([p * 1e-3, 0, 0, 0, 0, 0], (n, 1)),
            np.zeros(n),
            np.zeros((n, 4, 2)),
            np.zeros((n, len(STAT_NAMES))),
        )

    simulator = SimpleNamespace(tags=lambda exp: (0, 1), state_key=lambda exp, s: "s", run=run)
    runner = SimRunner(SimpleNamespace(rig_model=rig, repeats=1), simulator)
    ticks = []
    errors = runner.errors(base, items, lambda: ticks.append(1))
    assert len(ticks) == len(items)
    assert len(runs) == len(set(zip(items.p, items.theta, strict=True)))
    np.testing.assert_array_equal(errors[:, 0], items.p * 1e-3)


def test_a_calibration_distortion_beside_a_focal_length_is_named():
    """Issue 25, blind seed 32: a calibration file's distortion (the simulation renders the
    claimed k1, the lens has none; here the lens has k1 -0.09 the simulation lacks) beside a
    focal length of -1.5 %. Alone, the distortion fit runs onto k2's bound (it stands in for the
    focal length too: measured k1 -0.43, k2 1.5) and was never tried beside the focal length;
    refitted jointly it is off its bound and named (measured scale -0.01538, k1 -0.0851)."""
    rig = load_rig()
    hidden = {"focal_length": {"scale": -0.015}, "lens_distortion": {"k1": -0.09}}
    search = _search(rig, hidden)
    chosen = _select(search)
    assert [s.effects for s in search.on_bound] == [["lens_distortion"]]
    fitted = {f.effect: f.params for _, f in chosen.fits}
    assert set(fitted) == {"focal_length", "lens_distortion"}
    assert fitted["focal_length"]["scale"] == pytest.approx(-0.015, rel=0.05)
    assert fitted["lens_distortion"]["k1"] == pytest.approx(-0.09, abs=0.015)


def _squares(sizes: np.ndarray) -> np.ndarray:
    """Axis-aligned squares (N, 4, 2) whose corners lie ``sizes`` px from their centres."""
    unit = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) / np.sqrt(2)
    centres = np.column_stack([np.linspace(100, 900, len(sizes)), np.full(len(sizes), 300.0)])
    return centres[:, None, :] + sizes[:, None, None] * unit[None]


def test_a_size_change_tells_a_print_scale_from_an_edge_offset():
    """A print scale changes every tag's size by the same share; an edge offset by the same
    pixels; a defocus by an offset that changes with depth (so with size). 0.05 px of corner
    noise (seed 0), 30 tags of 25-95 px (the sizes of the blind captures)."""
    from simgap.analysis.candidates import size_change

    rng = np.random.default_rng(0)
    sizes = np.linspace(25.0, 95.0, 30)
    sim = _squares(sizes)

    def real(new_sizes):
        return _squares(new_sizes) + rng.normal(0.0, 0.05, sim.shape)

    scale = size_change(real(sizes * 1.02), sim)
    assert scale.slope == pytest.approx(0.02, abs=0.002)
    assert abs(scale.slope_z) > 20 and abs(scale.zero_share) < 0.3
    offset = size_change(real(sizes - 0.5), sim)  # a softer camera's edge offset
    assert abs(offset.slope_z) < 4 and offset.offset_px == pytest.approx(-0.5, abs=0.05)
    crossing = size_change(real(sizes * 0.94 + 3.0), sim)  # seed 31 trial 17's defocus
    assert abs(crossing.slope_z) > 4 and crossing.zero_share > 1.0


# the 0.6 px shrink runs with the slow tests (10 s): the 0.3 px one runs the same code by default
@pytest.mark.parametrize("shrink_px", [0.3, pytest.param(0.6, marks=pytest.mark.slow)])
def test_a_print_scale_does_not_follow_an_edge_offset(shrink_px):
    """Issue 25: a softer camera moves every detected corner towards the tag's centre by about
    the same pixels; a print scale fitted to it (-0.6 % for 0.3 px here) is no finding, while a
    true print scale of 2.5 % still is (its size change stood 20.8 standard errors out,
    measured)."""
    from simgap.analysis.search import grows_with_size

    rig = load_rig()
    items, base = _items(rig, {}, noise_px=0.2, seed=1, shrink_px=shrink_px)
    idx = np.arange(len(items))
    search = ModelSearch(
        rig, base, items, idx[idx % 3 != 0], idx[idx % 3 == 0], idx, np.ones(6, bool)
    )
    scored = search.evaluate((CANDIDATES["tag_scale"],))
    assert scored.fits[0][1].params["scale"] < -0.004  # it does follow the offset
    assert not grows_with_size(scored.fits[0][1])
    chosen = _select(search)
    assert chosen is None or "tag_scale" not in chosen.effects
    true_scale = _search(rig, {"tag_scale": {"scale": 0.025}})
    assert _select(true_scale).effects == ["tag_scale"]


def test_a_look_alike_that_led_is_swapped_for_the_effect_that_explains_better():
    """Issue 25, blind seed 31 trial 5: a print scale led a focal length's capture alone (a defocus
    beside it hid the difference), and the greedy search kept it once the defocus had joined.
    Simplifying now swaps a projection effect for one with as many parameters that explains the
    evidence distinguishably better: from a print scale on a -2.2 % focal length's corners
    (measured evidence 15.7) to the focal length (1.21, scale -0.02221)."""
    rig = load_rig()
    search = _search(rig, {"focal_length": {"scale": -0.022}})
    pool = [c for c in CANDIDATES.values() if isinstance(c, ProjectionCandidate)]
    led = search.evaluate((CANDIDATES["tag_scale"],))
    swapped = search.simplify(led, pool)
    assert swapped.effects == ["focal_length"]
    assert swapped.evidence_after < 0.2 * led.evidence_after
    assert swapped.fits[0][1].params["scale"] == pytest.approx(-0.022, rel=0.03)


def test_a_distortion_the_corners_single_out_joins_a_model_and_stands_alone():
    """A lens distortion is added beside a chosen model, and found where nothing else differs.

    Blind seed 37: the greedy search added the appearance effects that lowered the image
    statistics most and pruned them, and exposure + lens distortion (admissible, corners 0.244 ->
    0.213 px) was never reached; a capture where no evidence family differed significantly was
    not searched at all (trial 45, corners 0.336 -> 0.172 px with the lens). Here a focal length
    + 1.5 % with a lens k1 -0.06 on 0.2 px corner noise: the lens joins the focal-length model
    (measured k1 -0.055, k2 -0.020); without a lens nothing joins; pure corner noise has no
    corner finding.
    """
    from simgap.analysis.search import corner_effect_alone, with_corner_effects

    rig = load_rig()
    focal, lens = CANDIDATES["focal_length"], CANDIDATES["lens_distortion"]
    pool = [c for c in CANDIDATES.values() if isinstance(c, ProjectionCandidate)]
    search = _search(rig, {"focal_length": {"scale": 0.015}, "lens_distortion": {"k1": -0.06}})
    model = with_corner_effects(search.evaluate((focal,)), pool, search.evaluate, 5)
    assert model.effects == ["focal_length", "lens_distortion"]
    assert dict(model.fits)[lens].params["k1"] == pytest.approx(-0.06, abs=0.015)
    search = _search(rig, {"focal_length": {"scale": 0.015}})
    model = with_corner_effects(search.evaluate((focal,)), pool, search.evaluate, 5)
    assert model.effects == ["focal_length"]

    search = _search(rig, {"lens_distortion": {"k1": 0.05}})
    alone = corner_effect_alone(search.rank(pool, significant=False))
    assert alone is not None and alone.effects == ["lens_distortion"]
    search = _search(rig, {})
    assert corner_effect_alone(search.rank(pool, significant=False)) is None


def test_a_fixture_change_that_moves_no_pose_stays_only_where_the_corners_show_it(monkeypatch):
    """A minor camera mount beside a blur is pruned unless it lowers the corners beyond 10 %.

    Blind seeds 33-39: all four minor changes of the fixture's transform tree were not in the
    capture; the corners had singled them out only item by item (seed 38 trial 26: a 0.24 mm mount
    beside a laminate, corners 0.482 -> 0.447 px). Blind seed 40: true carriage pitches of 1.1 and
    2.1 % beside the camera's blur were minor on a noisy one-frame capture and lowered the corners
    0.44 -> 0.20 and 0.91 -> 0.23 px (:func:`simgap.analysis.search.pruned`). Here the evidence
    keeps every effect (``as_good`` false): a mount that moves no pose and lowers the corners
    0.48 -> 0.45 px leaves; one that lowers them 0.44 -> 0.20 px stays, and so does one that
    moves the pose; a principal point that moves no pose stays (a calibration file may know the
    intrinsics, so they can move corners and no pose) where it moves the predicted corners by
    the detector's own corner bias (MINOR_CORNER_SHIFT_PX, 0.2 px) or more. Blind seed 73 trial
    2 (a sun, nothing geometric hidden) named a principal point of (0.14, 0.05) px that lowered
    the corners 0.25 -> 0.19 px: it moves them by less than that bias, and leaves.
    """
    from dataclasses import dataclass as _dataclass

    from simgap.analysis.gap import Prediction
    from simgap.analysis.search import pruned

    @_dataclass
    class Model:
        fits: list
        corner_gap_after_px: float
        prediction: Prediction
        corner_unit_px: float = 0.2
        evidence_after: float = 1.0

        @property
        def effects(self) -> list[str]:
            return [c.effect for c, _ in self.fits]

    def case(corners_with: float, corners_without: float, shift_px: float = 1.0):
        """Models with and without the second effect; it moves every predicted corner along x."""

        def model(*names: str) -> Model:
            full = len(names) == 2
            corners = np.zeros((8, 4, 2))
            corners[..., 0] += shift_px if full else 0.0
            prediction = Prediction(np.zeros((8, 6)), corners)
            gap = corners_with if full else corners_without
            return Model([(CANDIDATES[n], Fit(n, {})) for n in names], gap, prediction)

        return model, lambda candidates: model(*(c.effect for c in candidates))

    def weights(mount: float, pp: float):
        return lambda m: {"blur": 5.0, "camera_mount": mount, "principal_point": pp}

    # the evidence keeps them all: the rule pruned() reads, in its private module
    monkeypatch.setattr("simgap.analysis.search._pruning.as_good", lambda a, b: False)
    model, evaluate = case(0.45, 0.48)
    assert pruned(model("blur", "camera_mount"), evaluate, weights(0.2, 0.0)).effects == ["blur"]
    kept = pruned(model("blur", "principal_point"), evaluate, weights(0.0, 0.2))
    assert kept.effects == ["blur", "principal_point"]
    moving = pruned(model("blur", "camera_mount"), evaluate, weights(3.0, 0.0))
    assert moving.effects == ["blur", "camera_mount"]
    model, evaluate = case(0.20, 0.44)
    seen = pruned(model("blur", "camera_mount"), evaluate, weights(0.2, 0.0))
    assert seen.effects == ["blur", "camera_mount"]
    model, evaluate = case(0.19, 0.25, shift_px=0.15)
    faint = pruned(model("blur", "principal_point"), evaluate, weights(0.0, 0.0))
    assert faint.effects == ["blur"]
    model, evaluate = case(0.19, 0.25, shift_px=0.25)
    shown = pruned(model("blur", "principal_point"), evaluate, weights(0.0, 0.0))
    assert shown.effects == ["blur", "principal_point"]


def test_a_focal_length_beside_a_print_scale_is_not_answered_as_a_mount():
    """Blind seed 72 trial 8's pair: a focal length of -2.1 % and a print 1.2 % large, whose depth
    scales nearly cancel. A camera mount leads alone, and the greedy search from it alone ended
    in a mount and a principal point (combined misfit 3.70, measured with one start); starting
    again from the next geometric effects (MODEL_SEARCH_STARTS) finds the pair (1.22): measured
    -0.0212 and +0.0121."""
    rig = load_rig()
    hidden = {"focal_length": {"scale": -0.021}, "tag_scale": {"scale": 0.012}}
    chosen = _select(_search(rig, hidden))
    assert chosen is not None and sorted(chosen.effects) == sorted(hidden)
    for _, fit in chosen.fits:
        assert fit.params["scale"] == pytest.approx(hidden[fit.effect]["scale"], rel=0.05)


@pytest.mark.parametrize(
    "hidden",
    [
        {"tag_scale": {"scale": -0.021}, "turntable_offset": {"angle_rad": -0.021}},
        {"tag_scale": {"scale": -0.015}, "carriage_pitch": {"scale": -0.013}},
    ],
    ids=["print+turntable", "print+carriage"],
)
def test_two_geometric_effects_that_hide_each_other_are_found_together(hidden):
    """Issue 25, blind seed 42 trials 70 and 51 (the pairs' values): alone, neither effect may
    enter (the other's share of the gap stays in the corners: a print scale's size change is
    not significant beside the rotation, or is cancelled by the carriage's depth change; the
    turntable offset moves the print-dominated pose gap by 2 %). Without the pair step the
    search named nothing on these exact corners (measured); with it both, each parameter
    within 6 % of the truth (measured: -0.0211, -0.021; -0.015, -0.0123, the largest 5.4 %)."""
    rig = load_rig()
    chosen = _select(_search(rig, hidden))
    assert chosen is not None and sorted(chosen.effects) == sorted(hidden)
    for _, fit in chosen.fits:
        for key, value in hidden[fit.effect].items():
            assert fit.params[key] == pytest.approx(value, rel=0.06)
