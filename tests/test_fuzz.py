"""Property-based fuzzing (hypothesis) of every input family (issue 10): each generated bad input
gets simgap's named error (file, key or row, expectation); none is accepted silently."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simgap.core.aruco import DICTIONARIES
from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel, load_rig
from simgap.pipeline.capture import (
    CaptureWarning,
    calibration_to_yaml,
    ingest,
    read_calibration,
    read_capture,
    write_capture,
)
from simgap.pipeline.experiment import load_experiment
from simgap.results.contract import DatasetError, check_dataset
from simgap.results.dataset import (
    build_dataset,
    read_netcdf,
    write_netcdf,
)

FUZZ = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])
SMALL = CameraModel(64, 48, 60.0, 60.0, 31.5, 23.5)
NOT_DICTIONARIES = sorted(n for n in dir(cv2.aruco) if n[0] != "_" and n not in DICTIONARIES)


#: Folder of this module's scratch folders (pytest's temporary tree, pruned by pytest).
_SCRATCH_ROOT: list[Path] = []


@pytest.fixture(scope="module", autouse=True)
def _scratch_root(tmp_path_factory):
    _SCRATCH_ROOT.append(tmp_path_factory.mktemp("fuzz"))
    yield
    _SCRATCH_ROOT.pop()


def scratch() -> Path:
    """A new empty folder for one hypothesis example, inside pytest's temporary tree."""
    return Path(tempfile.mkdtemp(prefix="example-", dir=_SCRATCH_ROOT[-1]))


# --- experiment YAML --------------------------------------------------------------------------

#: (key path, strategy of invalid values, fragment the error must contain)
BAD_VALUES = [
    ("render.spp", st.integers(max_value=0), "expected an integer >= 1"),
    ("image.exposure", st.one_of(NON_FINITE, st.floats(max_value=0.0)), "image.exposure"),
    ("rig.camera.fx", st.one_of(NON_FINITE, st.floats(1e-300, 95.9), st.floats(96001, 1e300)), ""),
    ("rig.camera.cx", st.one_of(NON_FINITE, st.floats(-1e300, -480.6), st.floats(2400, 1e300)), ""),
    ("rig.camera.width", st.integers(65537, 2**62), "expected positive pixel sizes"),
    ("rig.grid.theta_step_deg", st.one_of(NON_FINITE, st.floats(max_value=0.0)), ""),
    ("rig.grid.theta_count", st.integers(37, 10**15), "theta_count"),
    ("rig.tags.dictionary", st.sampled_from(NOT_DICTIONARIES), "predefined dictionary"),
    ("detector.dictionary", st.sampled_from(NOT_DICTIONARIES), "predefined dictionary"),
    ("repeats", st.integers(10**9, 10**18), "the run would need about"),
    ("scene.lights.key.position", st.lists(NON_FINITE, min_size=3, max_size=3), "finite"),
    ("effects.lens_distortion.k1", NON_FINITE, "expected a finite number"),
    ("effects.blur.sigma_px", NON_FINITE, "expected a finite number"),
]


@st.composite
def bad_experiments(draw) -> tuple[dict, str, str]:
    key, values, fragment = draw(st.sampled_from(BAD_VALUES))
    data: dict = {"name": "fz", "configurations": {"p": [7], "theta_deg": [0]}}
    node = data
    *parents, last = key.split(".")
    for k in parents:
        node = node.setdefault(k, {})
    node[last] = draw(values)
    return data, key, fragment


