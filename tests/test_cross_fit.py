"""Cross-fitted corner evidence: the two folds' residuals, the paired test, nested lens fits."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_diagnose import _items, _search, _select

from simgap.analysis.candidates import CANDIDATES, ProjectionCandidate
from simgap.analysis.gap import (
    MIN_PAIRED_ITEMS,
    clearly_lower,
    item_centre_residuals_px2,
    item_residuals_px2,
)
from simgap.analysis.search import (
    ModelSearch,
    as_good,
    as_good_cross_fitted,
    corner_residuals,
    equivalent_models,
    generalises_better,
    improves_on_nothing,
    parsimonious,
    seen_in_centres,
    seen_in_corners,
    stands_in_for,
    with_corner_effects,
    without_displaced,
    worsens_pose,
)
from simgap.analysis.thresholds import MIN_POSE_REDUCTION
from simgap.core.rig import load_rig
from simgap.diagnosis.diagnose import equivalent_alternatives


def test_clearly_lower_needs_a_consistent_improvement():
    rng = np.random.default_rng(0)
    b = rng.uniform(0.5, 1.5, 30)
    # every item 10 % lower: consistent
    assert clearly_lower(0.9 * b, b)
    # the same residuals with noise of either sign around them: no direction
    assert not clearly_lower(b + rng.normal(0.0, 0.2, b.size), b)
    # consistent, but by less than the smallest share (PAIRED_MIN_SHARE, 5 %)
    assert not clearly_lower(0.97 * b, b)
    # too few items to test; items missing on either side are left out
    assert not clearly_lower(0.5 * b[: MIN_PAIRED_ITEMS - 1], b[: MIN_PAIRED_ITEMS - 1])
    a = 0.9 * b
    a[:3] = np.nan
    assert clearly_lower(a, b)


def test_every_searched_item_is_predicted_by_the_other_folds_fit():
    """A searched model's corner residuals cover the choose split (model fitted on the fit split)
    and then the fit split, predicted by the model refitted on the choose split."""
    rig = load_rig()
    search = _search(rig, {"lens_distortion": {"k1": 0.05}})
    lens = CANDIDATES["lens_distortion"]
    scored = search.evaluate((lens,))
    n_choose, n_fit = len(search.choose_index), len(search.fit_index)
    residuals = corner_residuals(scored, cross_fitted=True)
    before = corner_residuals(scored, before=True, cross_fitted=True)
    assert residuals.shape == before.shape == (n_choose + n_fit,)
    # the model search's own comparisons keep the choose split
    assert corner_residuals(scored).shape == (n_choose,)
    # the second fold, computed here without the search (on the simulation fits' items: here the
    # whole fit split)
    assert np.array_equal(search.sim_fit_index, search.fit_index)
    choose, fit = search.items.subset(search.choose_index), search.items.subset(search.fit_index)
    refit = lens.fit(rig, search.base, choose)
    predicted = fit.sim_corners + lens.corner_shift(rig, search.base, refit.extra["x"], fit)
    expected = np.sum((fit.real_corners - predicted) ** 2, axis=-1).mean(axis=-1)
    np.testing.assert_allclose(residuals[n_choose:], expected, rtol=1e-12)
    np.testing.assert_allclose(
        before[n_choose:],
        np.sum((fit.real_corners - fit.sim_corners) ** 2, axis=-1).mean(axis=-1),
        rtol=1e-12,
    )
    # the lens is right: lower on both folds (measured medians 0.47x and 0.79x the simulation's)
    assert np.median(residuals[:n_choose]) < 0.6 * np.median(before[:n_choose])
    assert np.median(residuals[n_choose:]) < 0.9 * np.median(before[n_choose:])


def test_a_report_split_score_is_not_cross_fitted():
    """Scored outside the search (the measure split), a model has its own items only: asked for
    cross-fitted residuals it raises (a paired test against a cross-fitted model would compare
    other items)."""
    rig = load_rig()
    search = _search(rig, {"lens_distortion": {"k1": 0.05}})
    scored = search.evaluate((CANDIDATES["lens_distortion"],))
    reported = search.score(scored.fits, scored.projection[:2], search.choose_index)
    assert corner_residuals(reported).shape == (len(search.choose_index),)
    with pytest.raises(ValueError, match="not cross-fitted"):
        corner_residuals(reported, cross_fitted=True)
    with pytest.raises(ValueError, match="not cross-fitted"):
        corner_residuals(dataclasses.replace(scored, cross_fit_difference=None), cross_fitted=True)


@pytest.mark.parametrize(
    "hidden, noise_px, k2_released, k1_tolerance",
    [
        # a lens with k1 alone: k2 stays zero (fitted always, it took 0.020 and k1 -0.0835;
        # nested, measured k1 -0.0811)
        ({"k1": -0.08}, 0.2, False, 0.003),
        # a D435-like module (k1 0.16, k2 -0.48, k3 0.42) whose corners demand k2: released
        # (measured k1 0.157, k2 -0.398, corners 0.005 px RMS)
        ({"k1": 0.16, "k2": -0.48, "k3": 0.42}, 0.0, True, 0.005),
        ({"k1": 0.1, "k2": -0.45}, 0.0, True, 1e-6),
    ],
)
def test_a_lens_fit_frees_k2_only_where_the_corners_need_it(
    hidden, noise_px, k2_released, k1_tolerance
):
    """Issue 25, blind seed 44 trial 39: a lens without distortion (a calibration file that
    claims k1 0.062) fitted k1 0.017, k2 -0.25 on central tags; with k1 alone, 0.006. The
    nested fit keeps k2 at zero unless it lowers the items' corners consistently
    (:func:`simgap.analysis.gap.clearly_lower`). Tolerances from the measured values (in the
    comments). Under 0.2 px of corner noise the D435-like lens keeps k1 alone on these items
    (measured k1 0.115): k2 lowers the median item by 1.9 %, at p = 0.025 (the gain is at the
    outer tags); on development seed 44 every lens but two read k1 within 10 %
    (docs/validation.md)."""
    rig = load_rig()
    items, base = _items(rig, {"lens_distortion": hidden}, noise_px=noise_px, seed=1)
    fit = CANDIDATES["lens_distortion"].fit(rig, base, items)
    assert (fit.params["k2"] != 0.0) == k2_released
    assert fit.params["k1"] == pytest.approx(hidden["k1"], abs=k1_tolerance)


@pytest.mark.parametrize("shrink_px, measured_scale", [(0.2, -0.0186), (0.3, -0.0182)])
def test_a_carriage_pitch_is_seen_in_the_tag_centres_where_edges_bias_the_depth(
    shrink_px, measured_scale
):
    """Blind seed 45 trials 19, 56, 63 (development since): a camera whose edges differ (each
    corner drawn ``shrink_px`` towards the tag's centre, as overexposure with softer optics
    does) reads every tag smaller, so further away; a carriage pitch of -2 % brings the far
    tags closer. The right pitch fit then leaves a *larger* pose gap (measured 1.34 -> 1.36 and
    0.80 -> 1.77): refused by the pose (:func:`~simgap.analysis.search.worsens_pose`). The tag
    centres carry no edge bias and single it out (cross-fitted, item by item,
    :func:`~simgap.analysis.search.seen_in_centres`), and the search names it. The fitted
    scale is biased by the edges by 7-9 % (measured values in the parameters; tolerance 10 % of
    the truth)."""

    rig = load_rig()
    search = _search(rig, {"carriage_pitch": {"scale": -0.02}}, shrink_px=shrink_px)
    pitch = search.evaluate((CANDIDATES["carriage_pitch"],))
    assert pitch.pose_gap_all_axes_after > pitch.pose_gap_all_axes_before
    assert worsens_pose(pitch, None, tolerance=-MIN_POSE_REDUCTION)
    assert seen_in_centres(pitch, None)
    chosen = _select(search)
    assert chosen.effects == ["carriage_pitch"]
    # the measured value, to the third decimal of a percent (the fit is deterministic; 1e-3 of
    # slack for the optimiser's tolerance), and within 10 % of the truth
    assert chosen.fits[0][1].params["scale"] == pytest.approx(measured_scale, abs=1e-3)
    assert chosen.fits[0][1].params["scale"] == pytest.approx(-0.02, abs=0.002)


def test_an_edge_bias_alone_moves_no_tag_centre():
    """The negative control: the same edge bias on a capture without any effect lowers no
    centre for any geometric candidate (a print scale follows the shrink and moves no centre at
    all)."""

    rig = load_rig()
    search = _search(rig, {}, shrink_px=0.3)
    for candidate in CANDIDATES.values():
        if isinstance(candidate, ProjectionCandidate):
            assert not seen_in_centres(search.evaluate((candidate,)), None), candidate.effect


def test_a_look_alike_displaced_by_a_corner_effect_leaves():
    """Blind seed 45 trial 69: a focal length that entered on centres a distortion had moved
    leaves once the lens distortion joins it
    (:func:`~simgap.analysis.search.without_displaced`); a true one stays. Beside the
    right lens a look-alike focal length fits -0.01 % and moves the pose gap by 1-5 % (noise
    seeds 2-7, measured; on seed 1 it happens to lower the pose gap 11 %, as pose noise may)."""

    rig = load_rig()
    lens, focal = CANDIDATES["lens_distortion"], CANDIDATES["focal_length"]
    for hidden, kept in (
        ({"lens_distortion": {"k1": 0.08}}, ["lens_distortion"]),
        (
            {"lens_distortion": {"k1": 0.08}, "focal_length": {"scale": 0.02}},
            ["focal_length", "lens_distortion"],
        ),
    ):
        search = _search(rig, hidden, seed=2)
        model = without_displaced(search.evaluate((focal, lens)), search.evaluate, lens)
        assert sorted(model.effects) == kept


def test_a_minor_finding_another_explains_as_well_in_its_place_is_undecided():
    """:meth:`~simgap.analysis.search.ModelSearch.look_alikes`: a principal point of 0.5 px, minor,
    is explained as well by a small camera rotation in its place on noise seed 1 (measured: a
    camera mount); on seed 3 the mount refitted on the choose split predicts the fit split's
    corners clearly worse (:func:`~simgap.analysis.search.generalises_better`), so the corners
    single the principal point out; a calibration file's distortion of k1 -0.08 is singled out by
    the corners (no look-alike on seeds 1 and 3); a focal length of +0.2 % moves the poses (not
    minor) and is not questioned."""
    rig = load_rig()
    cands = [c for c in CANDIDATES.values() if isinstance(c, ProjectionCandidate)]
    for hidden, effect, alikes in (
        (
            {"principal_point": {"dx_px": 0.5, "dy_px": 0.0}},
            "principal_point",
            {1: {"camera_mount"}, 3: set()},
        ),
        ({"lens_distortion": {"k1": -0.08}}, "lens_distortion", {1: set(), 3: set()}),
        ({"focal_length": {"scale": 0.002}}, "focal_length", {1: set(), 3: set()}),
    ):
        for seed, expected in alikes.items():
            search = _search(rig, hidden, seed=seed)
            ranking = search.rank(cands, significant=True)
            chosen = search.select(ranking)
            assert chosen is not None and chosen.effects == [effect], (hidden, seed)
            found = search.look_alikes(chosen, ranking)
            assert set(found.get(effect, ())) == expected, (hidden, seed, found)
            if effect == "focal_length":
                assert search.minor(chosen) == []


def test_a_tag_centre_is_blind_to_a_symmetric_edge_bias():
    """The centre residual: a square drawn in or out about its centre leaves it (0 px^2), a shift
    of (dx, dy) px gives dx^2 + dy^2."""
    square = np.array([[-10.0, -10.0], [10.0, -10.0], [10.0, 10.0], [-10.0, 10.0]])
    shrunk = 0.97 * square
    shifted = square + [0.3, -0.4]
    diff = np.stack([shrunk - square, shifted - square])
    np.testing.assert_allclose(item_centre_residuals_px2(diff), [0.0, 0.25], atol=1e-12)
    # the corner residual sees both
    assert np.all(item_residuals_px2(diff) > 0.08)


def test_a_corner_effect_displaces_a_look_alike_that_sorts_after_it():
    """Through :func:`~simgap.analysis.search.with_corner_effects`: a principal point of
    0.18 px that stood in for a lens (k1 0.08, noise seed 2) leaves when the lens joins, although
    it comes after the lens in the model's order (projection effects by name)."""
    rig = load_rig()
    search = _search(rig, {"lens_distortion": {"k1": 0.08}}, seed=2)
    start = search.evaluate((CANDIDATES["principal_point"],))
    model = with_corner_effects(start, [CANDIDATES["lens_distortion"]], search.evaluate, 4)
    assert model.effects == ["lens_distortion"]


