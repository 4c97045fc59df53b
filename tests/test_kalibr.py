"""Kalibr camchain calibration files (issue 50): read as OpenCV's models, cam N chosen, refusals.

The camchain below is written by hand in the layout Kalibr's wiki documents ("YAML formats":
``camN`` mappings with camera_model, intrinsics [fu, fv, pu, pv], distortion_model,
distortion_coeffs, resolution [w, h], and the chain's extrinsics and topics), with a radtan cam0
and an equidistant cam1 of a 752 x 480 stereo pair.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from simgap.cli import app
from simgap.core import lens
from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel
from simgap.pipeline.capture import calibration_to_yaml, read_calibration
from simgap.pipeline.capture.calibration import calibration_source

CAMCHAIN = """\
cam0:
  T_cam_imu:
  - [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975]
  - [0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768]
  - [-0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [1]
  camera_model: pinhole
  distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
  distortion_model: radtan
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
  timeshift_cam_imu: 0.00012
cam1:
  T_cam_imu:
  - [0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556]
  - [0.999598781151, 0.0130119051815, 0.0251588363115, 0.0453689425024]
  - [-0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038]
  - [0.0, 0.0, 0.0, 1.0]
  T_cn_cnm1:
  - [0.999997256478, 0.00231714971224, 0.000376008102713, -0.110073808127]
  - [-0.00231714554, 0.999997167236, -0.00211303598034, 0.000399121547014]
  - [-0.000376879635804, 0.00211287890946, 0.999997697719, -0.000853702503357]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [0]
  camera_model: pinhole
  distortion_coeffs: [-0.0133, 0.0094, -0.0051, 0.0012]
  distortion_model: equidistant
  intrinsics: [457.587, 456.134, 379.999, 255.238]
  resolution: [752, 480]
  rostopic: /cam1/image_raw
  timeshift_cam_imu: 0.00011
"""
RADTAN = (-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05)
EQUIDISTANT = (-0.0133, 0.0094, -0.0051, 0.0012)


@pytest.fixture
def camchain(tmp_path) -> Path:
    path = tmp_path / "camchain-imucam.yaml"
    path.write_text(CAMCHAIN)
    return path


def _points() -> np.ndarray:
    """Camera-frame points (m) across a 752 x 480 camera's view, 0.3-3 m deep."""
    rng = np.random.default_rng(5)
    z = rng.uniform(0.3, 3.0, 50)
    xy = rng.uniform(-0.7, 0.7, (50, 2)) * z[:, None]
    return np.column_stack([xy, z])


def test_cam0_is_radtan_as_opencv_plumb_bob(camchain):
    """Kalibr's radtan [k1, k2, r1, r2] is OpenCV's (k1, k2, p1, p2, k3 = 0), to 1e-9 px."""
    cam = read_calibration(camchain)
    assert cam == CameraModel(752, 480, 458.654, 457.296, 367.215, 248.375, (*RADTAN, 0.0))
    pts = _points()
    k1, k2, r1, r2 = RADTAN
    a, b = pts[:, 0] / pts[:, 2], pts[:, 1] / pts[:, 2]
    rr = a**2 + b**2
    radial = 1 + k1 * rr + k2 * rr**2
    x = a * radial + 2 * r1 * a * b + r2 * (rr + 2 * a**2)
    y = b * radial + r1 * (rr + 2 * b**2) + 2 * r2 * a * b
    direct = np.column_stack([458.654 * x + 367.215, 457.296 * y + 248.375])
    got = lens.project(pts, cam.matrix, cam.distortion_model, cam.dist_coeffs)
    assert np.abs(got - direct).max() < 1e-9


def test_cam1_is_equidistant_as_opencv_fisheye(camchain):
    """``FILE:cam1`` chooses cam1; Kalibr's equidistant is OpenCV's fisheye, to 1e-9 px."""
    cam = read_calibration(Path(f"{camchain}:cam1"))
    assert cam == CameraModel(
        752, 480, 457.587, 456.134, 379.999, 255.238, EQUIDISTANT, "equidistant"
    )
    pts = _points()
    a, b = pts[:, 0] / pts[:, 2], pts[:, 1] / pts[:, 2]
    r = np.hypot(a, b)
    theta = np.arctan(r)
    k1, k2, k3, k4 = EQUIDISTANT
    theta_d = theta * (1 + k1 * theta**2 + k2 * theta**4 + k3 * theta**6 + k4 * theta**8)
    direct = np.column_stack(
        [457.587 * theta_d / r * a + 379.999, 456.134 * theta_d / r * b + 255.238]
    )
    got = lens.project(pts, cam.matrix, cam.distortion_model, cam.dist_coeffs)
    assert np.abs(got - direct).max() < 1e-9


def test_a_camera_suffix_names_the_file_and_the_camera(camchain, tmp_path):
    assert calibration_source(f"{camchain}:cam1") == (camchain, "cam1")
    assert calibration_source(camchain) == (camchain, None)
    odd = tmp_path / "odd:cam1"  # a file whose name ends like a suffix is that file
    odd.write_text(CAMCHAIN)
    assert calibration_source(odd) == (odd, None)
    with pytest.raises(ConfigError, match=r"cam2: no such camera in the camchain \(it has cam0"):
        read_calibration(Path(f"{camchain}:cam2"))
    ros = tmp_path / "ost.yaml"
    ros.write_text(calibration_to_yaml(read_calibration(camchain)))
    with pytest.raises(ConfigError, match=rf"{ros}: :cam1: expected a file of several cameras"):
        read_calibration(Path(f"{ros}:cam1"))


@pytest.mark.parametrize(
    "cal",
    [
        CameraModel(752, 480, 458.654, 457.296, 367.215, 248.375, (*RADTAN, 0.0)),
        CameraModel(752, 480, 457.587, 456.134, 379.999, 255.238, EQUIDISTANT, "equidistant"),
    ],
)
def test_kalibr_files_round_trip(tmp_path, cal):
    path = tmp_path / "camchain.yaml"
    path.write_text(calibration_to_yaml(cal, "kalibr"))
    assert read_calibration(path) == cal


def test_kalibr_cannot_hold_a_k3_or_a_rational_model():
    with pytest.raises(ValueError, match=r"plumb_bob without k3 \(radtan\) or equidistant"):
        calibration_to_yaml(CameraModel(distortion=(0.1, 0.0, 0.0, 0.0, 0.01)), "kalibr")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "camera_model: pinhole\n  distortion_coeffs: [-0.28",
            "camera_model: omni\n  distortion_coeffs: [-0.28",
            r"cam0.camera_model: expected pinhole, got omni \(the unified omnidirectional",
        ),
        (
            "camera_model: pinhole\n  distortion_coeffs: [-0.28",
            "camera_model: ds\n  distortion_coeffs: [-0.28",
            r"cam0.camera_model: expected pinhole, got ds \(the double sphere",
        ),
        (
            "distortion_model: radtan",
            "distortion_model: fov",
            r"cam0.distortion_model: expected one of radtan, equidistant, none, got fov \(the "
            r"FOV \(ATAN\) model",
        ),
        (
            "intrinsics: [458.654, 457.296, 367.215, 248.375]",
            "intrinsics: [458.654, 457.296, 367.215]",
            r"cam0.intrinsics: expected 4 numbers, got 3",
        ),
        (
            "distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]",
            "distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359]",
            r"cam0.distortion_coeffs: expected 4 numbers, got 3",
        ),
        (
            "  resolution: [752, 480]\n  rostopic: /cam0",
            "  resolution: [752.5, 480]\n  rostopic: /cam0",
            r"cam0.resolution\[0\]: expected a positive integer",
        ),
        (
            "intrinsics: [458.654, 457.296, 367.215, 248.375]",
            "intrinsics: [458.654, 457.296, 367.215, 2480.375]",
            r"cam0.intrinsics: cy: expected a principal point within the image",
        ),
    ],
)
def test_bad_camchains_are_named_errors(tmp_path, old, new, message):
    """Kalibr's omni / ds and fov models are refused (OpenCV has none), like any bad key."""
    path = tmp_path / "camchain.yaml"
    assert old in CAMCHAIN
    path.write_text(CAMCHAIN.replace(old, new, 1))
    with pytest.raises(ConfigError, match=rf"^{path}: {message}"):
        read_calibration(path)