@FUZZ
@given(case=bad_experiments())
def test_bad_experiment_values_are_named_errors(case):
    data, key, fragment = case
    path = scratch() / "exp.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as info:
        load_experiment(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: {key}") and fragment in msg, msg


@FUZZ
@given(k=st.integers(0, 35), turns=st.integers(-3, 3).filter(bool), extra=st.integers(0, 3))
def test_theta_stops_colliding_after_wrapping_are_refused(k, turns, extra):
    path = scratch() / "exp.yaml"
    thetas = [10 * k, 10 * k + 360 * turns] + [10 * ((k + 1 + i) % 36) for i in range(extra)]
    path.write_text(yaml.safe_dump({"name": "t", "configurations": {"theta_deg": thetas}}))
    with pytest.raises(ConfigError, match=r"configurations.theta_deg: .* same turntable stop"):
        load_experiment(path)


@FUZZ
@given(
    text=st.text(st.sampled_from("abc: {}[]-\n#'\"0123456789e.,&*!|>%@`\t"), max_size=60),
    garbage=st.binary(min_size=1, max_size=40),
)
def test_arbitrary_experiment_bytes_never_raise_raw_errors(text, garbage):
    """Whatever the bytes, loading gives an experiment or a ConfigError naming the file."""
    path = scratch() / "exp.yaml"
    for content in (text.encode(), garbage, b"name: x\n" + garbage):
        path.write_bytes(content)
        try:
            load_experiment(path)
        except ConfigError as exc:
            assert str(exc).startswith(str(path)), exc


@FUZZ
@given(key=st.sampled_from(["render", "image", "name", "repeats"]), lines=st.integers(0, 3))
def test_duplicate_keys_name_key_and_line(key, lines):
    path = scratch() / "exp.yaml"
    value = {"render": "{spp: 4}", "image": "{exposure: 1}", "name": "x", "repeats": "2"}[key]
    path.write_text(f"{key}: {value}\n" + "# filler\n" * lines + f"{key}: {value}\n")
    with pytest.raises(ConfigError, match=rf": {key}: duplicate key at line {lines + 2} \("):
        load_experiment(path)


# --- calibration files ------------------------------------------------------------------------


@st.composite
def bad_calibrations(draw) -> tuple[str, str]:
    cam = load_rig().camera
    fmt = draw(st.sampled_from(["ros", "opencv"]))
    field, value = draw(
        st.one_of(
            st.tuples(st.just("fx"), st.one_of(st.floats(1e-300, 95.0), st.floats(1e5, 1e300))),
            st.tuples(st.just("cy"), st.one_of(st.floats(-1e300, -300.0), st.floats(1400, 1e300))),
            st.tuples(st.just("truncate"), st.floats(0.05, 0.6)),
        )
    )
    text = calibration_to_yaml(cam, fmt)
    if field == "truncate":  # cut before the distortion: information is lost
        return text[: int(text.index("distortion_model") * value)], field
    old = {"fx": "1386.0", "cy": "539.5"}[field]
    if fmt == "opencv":
        old = {"fx": "1386.", "cy": "539.5"}[field]
    return text.replace(old, f"{value!r}", 1), field


@FUZZ
@given(case=bad_calibrations())
def test_bad_calibration_files_are_named_errors(case):
    text, field = case
    path = scratch() / "camera.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        read_calibration(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: "), msg
    assert field == "truncate" or f"{field}: expected" in msg or "expected a number" in msg, msg


@FUZZ
@given(k1=st.one_of(NON_FINITE, st.floats(101, 1e300), st.floats(-1e300, -101)))
def test_bad_distortion_is_a_named_error(k1):
    data = yaml.safe_load(calibration_to_yaml(load_rig().camera, "ros"))
    data["distortion_coefficients"]["data"][0] = k1
    path = scratch() / "camera.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="distortion_coefficients.data"):
        read_calibration(path)


# --- manifests and images ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def capture(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("capture")
    img = np.full((SMALL.height, SMALL.width, 3), 200, np.uint8)
    write_capture(folder, [(0, 0.0, 0, img), (7, math.radians(30), 0, img)], SMALL)
    return folder


ESCAPES = st.one_of(
    st.sampled_from(["/etc/passwd", "/dev/zero", "/proc/self/environ"]),
    st.builds(lambda n, t: "../" * n + t, st.integers(1, 6), st.sampled_from(["x.png", "etc"])),
    st.builds(lambda n: "images/" + "../" * n + "images/p00_t000.png", st.integers(1, 3)),
)


@FUZZ
@given(
    image=ESCAPES,
    p=st.one_of(st.integers(15, 10**6), st.integers(-(10**6), -1)),
    theta=st.floats(0.002, 0.17),
    which=st.sampled_from(["image", "p", "theta"]),
)
def test_bad_manifest_rows_are_named_errors(capture, image, p, theta, which):
    rig = load_rig()
    row = {"image": "images/p00_t000.png", "p": 0, "theta": 0.0}
    row[which] = {"image": image, "p": p, "theta": theta}[which]
    manifest = capture / "manifest.csv"
    original = manifest.read_text()
    try:
        manifest.write_text(f"image,p,theta_rad\n{row['image']},{row['p']},{row['theta']}\n")
        with pytest.raises(ConfigError, match=rf"manifest.csv: row 1 \(line 2\): {which}"):
            read_capture(capture, rig)
    finally:
        manifest.write_text(original)


