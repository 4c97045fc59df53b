"""Sweep: dataset contract, cache reuse, resume after interruption, recorded detection failures."""

from __future__ import annotations

import numpy as np
import yaml
from typer.testing import CliRunner

from simgap.cli import app
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.sweep import experiment_pipelines, run_experiment
from simgap.pipeline.variant import MAX_SCENES_ALIVE, cached_scenes, clear_scenes
from simgap.render.scene import projected_sticker_boxes
from simgap.results.dataset import read_netcdf


def _write(tmp_path, name, **overrides):
    data = {
        "name": name,
        "configurations": {"p": [0, 14], "theta_deg": [0, 90, 180]},
        "render": {"spp": 4},
    }
    data.update(overrides)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_experiment(path)


def test_sweep_dataset_contract_and_cache_reuse(tmp_path, count_renders):
    exp = _write(tmp_path, "mini")
    ds = run_experiment(exp, tmp_path / "cache", show_progress=False)
    assert ds.sizes["tag"] == 2 and ds.sizes["p"] == 2 and ds.sizes["theta"] == 3
    assert list(ds.axis.values) == ["tx", "ty", "tz", "rx", "ry", "rz"]
    assert ds.error.dims == ("variant", "repeat", "tag", "p", "theta", "axis")
    # one render per configuration with a sticker facing the camera (tag 1 grazes it at 90 deg)
    facing = [bool(projected_sticker_boxes(exp.rig_model, p, t)) for p in (0, 14) for t in ds.theta]
    assert len(count_renders) == sum(facing) == 6
    vis = ds.visible.values
    det = ds.detected.values[0, 0]
    assert vis[0, :, 0].all() and vis[1, :, 2].all() and not vis[:, :, 1].any()
    assert det[vis].all()  # every visible tag is found on these easy configurations
    err = ds.error.values[0, 0]
    assert np.isfinite(err[det]).all() and np.isnan(err[~det]).all()
    # tolerance from the baseline sweep: |t| <= 10 mm on visible configurations up to p = 14
    assert np.nanmax(np.abs(err[vis][:, :3])) < 0.01
    assert "experiment_yaml" in ds.attrs and "SUBPIX" in ds.attrs["detector"]
    # a second run is served entirely from the cache and gives the same numbers
    again = run_experiment(exp, tmp_path / "cache", show_progress=False)
    assert len(count_renders) == 6
    np.testing.assert_array_equal(again.error.values, ds.error.values)


def test_interrupted_sweep_resumes(tmp_path, count_renders):
    exp = _write(tmp_path, "resume")
    cache = tmp_path / "cache"
    first = run_experiment(exp, cache, show_progress=False)
    # simulate an interruption after three configurations: drop one render and its products
    for kind in ("results", "frames", "renders"):
        files = sorted((cache / kind).rglob("*.*"))
        assert files
    victim = sorted((cache / "renders").rglob("*.exr"))[0]
    victim.unlink()
    for f in (cache / "results").rglob("*.npz"):
        f.unlink()
    for f in (cache / "frames").rglob("*.*"):
        f.unlink()
    count_renders.clear()
    second = run_experiment(exp, cache, show_progress=False)
    assert len(count_renders) == 1  # only the missing render is redone
    np.testing.assert_array_equal(second.error.values, first.error.values)


def test_visible_but_undetected_is_recorded(tmp_path):
    exp = _write(tmp_path, "dark", image={"exposure": 0.0005})
    ds = run_experiment(exp, tmp_path / "cache", show_progress=False)
    vis = ds.visible.values
    det = ds.detected.values[0, 0]
    assert vis.sum() == 4 and det.sum() == 0
    assert np.isnan(ds.estimated.values[0, 0][vis]).all()
    assert np.isnan(ds.corners.values).all()


def test_cli_smoke_run_and_report(tmp_path, session_cache):
    """`simgap run experiments/smoke.yaml` and `simgap report` work end to end."""
    runner = CliRunner()
    nc = tmp_path / "smoke.nc"
    res = runner.invoke(
        app, ["run", "experiments/smoke.yaml", "-o", str(nc), "--cache", str(session_cache)]
    )
    assert res.exit_code == 0, res.output
    ds = read_netcdf(nc)
    # tag 0 at p=0/theta=0 and tag 1 at p=0/theta=180 are in the smoke set and are detected
    assert ds.detected.sel(tag=0, p=0, theta=0.0).item()
    assert ds.detected.sel(tag=1, p=0).sel(theta=np.pi, method="nearest").item()
    rep = tmp_path / "rep"
    res = runner.invoke(app, ["report", str(nc), "-o", str(rep)])
    assert res.exit_code == 0, res.output
    assert (rep / "table2.md").is_file() and (rep / "heatmap_tag0.png").is_file()


def test_a_process_keeps_one_scene_and_rebuilds_it_bit_for_bit(tmp_path):
    """Scenes alive slow every launch (MAX_SCENES_ALIVE): one is kept; a rebuilt one renders
    the same bits, and an experiment's variants, used in turn by every task, all stay."""
    exp = load_experiment("experiments/smoke.yaml")
    p, theta = 7, float(np.deg2rad(30.0))
    clear_scenes()
    try:
        first = experiment_pipelines(exp, tmp_path / "a")[0]
        rendered, _ = first.hdr(p, theta, 0)
        other = experiment_pipelines(exp.with_render(spp=8), tmp_path / "b")[0]
        other.scene()
        assert cached_scenes() == MAX_SCENES_ALIVE == 1
        again = experiment_pipelines(exp, tmp_path / "c")[0]  # an empty cache: rendered anew
        rendered_again, _ = again.hdr(p, theta, 0)
        assert again.seconds["scene load"] > 0  # the scene was built again, not kept
        np.testing.assert_array_equal(rendered_again, rendered)
        smoke_variants = load_experiment("experiments/smoke_variants.yaml")
        variants = experiment_pipelines(smoke_variants, tmp_path)
        for pipe in variants:
            pipe.scene()
        assert cached_scenes() == len({pipe.scene_key for pipe in variants}) > 1
    finally:
        clear_scenes()