def test_none_distortion_is_zeros(tmp_path):
    path = tmp_path / "camchain.yaml"
    text = CAMCHAIN.replace("distortion_model: radtan", "distortion_model: none", 1)
    path.write_text(text.replace(
        "distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]",
        "distortion_coeffs: []",
    ))  # fmt: skip
    assert read_calibration(path).distortion == (0.0,) * 5


def test_an_experiment_and_the_cli_take_a_camchain_camera(camchain, tmp_path):
    """``rig.camera.calibration: FILE:cam1`` and ``--calibration FILE:cam1``; a bad camchain
    exits with code 2 and a line naming the file and the key, no traceback."""
    from simgap.pipeline.experiment import load_experiment, with_calibration

    exp_path = tmp_path / "exp.yaml"
    exp_path.write_text(f"name: stereo\nrig:\n  camera:\n    calibration: {camchain.name}:cam1\n")
    cam1 = read_calibration(Path(f"{camchain}:cam1"))
    assert load_experiment(exp_path).rig_model.camera == cam1
    plain = tmp_path / "plain.yaml"
    plain.write_text("name: plain\n")
    assert with_calibration(load_experiment(plain), f"{camchain}:cam1").rig_model.camera == cam1
    bad = tmp_path / "omni.yaml"
    bad.write_text(CAMCHAIN.replace("camera_model: pinhole", "camera_model: omni"))
    photos = tmp_path / "photos"
    photos.mkdir()
    board = tmp_path / "board.yaml"
    board.write_text("kind: grid\ncolumns: 2\nrows: 2\nmarker_m: 0.02\nseparation_m: 0.005\n")
    args = ["ingest", str(photos), "--board", str(board), "--calibration", f"{bad}:cam1"]
    res = CliRunner().invoke(app, [*args, "-o", str(tmp_path / "out.nc")])
    assert res.exit_code == 2, res.output
    assert f"{bad}: cam1.camera_model: expected pinhole, got omni" in res.output
    assert "Traceback" not in res.output