def test_a_lens_the_cross_fitted_corners_show_is_found_where_nothing_starts_the_search():
    """Blind seed 46 trial 33: a lens (k1 0.082) the cross-fitted corners singled out
    (p = 0.0004, 27 items) lowered the evidence of a 9-item choose split too little to start
    the search, and nothing was named. Here k1 0.05 under 0.1 px of corner noise, a choose
    split of every fourth item (10 of 38): the lens alone does not improve on nothing on it, the
    cross-fitted corners single it out, and it is the answer (measured k1 0.0493; tolerance
    10 %)."""
    rig = load_rig()
    items, base = _items(rig, {"lens_distortion": {"k1": 0.05}}, noise_px=0.1, seed=1)
    idx = np.arange(len(items))
    fit, choose = idx[idx % 4 != 0], idx[idx % 4 == 0]
    search = ModelSearch(rig, base, items, fit, choose, fit, np.ones(6, bool))
    lens = search.evaluate((CANDIDATES["lens_distortion"],))
    assert not improves_on_nothing(lens)
    assert seen_in_corners(lens, None)
    chosen = _select(search)
    assert chosen.effects == ["lens_distortion"]
    assert chosen.fits[0][1].params["k1"] == pytest.approx(0.05, rel=0.1)


def test_a_geometry_that_predicts_cross_fitted_corners_better_is_not_tied():
    """Blind seed 46 trial 38: on six items a tag offset explained the choose split as
    well as the true camera mount (evidence 4.50 against 4.51) and parsimony named it; refitted
    on those few items it did not predict the others (median 0.60 px^2 against 0.08). Here a
    mount of (-2.8, 2.2, -1.2) mm on 24 items within 40 deg of each tag's frontal stop: the
    offset's choose-split evidence is made equal to the mount's, and the cross-fitted corners
    (measured, not made) still rule it out of the tie, and out of the mount's look-alikes."""
    rig = load_rig()
    items, base = _items(
        rig, {"camera_mount": {"translation_m": [-0.0028, 0.0022, -0.0012]}}, noise_px=0.2, seed=1
    )
    deg = np.degrees(items.theta) % 180
    sub = items.subset(np.flatnonzero(np.minimum(deg, 180 - deg) <= 40))
    idx = np.arange(len(sub))
    fit, choose = idx[idx % 3 != 0], idx[idx % 3 == 0]
    search = ModelSearch(rig, base, sub, fit, choose, fit, np.ones(6, bool))
    mount = search.evaluate((CANDIDATES["camera_mount"],))
    offset = search.evaluate((CANDIDATES["tag_offset"],))
    assert generalises_better(mount, offset)
    assert not generalises_better(offset, mount)
    tied = dataclasses.replace(
        offset,
        corner_gap_after_px=mount.corner_gap_after_px,
        pose_gap_all_axes_after=mount.pose_gap_all_axes_after,
        image_misfit_after=mount.image_misfit_after,
        detection_mismatch_after=mount.detection_mismatch_after,
        prediction=mount.prediction,
    )
    assert as_good(tied, mount)
    assert not as_good_cross_fitted(tied, mount)
    assert parsimonious([mount, tied]) is mount
    # nor a look-alike of the mount: the report does not leave the mount undecided against it
    assert equivalent_models(tied, mount)
    assert not stands_in_for(tied, mount)
    assert stands_in_for(mount, tied)
    # the report's equivalent models follow the same rule, each set of effects listed once
    assert equivalent_alternatives(mount, [tied, tied]) == []
    assert equivalent_alternatives(tied, [mount, mount]) == [mount]
    # not cross-fitted (a measure split's score), or the same geometry: no cross-fitted comparison
    assert not generalises_better(dataclasses.replace(mount, cross_fit_difference=None), offset)
    assert not generalises_better(mount, mount)


