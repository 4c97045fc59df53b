"""Experiments with variants: inheritance, validation, stage reuse, Dask, distortion accuracy."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import simgap.pipeline.sweep as sweep
import simgap.pipeline.variant as variant
from simgap.core.config import ConfigError
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.region import sticker_region
from simgap.pose.detect import Detector, DetectorSettings
from simgap.pose.estimate import project_tag_corners
from simgap.render import imaging
from simgap.render.scene import FixtureScene, load_scene_spec, projected_sticker_outlines


def _write(path, data):
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_inheritance_variants_and_grid(tmp_path):
    _write(
        tmp_path / "parent.yaml", {"name": "parent", "render": {"spp": 4, "seed": 3}, "repeats": 2}
    )
    child = _write(
        tmp_path / "child.yaml",
        {
            "name": "child",
            "inherit": "parent.yaml",
            "render": {"spp": 8},
            "variants": [{"name": "gloss", "effects": {"tag_gloss": {"alpha": 0.1}}}],
            "grid": {"exposure.ev": [-1, 1], "blur.sigma_px": [0.5, 1.0, 2.0]},
        },
    )
    exp = load_experiment(child)
    assert exp.render.spp == 8 and exp.render.seed == 3 and exp.repeats == 2
    names = [n for n, _ in exp.variant_states()]
    assert names[:2] == ["baseline", "gloss"] and len(names) == 2 + 6
    assert "exposure.ev=-1,blur.sigma_px=2.0" in names


@pytest.mark.parametrize(
    "data, message",
    [
        (
            {"variants": [{"name": "a", "effects": {"tag_gloss": {"alpha": 5}}}]},
            "variants[0].effects.tag_gloss.alpha",
        ),
        (
            {"variants": [{"name": "a", "effects": {"glossy": {}}}]},
            "variants[0].effects.glossy: unknown effect",
        ),
        ({"variants": [{"name": "a"}, {"name": "a"}]}, "variants: duplicate variant name 'a'"),
        ({"variants": [{"effects": {}}]}, "variants[0].name: required key is missing"),
        ({"grid": {"exposure": [1]}}, "grid.exposure: expected a key of the form effect.parameter"),
        ({"grid": {"exposure.evv": [1]}}, "grid: exposure.evv: unknown key"),
        ({"effects": {"blur": {"sigma_px": -1}}}, "effects.blur.sigma_px: expected 0 < sigma"),
        ({"repeats": 0}, "repeats: expected an integer >= 1"),
        ({"inherit": "missing.yaml"}, "inherit:"),
    ],
)
def test_variant_errors_name_file_and_key_path(tmp_path, data, message):
    path = _write(tmp_path / "bad.yaml", {"name": "bad", **data})
    with pytest.raises(ConfigError) as exc:
        load_experiment(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


def test_an_inheriting_experiment_removes_an_effect_with_null(tmp_path):
    _write(tmp_path / "orbit.yaml", {"name": "orbit", "effects": {"black_sky": {},
                                                                  "earthshine": {}}})  # fmt: skip
    child = _write(
        tmp_path / "surface.yaml",
        {"name": "surface", "inherit": "orbit.yaml",
         "effects": {"earthshine": None, "regolith": {}}},
    )  # fmt: skip
    exp = load_experiment(child)
    assert list(exp.effects) == ["black_sky", "regolith"]
    spec = exp.variant_states()[0][1].scene.spec
    assert "earth" not in spec.lights and spec.ground is not None


def test_circular_inheritance_is_an_error(tmp_path):
    _write(tmp_path / "a.yaml", {"name": "a", "inherit": "b.yaml"})
    _write(tmp_path / "b.yaml", {"name": "b", "inherit": "a.yaml"})
    with pytest.raises(ConfigError, match="circular inheritance"):
        load_experiment(tmp_path / "a.yaml")


@pytest.fixture
def spies(monkeypatch, count_renders):
    """Renders (either mode, :func:`count_renders`) and image pipelines run."""
    calls = {"pipeline": 0}
    pipeline = variant.run_pipeline

    def spy_pipeline(*a, **k):
        calls["pipeline"] += 1
        return pipeline(*a, **k)

    monkeypatch.setattr(variant, "run_pipeline", spy_pipeline)
    calls["renders"] = count_renders
    return calls


def test_variants_reuse_upstream_stages(tmp_path, spies):
    path = _write(
        tmp_path / "reuse.yaml",
        {
            "name": "reuse",
            "configurations": {"p": [0], "theta_deg": [0, 180]},
            "render": {"spp": 4},
            "repeats": 2,
            "variants": [
                {"name": "blur", "effects": {"blur": {"sigma_px": 1.0}}},
                {"name": "refine_none", "effects": {"detector_refinement": {"method": "NONE"}}},
                {"name": "gloss", "effects": {"tag_gloss": {"alpha": 0.1}}},
                {"name": "noise", "effects": {"sensor_noise": {}}},
            ],
        },
    )
    exp = load_experiment(path)
    ds = sweep.run_experiment(exp, tmp_path / "cache", show_progress=False)
    assert list(ds.variant.values) == ["baseline", "blur", "refine_none", "gloss", "noise"]
    # 2 configurations: renders only for the 2 distinct scenes (baseline, gloss)
    assert len(spies["renders"]) == 2 * 2
    # frames: baseline, blur, gloss once each; noise once per repeat; refine_none reuses baseline
    assert spies["pipeline"] == 2 * (3 + 2)
    det = ds.detected.sel(variant="baseline").values
    assert det.sum() == 2 * 2  # each configuration's facing tag, in both repeats
    err = ds.error.values
    # deterministic variants: repeats identical; noisy variant: repeats differ
    np.testing.assert_array_equal(err[0, 0], err[0, 1])
    noise = ds.error.sel(variant="noise").values
    assert not np.array_equal(noise[0][np.isfinite(noise[0])], noise[1][np.isfinite(noise[1])])
    assert "variant_effects" in ds.attrs and "tag_gloss" in ds.attrs["variant_effects"]


def test_dask_schedulers_give_the_same_result(tmp_path, monkeypatch):
    """Two local worker processes, and a real scheduler and worker process on loopback,
    reproduce the default run (one in-process worker) exactly.

    Local worker processes are used from :data:`sweep.PROCESS_SWEEP_MIN_PAIRS`
    configuration-variant pairs on (the baseline study's 540 run that way); the threshold is
    lowered to this experiment's 4 configurations x 2 variants.
    """
    from distributed import LocalCluster

    path = _write(
        tmp_path / "dask.yaml",
        {
            "name": "dask",
            "configurations": {"p": [0, 14], "theta_deg": [0, 180]},
            "render": {"spp": 4},
            "variants": [{"name": "blur", "effects": {"blur": {"sigma_px": 0.8}}}],
        },
    )
    exp = load_experiment(path)
    local = sweep.run_experiment(exp, tmp_path / "cache-local", show_progress=False)
    assert local.attrs["scheduler"] == "in-process LocalCluster"
    assert int(local.detected.sum()) >= 2
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://127.0.0.1:")
        remote = sweep.run_experiment(
            exp, tmp_path / "cache-remote", show_progress=False, scheduler=address
        )
    assert remote.attrs["scheduler"] == address
    monkeypatch.setattr(sweep, "PROCESS_SWEEP_MIN_PAIRS", 8)
    procs = sweep.run_experiment(exp, tmp_path / "cache-procs", show_progress=False)
    assert procs.attrs["scheduler"] == "LocalCluster, 2 worker processes"
    for other in (remote, procs):
        for name in ("detected", "error", "corners", "reproj_px"):
            np.testing.assert_array_equal(other[name].values, local[name].values)


@pytest.mark.parametrize("tag, p, theta_deg", [(0, 0, 40), (1, 0, 140), (0, 3, 50)])
def test_distorted_render_corners_match_projectpoints(rig, tag, p, theta_deg):
    """Corners of a Brown-Conrady render against cv2.projectPoints with the same coefficients.

    Rendered at 4x resolution (same field of view and normalised distortion), so the ArUco
    detector's own pixel-locking bias (about 0.2-0.4 px, present without distortion too) shrinks
    to a quarter in the original pixels; what remains measures the distortion model.
    """
    s = 4
    dist = (0.13, -0.26, 0.0, 0.0, 0.10)  # D435-like magnitudes; 5-9 px displacement here
    cam = rig.camera
    hi = cam.replace(
        width=cam.width * s,
        height=cam.height * s,
        fx=cam.fx * s,
        fy=cam.fy * s,
        cx=(cam.cx + 0.5) * s - 0.5,
        cy=(cam.cy + 0.5) * s - 0.5,
        distortion=dist,
    )
    theta = np.deg2rad(theta_deg)
    outlines = projected_sticker_outlines(rig, p, theta, camera=hi, points_per_side=8)
    region = sticker_region(outlines, 96, (hi.width, hi.height))
    scene = FixtureScene(rig, load_scene_spec(), (hi.width, hi.height), spp=8, camera=hi)
    scene.set_pose(p, theta)
    crop = region.crop(scene.render_pixels(region.pixels(), seed=2))
    crop = imaging.encode_srgb8(imaging.quantise_half(crop))
    found = Detector(DetectorSettings()).detect(
        imaging.paste(imaging.to_gray(crop), region.offset, (hi.width, hi.height))
    )
    lo_dist = cam.replace(distortion=dist)
    truth = project_tag_corners(rig.eyepoint_from_tag(tag, p, theta), rig.tags.size, lo_dist)
    undistorted = project_tag_corners(rig.eyepoint_from_tag(tag, p, theta), rig.tags.size, cam)
    assert np.linalg.norm(truth - undistorted, axis=1).max() > 1.5  # distortion matters here
    detected = (found[tag] + 0.5) / s - 0.5  # back to the original pixel grid
    err = np.linalg.norm(detected - truth, axis=1)
    # issue 3 asks mean < 0.15 px, max < 0.3 px; measured mean 0.09-0.12, max <= 0.16 px
    assert err.mean() < 0.15 and err.max() < 0.3, err


def test_smoke_variants_dataset(smoke_variants_nc):
    """`experiments/smoke_variants.yaml` gives one dataset with the five named variants."""
    from simgap.results.dataset import read_netcdf

    ds = read_netcdf(smoke_variants_nc)
    assert list(ds.variant.values) == ["baseline", "distortion", "glossy_tags", "defocus", "noise"]
    assert ds.sizes["repeat"] == 2
    vis = ds.visible.values
    det = ds.detected.values
    # every variant detects the tags at p=0 (tag 0 at theta=0 and tag 1 at theta=180)
    assert det[:, :, 0, 0, 0].all() and det[:, :, 1, 0, 2].all()
    assert det[0, 0][vis].all()


def test_sweep_dataset_is_cf_valid(smoke_variants_nc):
    """`simgap run`'s dataset (five variants, image statistics) passes cfchecks (CF-1.10)."""
    from tests.cf_check import assert_cf_valid
    from tests.plain_xarray import assert_plain_selection

    assert_cf_valid(smoke_variants_nc)
    labels = {"variant", "stat", "uv", "translation_axis", "rotation_axis"}
    assert_plain_selection(smoke_variants_nc, labels)


def test_experiment_round_trips_through_its_dataset_yaml():
    """`diagnose --sim result.nc` rebuilds the experiment from the dataset's experiment_yaml."""
    from simgap.pipeline.experiment import experiment_from_yaml

    exp = load_experiment("experiments/smoke_variants.yaml")
    again = experiment_from_yaml(exp.to_yaml(), source="v.nc")
    assert [n for n, _ in again.variant_states()] == [n for n, _ in exp.variant_states()]
    assert again.variant_states()[1][1] == exp.variant_states()[1][1]
    assert again.configuration_axes()[0] == exp.configuration_axes()[0]


def test_image_stats_figure_counts_view_angle_from_facing(smoke_variants_nc):
    """The image-statistics figure's view angle is counted from facing, as the heatmaps' (issue
    53), and a statistic with one value everywhere says so instead of drawing a made-up scale."""
    from simgap.analysis.gap import VIEW_ANGLE_LABEL, plot_image_stats
    from simgap.results.dataset import read_netcdf

    ds = read_netcdf(smoke_variants_nc)
    fig = plot_image_stats({"baseline": ds}, "view_angle")
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert all(ax.get_xlabel() == VIEW_ANGLE_LABEL for ax in panels)
    xs = np.concatenate([line.get_xdata() for ax in panels for line in ax.get_lines()])
    assert 0.0 <= xs.min() and xs.max() < 90.0
    clipped = next(ax for ax in panels if ax.get_title().startswith("clipped pixels"))
    assert list(clipped.get_yticks()) == [0.0]
    assert any(t.get_text() == "every tag: 0" for t in clipped.texts)
