"""Shared fixtures: a temporary cache per test session, the default rig, the shared sample.

Under pytest-xdist the session's folders are shared by its workers (in the folder that holds
each worker's own temporary folder), so that a render one worker made is read by the other.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

import pytest

from simgap.core.rig import load_rig

REPO = Path(__file__).resolve().parents[1]
#: The public sample capture (made by an independent generator), in ``shared/`` beside the
#: checkout (the project's layout) or where ``SIMGAP_SHARED`` points.
CAPTURES = Path(os.environ.get("SIMGAP_SHARED", REPO.parent / "shared")) / "captures"
SAMPLE = CAPTURES / "sample-focal"
SAMPLE_NULL = CAPTURES / "sample-null"


@pytest.fixture(scope="session")
def sample() -> Path:
    """The shared sample capture folder; the tests about it skip where it is not present."""
    if not (SAMPLE / "manifest.csv").is_file():
        pytest.skip(f"shared sample capture not found at {SAMPLE} (set SIMGAP_SHARED)")
    return SAMPLE


@pytest.fixture(scope="session")
def sample_null() -> Path:
    """The shared capture with nothing wrong in it (another camera's image formation only)."""
    if not (SAMPLE_NULL / "manifest.csv").is_file():
        pytest.skip(f"shared sample capture not found at {SAMPLE_NULL} (set SIMGAP_SHARED)")
    return SAMPLE_NULL


@pytest.fixture(scope="session")
def rig():
    return load_rig()


@pytest.fixture
def count_renders(monkeypatch) -> list[tuple]:
    """The renders of configurations made while the test runs, in either render mode.

    One entry (the scene's pose, the pixel count) per call of the pipeline's renderer: the
    converged render (:func:`simgap.render.converged.converged_pixels`, whose own path-traced
    samples are part of it) or the path tracer (``FixtureScene.render_pixels``).
    """
    import simgap.pipeline.variant as variant
    from simgap.render.scene import FixtureScene

    calls: list[tuple] = []
    inside = []  # a converged render in progress: its own samples are not renders of their own
    path, converged = FixtureScene.render_pixels, variant.converged_pixels

    def spy_path(self, pixels, seed=0):
        if not inside:
            calls.append((self.pose, len(pixels)))
        return path(self, pixels, seed)

    def spy_converged(scene, pixels, *args, **kwargs):
        calls.append((scene.pose, len(pixels)))
        inside.append(True)
        try:
            return converged(scene, pixels, *args, **kwargs)
        finally:
            inside.pop()

    monkeypatch.setattr(FixtureScene, "render_pixels", spy_path)
    monkeypatch.setattr(variant, "converged_pixels", spy_converged)
    return calls


def _session_folder(tmp_path_factory, worker_id: str, name: str) -> Path:
    """A folder of this test session that every xdist worker sees (made if missing)."""
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if worker_id != "master" else base  # this session's, for every worker
    folder = shared / name
    folder.mkdir(exist_ok=True)
    return folder


@pytest.fixture(scope="session")
def session_cache(tmp_path_factory, worker_id):
    """One simgap cache for the session's workers (safe: the cache is made for concurrent runs)."""
    return _session_folder(tmp_path_factory, worker_id, "simgap-cache")


@pytest.fixture(scope="session")
def smoke_variants_nc(tmp_path_factory, worker_id, session_cache):
    """`simgap run experiments/smoke_variants.yaml`: the real five-variant dataset (about 30 s).

    Made once per test session: two test files use it, and under pytest-xdist the first worker
    to need it makes it in the folder the workers share while the other waits on a lock. Its
    renders go to the session cache, where `experiments/smoke.yaml`'s baseline renders are the
    same ones.
    """
    from typer.testing import CliRunner

    from simgap.cli import app

    folder = _session_folder(tmp_path_factory, worker_id, "smoke-variants")
    out = folder / "v.nc"
    with open(folder / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not out.is_file():
            args = ["run", "experiments/smoke_variants.yaml", "-o", str(out)]
            res = CliRunner().invoke(app, [*args, "--cache", str(session_cache)])
            assert res.exit_code == 0, res.output
    return out