def test_a_corner_effect_must_lower_the_corners_by_the_channels_relative_tolerance():
    """Per-item corner residuals (px^2) that fall consistently but by less than 10 % in RMS do
    not single a lens out; the measured cases: a blur behind a tone curve, whose spurious
    k1 -0.015 lowered the corners 0.553 -> 0.533 px (3.6 %), and a true lens, 0.483 -> 0.244 px."""
    from simgap.analysis.search import clearly_smaller

    rng = np.random.default_rng(0)
    before = 0.553**2 * rng.uniform(0.5, 1.5, 40)
    assert not clearly_smaller(before * (0.533 / 0.553) ** 2, before)
    assert clearly_smaller(before * (0.244 / 0.483) ** 2, before)
    assert clearly_smaller(before * 0.899**2, before)  # just inside the tolerance
    assert not clearly_smaller(None, before) and not clearly_smaller(before, None)


def test_a_projection_fit_on_items_never_detected_on_both_sides_changes_nothing():
    """A split whose items were detected on neither side (a motion-blurred, crushed capture) fits
    no geometry and predicts no change, instead of failing; no configuration, no pose."""
    from simgap.analysis.candidates import CANDIDATES
    from simgap.diagnosis.telling_poses import grid_items
    from simgap.effects.state import VariantState

    rig = load_rig()
    assert rig.eyepoints_from_tags([], [], []).shape == (0, 4, 4)
    items = grid_items(rig).subset(np.arange(6))
    items.real_corners = np.full((6, 4, 2), np.nan)
    fit = CANDIDATES["camera_mount"].fit(rig, VariantState(), items)
    assert np.all(fit.extra["x"] == 0.0) and np.isnan(fit.extra["corner_rms_px"])
