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
