"""Reliability (issue 10): caches safe under concurrency, corruption and kill -9; named errors on
the command line; captures confined to their folder; strict YAML."""

from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from simgap.cli import app
from simgap.core.atomic import HOST_TAG, atomic_write, temporary_name, writer_tag
from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel
from simgap.pipeline.cache import CacheWarning
from simgap.pipeline.capture import CaptureWarning, ingest, read_capture, write_capture
from simgap.pipeline.experiment import load_experiment
from simgap.pipeline.sweep import experiment_pipelines, run_experiment
from simgap.results.contract import DatasetError
from simgap.results.dataset import read_netcdf, write_netcdf

TINY = "name: tiny\nconfigurations: {p: [7], theta_deg: [0, 30, 60, 90]}\nrender: {spp: 4}\n"
CONTRACT = ("expected", "estimated", "error", "visible", "detected", "reproj_px", "corners")
SMALL = CameraModel(64, 48, 60.0, 60.0, 31.5, 23.5)


def assert_same_results(a: xr.Dataset, b: xr.Dataset) -> None:
    for c in a.coords:
        np.testing.assert_array_equal(a[c].values, b[c].values)
    for v in CONTRACT:
        np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)


def simgap_process(exp: Path, out: Path, cache: Path) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "simgap", "run", str(exp), "-o", str(out), "--cache", str(cache)]
    return subprocess.Popen(
        cmd + ["--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny experiment (1 p x 4 theta), its uninterrupted result and its cache."""
    folder = tmp_path_factory.mktemp("tiny")
    path = folder / "tiny.yaml"
    path.write_text(TINY)
    exp = load_experiment(path)
    cache = folder / "cache"
    return path, exp, run_experiment(exp, cache, show_progress=False), cache


# --- atomic writes ----------------------------------------------------------------------------


def test_temporary_names_are_unique_per_writer(tmp_path):
    target = tmp_path / "x.npz"
    names = {temporary_name(target) for _ in range(50)}
    assert len(names) == 50
    for name in names:
        assert name.parent == tmp_path and f".{writer_tag()}-" in name.name
        assert name.name.startswith(".x.npz.") and name.name.endswith(".tmp")


def _dead_pid() -> int:
    """The process id of a process that has exited."""
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    return int(done.stdout)


def test_the_next_write_removes_what_a_killed_writer_left(tmp_path):
    """A writer killed outright leaves ``.NAME.HOST-PID-HEX.tmp`` (issue 51: an 11.8 KB .exr in
    the cache); the next write into that folder removes it, and a staging folder of the same
    kind, but nothing of a live writer here or of a writer on another host."""
    dead = _dead_pid()
    stale = tmp_path / f".frame.exr.{HOST_TAG}-{dead}-0123456789ab.tmp"
    stale.write_bytes(b"half an exr")
    staged = tmp_path / f".bag.{HOST_TAG}-{dead}-0123456789ac.tmp"
    (staged / "bag").mkdir(parents=True)
    old_format = tmp_path / f".result.nc.{dead}-0123456789ad.tmp"  # before the host tag
    old_format.write_bytes(b"")
    alive = tmp_path / f".other.npz.{writer_tag()}-0123456789ae.tmp"
    alive.write_bytes(b"being written")
    other_host = "ffffff" if HOST_TAG != "ffffff" else "eeeeee"
    elsewhere = tmp_path / f".shared.npz.{other_host}-{dead}-0123456789af.tmp"
    elsewhere.write_bytes(b"a Dask worker on another host")
    atomic_write(tmp_path / "table.md", "# Table 2\n")
    assert not stale.exists() and not staged.exists() and not old_format.exists()
    assert alive.exists() and elsewhere.exists()


def test_a_killed_bag_conversions_folder_is_removed_by_the_next(tmp_path, monkeypatch):
    import tempfile

    from simgap.pipeline.bag.reader import remove_stale_bag_folders

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    dead = tmp_path / f"simgap-bag-{HOST_TAG}-{_dead_pid()}-x1y2z3"
    (dead / "capture" / "images").mkdir(parents=True)
    live = tmp_path / f"simgap-bag-{writer_tag()}-a1b2c3"
    live.mkdir()
    assert remove_stale_bag_folders() == 1
    assert not dead.exists() and live.exists()


def test_atomic_write_failure_leaves_target_and_no_temporary(tmp_path):
    target = tmp_path / "table.md"
    atomic_write(target, "old\n")

    def broken(tmp: Path) -> None:
        tmp.write_text("half a fi")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, broken)
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.md"]


# --- cache: corruption, concurrency, kill -9 ---------------------------------------------------


def test_truncated_cache_files_of_every_kind_heal(tiny, tmp_path):
    path, exp, reference, cache = tiny
    copy = tmp_path / "cache"
    shutil.copytree(cache, copy)
    (pipe,) = experiment_pipelines(exp, copy)
    p, theta = 7, float(np.deg2rad(30.0))
    frame_key = pipe.frame_key(p, theta, 0, 0)
    result_key = pipe.result_key(p, theta, 0, 0)
    png = pipe.cache.path("frames", frame_key, ".png")
    entries = [
        pipe.cache.path("renders", pipe.render_key(p, theta, 0), ".exr"),
        png,
        png.with_suffix(".json"),
        pipe.cache.path("results", result_key, ".npz"),
    ]
    for entry in entries:
        data = entry.read_bytes()
        entry.write_bytes(data[: len(data) // 2])
    with pytest.warns(CacheWarning) as caught:
        healed = run_experiment(exp, copy, show_progress=False)
    assert_same_results(healed, reference)
    messages = " ".join(str(w.message) for w in caught)
    for entry in entries:
        assert entry.name in messages
        assert entry.with_name(entry.name + ".corrupt").is_file()
        assert entry.stat().st_size > len(entry.with_name(entry.name + ".corrupt").read_bytes())
    with warnings.catch_warnings():  # healed for good: a rerun reads every entry silently
        warnings.simplefilter("error", CacheWarning)
        assert_same_results(run_experiment(exp, copy, show_progress=False), reference)


def test_two_concurrent_runs_on_one_cache_are_identical(tiny, tmp_path):
    path = tiny[0]
    cache = tmp_path / "shared-cache"
    outs = [tmp_path / "a.nc", tmp_path / "b.nc"]
    procs = [simgap_process(path, out, cache) for out in outs]
    logs = [proc.communicate(timeout=300)[0] for proc in procs]
    assert [proc.returncode for proc in procs] == [0, 0], logs
    a, b = (read_netcdf(out) for out in outs)
    assert_same_results(a, b)  # the first published render of a configuration is shared
    assert int(a.detected.sum()) >= 3  # real results: the facing tags are detected
    assert not list(cache.rglob("*.tmp")) and not list(cache.rglob("*.corrupt"))


def test_kill_9_mid_sweep_then_rerun_is_exact(tiny, tmp_path):
    path, exp, reference, _ = tiny
    cache = tmp_path / "cache"
    proc = simgap_process(path, tmp_path / "killed.nc", cache)
    deadline = time.monotonic() + 240
    while not list(cache.glob("results/*/*.npz")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[0]
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done = len(list(cache.glob("results/*/*.npz")))
    assert 1 <= done < 4  # killed mid-sweep
    assert not (tmp_path / "killed.nc").exists()
    resumed = run_experiment(exp, cache, show_progress=False)
    assert_same_results(resumed, reference)
    assert len(list(cache.glob("results/*/*.npz"))) == 4
    # what the killed writer left half-written is gone once the rerun wrote there (issue 51)
    assert not list(cache.rglob("*.tmp"))


# --- command line: exit 2, one line, no traceback ---------------------------------------------


def _dataset_file(tmp_path: Path, reference: xr.Dataset, change) -> Path:
    return write_netcdf(change(reference), tmp_path / "bad.nc")


@pytest.mark.parametrize(
    ("command", "setup", "expected"),
    [
        ("run", lambda t, r: t.joinpath("e.yaml").write_text(""), "empty experiment file"),
        ("run", lambda t, r: t.joinpath("e.yaml").write_bytes(b"name: \xe9\n"), "not UTF-8"),
        ("run", lambda t, r: t.joinpath("e.yaml").write_text("name: a\nname: b\n"), "line 2"),
        (
            "run",
            lambda t, r: t.joinpath("e.yaml").write_text("name: x\nrig: {camera: {cx: .nan}}\n"),
            "rig.camera.cx: expected a finite number",
        ),
        (
            "run",
            lambda t, r: t.joinpath("e.yaml").write_text("name: x\nrepeats: 1e12\n"),
            "repeats: the run would need about",
        ),
        ("report", lambda t, r: t.joinpath("bad.nc").write_bytes(b"junk"), "cannot read"),
        (
            "report",
            lambda t, r: _dataset_file(t, r, lambda d: d.assign_coords(theta=np.rad2deg(d.theta))),
            "theta: expected angles in radians",
        ),
        (
            "compare",
            lambda t, r: _dataset_file(t, r, lambda d: d.assign(error=d.error.astype(str))),
            "error: expected numbers",
        ),
        (
            "compare",
            lambda t, r: _dataset_file(t, r, lambda d: d.assign_coords(variant=[0])),
            "variant: expected strings",
        ),
    ],
)
def test_cli_errors_exit_2_with_one_line(tiny, tmp_path, command, setup, expected):
    setup(tmp_path, tiny[2])
    arg = tmp_path / ("e.yaml" if command == "run" else "bad.nc")
    res = CliRunner().invoke(app, [command, str(arg), "-o", str(tmp_path / "out.nc")])
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and "Traceback" not in res.output, res.output
    assert str(arg) in lines[0] and expected in lines[0], lines[0]
    debug = CliRunner().invoke(app, ["--debug", command, str(arg), "-o", str(tmp_path / "o.nc")])
    assert isinstance(debug.exception, ConfigError)  # --debug re-raises (DatasetError included)


def test_diagnose_without_error_fails_before_simulating(tiny, tmp_path):
    path, _, reference, _ = tiny
    real = write_netcdf(reference.drop_vars("error"), tmp_path / "real.nc")
    cache = tmp_path / "cache"
    args = ["diagnose", str(real), "--sim", str(path), "-o", str(tmp_path / "d")]
    res = CliRunner().invoke(app, args + ["--cache", str(cache)])
    assert res.exit_code == 2, res.output
    assert "error: required variable is missing" in res.output and str(real) in res.output
    assert not cache.exists() or not list(cache.rglob("*.*"))  # nothing was simulated
    from simgap.diagnosis.diagnose import diagnose

    with pytest.raises(DatasetError, match="error: required variable"):
        diagnose(read_netcdf(real), None, cache)  # checked before the experiment is even used


# --- capture folders ---------------------------------------------------------------------------


def blank_capture(folder: Path, image_format: str = "png") -> Path:
    img = np.full((SMALL.height, SMALL.width, 3), 200, np.uint8)
    frames = [(0, 0.0, 0, img), (7, math.radians(30), 0, img)]
    write_capture(folder, frames, SMALL, image_format=image_format)
    return folder


@pytest.mark.parametrize("image", ["/etc/passwd", "../outside.png", "images/../images/x.png"])
def test_manifest_paths_outside_the_folder_are_refused(tmp_path, rig, image):
    folder = blank_capture(tmp_path / "cap")
    (tmp_path / "outside.png").write_bytes((folder / "images" / "p00_t000.png").read_bytes())
    (folder / "manifest.csv").write_text(f"image,p,theta_rad\n{image},0,0\n")
    with pytest.raises(
        ConfigError, match=r"manifest.csv: row 1 \(line 2\): image: expected a path"
    ):
        read_capture(folder, rig)


def test_symlink_out_of_the_folder_is_refused(tmp_path, rig):
    folder = blank_capture(tmp_path / "cap")
    (folder / "images" / "link.png").symlink_to("/etc/passwd")
    (folder / "manifest.csv").write_text("image,p,theta_rad\nimages/link.png,0,0\n")
    with pytest.raises(ConfigError, match=r"row 1 .*resolves to /etc/passwd, outside"):
        read_capture(folder, rig)


@pytest.mark.parametrize("fmt", ["png", "jpg"])
def test_truncated_frame_is_a_recorded_failure(tmp_path, rig, fmt):
    folder = blank_capture(tmp_path / "cap", fmt)
    bad = folder / "images" / f"p07_t030.{fmt}"
    data = bad.read_bytes()
    bad.write_bytes(data[: len(data) - 3])  # the decoder alone would accept a JPEG like this
    with pytest.warns(CaptureWarning, match=f"p07_t030.{fmt}: frame cannot be decoded"):
        ds = ingest(folder, rig)
    assert ds.attrs["frames_unreadable"] == 1 and bad.name in ds.attrs["frames_failed"]


def test_16_bit_png_is_refused_with_a_named_error(tmp_path, rig):
    folder = blank_capture(tmp_path / "cap")
    ok, buf = cv2.imencode(".png", np.full((48, 64, 3), 40000, np.uint16))
    (folder / "images" / "p07_t030.png").write_bytes(buf.tobytes())
    with pytest.raises(ConfigError, match=r"row 2 .*p07_t030.png is a 16-bit PNG; expected 8-bit"):
        read_capture(folder, rig)


# --- strict YAML ------------------------------------------------------------------------------


def test_exponent_notation_is_a_float(tmp_path):
    path = tmp_path / "e.yaml"
    path.write_text("name: e\nimage: {exposure: 5e-1}\nrender: {spp: 1e1}\n")
    exp = load_experiment(path)
    assert exp.image.exposure == 0.5 and exp.render.spp == 10


def test_errors_in_a_parent_name_the_parent(tmp_path):
    (tmp_path / "parent.yaml").write_text("name: p\nimage: {exposure: .inf}\n")
    (tmp_path / "child.yaml").write_text("name: c\ninherit: parent.yaml\nrender: {spp: 2}\n")
    with pytest.raises(ConfigError) as info:
        load_experiment(tmp_path / "child.yaml")
    msg = str(info.value)
    assert msg.startswith(f"{tmp_path / 'parent.yaml'}: image.exposure: expected a finite number")
    assert f"inherited by {tmp_path / 'child.yaml'}" in msg