@settings(max_examples=12, deadline=None)
@given(fmt=st.sampled_from(["png", "jpg"]), fraction=st.floats(0.05, 0.995))
def test_truncated_frames_are_recorded_failures(fmt, fraction):
    folder = scratch()
    img = np.full((SMALL.height, SMALL.width, 3), 200, np.uint8)
    write_capture(
        folder, [(0, 0.0, 0, img), (7, math.radians(30), 0, img)], SMALL, image_format=fmt
    )
    bad = folder / "images" / f"p07_t030.{fmt}"
    data = bad.read_bytes()
    bad.write_bytes(data[: max(1, min(len(data) - 1, int(len(data) * fraction)))])
    with pytest.warns(CaptureWarning, match=bad.name):
        ds = ingest(folder, load_rig())
    assert ds.attrs["frames_unreadable"] == 1


# --- datasets ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dataset():
    rig = load_rig()
    tags, ps, thetas = (0, 1), (0, 7), np.deg2rad([0.0, 30.0, 180.0])
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in thetas] for p in ps] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in thetas] for p in ps] for t in tags])
    full = (1, 1, 2, 2, 3)
    error = np.random.default_rng(0).normal(0, 0.002, full + (6,))
    results = {
        "detected": visible[None, None].copy(),
        "estimated": expected[None, None] + error,
        "error": error,
        "reproj_px": np.full(full, 0.1),
        "corners": np.full(full + (4, 2), 500.0),
    }
    return build_dataset(tags, ps, thetas, expected, visible, results)


MUTATIONS = {
    "theta degrees": (lambda d, x: d.assign_coords(theta=np.rad2deg(d.theta) * x), "theta"),
    "theta scaled": (lambda d, x: d.assign_coords(theta=d.theta * (3 + 100 * x)), "theta"),
    "theta shifted": (lambda d, x: d.assign_coords(theta=d.theta - 0.01 - x), "theta"),
    "p strings": (lambda d, x: d.assign_coords(p=[f"{v}{x:.2f}" for v in d.p.values]), "p"),
    "p floats": (lambda d, x: d.assign_coords(p=d.p.values + 0.01 + x / 2), "p"),
    "variant number": (lambda d, x: d.assign_coords(variant=[x]), "variant"),
    "error strings": (lambda d, x: d.assign(error=d.error.astype(str)), "error"),
    "visible strings": (lambda d, x: d.assign(visible=d.visible.astype(str)), "visible"),
    "detected not 0/1": (lambda d, x: d.assign(detected=d.detected * (2 + x)), "detected"),
    "no error": (lambda d, x: d.drop_vars("error"), "error"),
}


@FUZZ
@given(name=st.sampled_from(sorted(MUTATIONS)), x=st.floats(0.5, 1.0))
def test_datasets_breaking_the_contract_are_named_errors(dataset, name, x):
    mutate, variable = MUTATIONS[name]
    path = write_netcdf(mutate(dataset, x), scratch() / "bad.nc")
    with pytest.raises(DatasetError, match=rf"^{path}: {variable}: "):
        check_dataset(read_netcdf(path), path)


@FUZZ
@given(data=st.binary(max_size=300), cut=st.floats(0.01, 0.9))
def test_files_that_are_not_datasets_are_named_errors(dataset, data, cut):
    good = write_netcdf(dataset, scratch() / "good.nc").read_bytes()
    path = scratch() / "bad.nc"
    for content in (data, good[: int(len(good) * cut)]):
        path.write_bytes(content)
        with pytest.raises(DatasetError, match=rf"^{path}: cannot read result dataset"):
            read_netcdf(path)


def test_dictionary_names_are_opencv_dictionaries():
    assert "DICT_ARUCO_MIP_36H12" in DICTIONARIES and "DICT_4X4_50" in DICTIONARIES
    assert not {"ArucoDetector", "CORNER_REFINE_NONE", "DetectorParameters"} & DICTIONARIES
    for name in DICTIONARIES:  # every accepted name really is a predefined dictionary
        assert cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).markerSize >= 4
