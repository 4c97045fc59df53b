"""Shared fixtures: a temporary cache per test session, the default rig and scene."""

from __future__ import annotations

import pytest

from simgap.rig import load_rig


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
