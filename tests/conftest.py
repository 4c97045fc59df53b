"""Shared fixtures: a temporary cache per test session, the default rig, the shared sample."""

from __future__ import annotations

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


@pytest.fixture(scope="session")
def session_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("simgap-cache")


@pytest.fixture(scope="session")
def smoke_variants_nc(tmp_path_factory, session_cache):
    """`simgap run experiments/smoke_variants.yaml`: the real five-variant dataset (about 1 min)."""
    from typer.testing import CliRunner

    from simgap.cli import app

    out = tmp_path_factory.mktemp("smoke-variants") / "v.nc"
    res = CliRunner().invoke(
        app,
        ["run", "experiments/smoke_variants.yaml", "-o", str(out), "--cache", str(session_cache)],
    )
    assert res.exit_code == 0, res.output
    return out
