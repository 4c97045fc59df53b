"""Tests of strict experiment loading: every error names the file, the key path and what was
expected (simgap.pipeline.experiment.load_experiment, simgap.core.config)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from simgap.core.config import ConfigError
from simgap.pipeline.experiment import Experiment, load_experiment

# Exact float64 arithmetic (deg2rad of multiples of 10): a few ulp of O(1) numbers.
EXACT_TOL = 1e-12


def write(tmp_path: Path, text: str, name: str = "exp.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def load_error(path: Path) -> str:
    with pytest.raises(ConfigError) as info:
        load_experiment(path)
    return str(info.value)


@pytest.mark.parametrize(
    ("text", "key", "expected"),
    [
        pytest.param("name: x\nbogus: 1\n", "bogus", ["unknown key", "render"], id="top-level"),
        pytest.param(
            "render: {sppp: 4}\n", "render.sppp", ["unknown key", "spp"], id="nested-unknown"
        ),
        pytest.param(
            'render: {spp: "many"}\n', "render.spp", ["expected an integer", "many"], id="type"
        ),
        pytest.param("render: {spp: 0}\n", "render.spp", ["expected an integer >= 1"], id="range"),
        pytest.param(
            "detector: {corner_refinement: FOO}\n",
            "detector.corner_refinement",
            ["FOO", "'NONE'", "'SUBPIX'", "'CONTOUR'", "'APRILTAG'"],
            id="literal",
        ),
        pytest.param(
            "configurations: {p: [0, 15]}\n", "configurations.p", ["15", "pin hole"], id="off-p"
        ),
        pytest.param(
            "configurations: {theta_deg: [0, 5]}\n",
            "configurations.theta_deg",
            ["5", "turntable stop", "10"],
            id="off-theta",
        ),
        pytest.param(
            "configurations: {tags: [0, 7]}\n", "configurations.tags", ["7"], id="unknown-tag"
        ),
        pytest.param(
            "rig: {camera: {fx: -1}}\n", "rig.camera.fx", ["positive focal"], id="rig-range"
        ),
        pytest.param(
            "rig: {camera: {fx: abc}}\n", "rig.camera.fx", ["expected a number"], id="rig-type"
        ),
        pytest.param(
            "rig: {links: {pin_pich: 0.03}}\n",
            "rig.links.pin_pich",
            ["unknown key", "pin_pitch"],
            id="rig-unknown",
        ),
        pytest.param(
            "image: {encoding: gamma22}\n", "image.encoding", ["'srgb'", "'linear'"], id="image"
        ),
        pytest.param("pnp: {method: P3P}\n", "pnp.method", ["'IPPE_SQUARE'"], id="pnp"),
    ],
)
def test_error_names_file_key_and_expectation(tmp_path, text, key, expected):
    path = write(tmp_path, text)
    msg = load_error(path)
    assert str(path) in msg
    assert key in msg
    for fragment in expected:
        assert fragment in msg, f"{fragment!r} not in {msg!r}"


def test_missing_file(tmp_path):
    path = tmp_path / "nope.yaml"
    msg = load_error(path)
    assert str(path) in msg
    assert "not found" in msg


def test_invalid_yaml(tmp_path):
    path = write(tmp_path, "render: [1, 2\nname: x\n")
    msg = load_error(path)
    assert str(path) in msg
    assert "YAML" in msg


def test_top_level_not_a_mapping(tmp_path):
    path = write(tmp_path, "- a\n- b\n")
    msg = load_error(path)
    assert str(path) in msg
    assert "mapping" in msg


def test_valid_file_loads_and_grid(tmp_path):
    path = write(
        tmp_path,
        "name: tiny\n"
        "configurations: {p: [0, 7, 14], theta_deg: [0, 30, 180, 370], tags: [1]}\n"
        "render: {spp: 4, sampler: ldsampler}\n"
        "detector: {corner_refinement: APRILTAG}\n"
        "pnp: {method: SQPNP}\n",
    )
    exp = load_experiment(path)
    assert isinstance(exp, Experiment)
    assert exp.name == "tiny"
    assert exp.render.spp == 4
    assert exp.render.sampler == "ldsampler"
    assert exp.detector.corner_refinement == "APRILTAG"
    assert exp.pnp.method == "SQPNP"
    ps, thetas, tags = exp.configuration_axes()
    assert ps == (0, 7, 14)
    assert tags == (1,)
    # 370 deg is the 10 deg stop (wrapped into [0, 360)).
    np.testing.assert_allclose(thetas, np.deg2rad([0.0, 30.0, 180.0, 10.0]), rtol=0, atol=EXACT_TOL)


def test_name_defaults_to_file_stem(tmp_path):
    exp = load_experiment(write(tmp_path, "render: {spp: 2}\n", name="my_run.yaml"))
    assert exp.name == "my_run"


def test_empty_configurations_mean_full_grid(tmp_path):
    exp = load_experiment(write(tmp_path, "name: full\n"))
    ps, thetas, tags = exp.configuration_axes()
    rig = exp.rig_model
    assert ps == rig.grid.p == tuple(range(15))
    assert tags == (0, 1)
    np.testing.assert_allclose(thetas, np.deg2rad(10.0 * np.arange(36)), rtol=0, atol=EXACT_TOL)


def test_rig_overrides_applied(tmp_path):
    exp = load_experiment(write(tmp_path, "name: r\nrig: {camera: {fx: 1400.5}}\n"))
    assert exp.rig_model.camera.fx == 1400.5
    assert exp.rig_model.camera.fy == 1386.0


def test_to_yaml_round_trip(tmp_path):
    exp = load_experiment(
        write(tmp_path, "name: rt\nrender: {spp: 7}\nconfigurations: {p: [3], theta_deg: [20]}\n")
    )
    data = yaml.safe_load(exp.to_yaml())
    assert isinstance(data, dict)
    assert data["name"] == "rt"
    assert data["render"]["spp"] == 7
    assert data["configurations"]["p"] == [3]
    assert "source" not in data
    # The resolved YAML is itself a valid experiment that loads to the same settings.
    again = load_experiment(write(tmp_path, exp.to_yaml(), name="again.yaml"))
    assert again.render == exp.render
    assert again.detector == exp.detector
    assert again.pnp == exp.pnp
    assert again.configurations == exp.configurations
