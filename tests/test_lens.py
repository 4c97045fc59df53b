"""OpenCV's camera models (issue 50): projection, inverse, PnP, calibration files, experiments."""

from __future__ import annotations

import numpy as np
import pytest

from simgap.core import lens
from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel, load_rig
from simgap.pipeline.capture import calibration_to_yaml, read_calibration
from simgap.pose.estimate import estimate_pose, pose_error, project_tag_corners

#: A RealSense D415's rational calibration as its file writes it: k2 29 and k3 100 balanced by k5
#: 28 and k6 103 (issue 50).
D415_RATIONAL = (-0.0529, 29.0, 0.0007, -0.0003, 100.0, -0.0195, 28.0, 103.0)
THIN_PRISM = (0.1, -0.2, 0.001, 0.0005, 0.05, 0.02, -0.01, 0.01, 0.002, -0.001, 0.0015, 0.0005)
TILTED = THIN_PRISM + (0.02, -0.015)
FISHEYE = (0.05, -0.02, 0.004, -0.001)
CAMERAS = {
    "plumb_bob": CameraModel(distortion=(0.12, -0.25, 0.001, -0.0008, 0.1)),
    "rational_polynomial": CameraModel(
        distortion=D415_RATIONAL, distortion_model="rational_polynomial"
    ),
    "thin_prism": CameraModel(distortion=THIN_PRISM, distortion_model="thin_prism"),
    "tilted": CameraModel(distortion=TILTED, distortion_model="tilted"),
    "equidistant": CameraModel(
        fx=700.0, fy=700.0, distortion=FISHEYE, distortion_model="equidistant"
    ),
}


def _points(rng: np.random.Generator, n: int = 200, half_angle: float = 0.5) -> np.ndarray:
    """Camera-frame points within ``half_angle`` (rad) of the optical axis, 0.2-2 m deep."""
    z = rng.uniform(0.2, 2.0, n)
    xy = rng.uniform(-np.tan(half_angle), np.tan(half_angle), (n, 2)) * z[:, None]
    return np.column_stack([xy, z])


@pytest.mark.parametrize("model", list(CAMERAS))
def test_normalise_inverts_project(model):
    cam = CAMERAS[model]
    pts = _points(np.random.default_rng(0))
    back = cam.normalise(cam.project(pts))
    # measured: below 1e-12 for every model (OpenCV's iterations to 1e-14)
    assert np.abs(back - pts[:, :2] / pts[:, 2:]).max() < 1e-9


def test_the_tilt_is_opencvs():
    """The sensor tilt the renderer inverts (:func:`simgap.core.lens.tilt_matrix`) is OpenCV's:
    a tilted model equals the thin-prism model followed by the tilt matrix."""
    pts = _points(np.random.default_rng(1))
    k = CAMERAS["tilted"].matrix
    prism = lens.project(pts, np.eye(3), "thin_prism", np.asarray(THIN_PRISM))
    tilted = np.column_stack([prism, np.ones(len(prism))]) @ lens.tilt_matrix(*TILTED[12:]).T
    manual = (tilted[:, :2] / tilted[:, 2:]) * [k[0, 0], k[1, 1]] + [k[0, 2], k[1, 2]]
    assert np.abs(manual - lens.project(pts, k, "tilted", np.asarray(TILTED))).max() < 1e-9


@pytest.mark.parametrize("model", list(CAMERAS))
def test_pose_round_trips_through_every_model(model):
    """Exact corners projected through the model give back the tag's pose (PnP on the model:
    OpenCV's own for the pinhole family, normalised coordinates for the fisheye)."""
    rig = load_rig()
    cam = CAMERAS[model]
    for tag, p, theta in ((0, 0, 0.0), (1, 7, np.radians(200)), (0, 14, np.radians(40))):
        m = rig.eyepoint_from_tag(tag, p, theta)
        corners = project_tag_corners(m, rig.tags.size, cam)
        est = estimate_pose(corners, rig.tags.size, cam)
        err = pose_error(est.pose, rig.expected_pose(tag, p, theta))
        # measured: below 1e-9 m and 1e-8 rad (IPPE on exact corners)
        assert np.abs(err[:3]).max() < 1e-7 and np.abs(err[3:]).max() < 1e-6, (model, err)
        assert est.reproj_px < 1e-6


@pytest.mark.parametrize("fmt", ["ros", "opencv"])
@pytest.mark.parametrize("model", list(CAMERAS))
def test_calibration_files_keep_every_model(tmp_path, fmt, model):
    cal = CAMERAS[model]
    path = tmp_path / "camera.yaml"
    path.write_text(calibration_to_yaml(cal, fmt))
    assert read_calibration(path) == cal


OPENCV_RATIONAL = """%YAML:1.0
---
image_width: 1280
image_height: 720
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 912.3, 0., 641.2, 0., 910.8, 359.9, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: {n}
   dt: d
   data: [ {data} ]
"""


@pytest.mark.parametrize(
    ("coeffs", "model"),
    [
        (D415_RATIONAL, "rational_polynomial"),
        (THIN_PRISM, "thin_prism"),
        (TILTED, "tilted"),
        ((0.1, -0.05, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0), "plumb_bob"),  # nothing beyond k3
    ],
)
def test_an_opencv_file_without_a_model_name_reads_it_from_its_count(tmp_path, coeffs, model):
    path = tmp_path / "camera.yaml"
    path.write_text(OPENCV_RATIONAL.format(n=len(coeffs), data=", ".join(map(str, coeffs))))
    cal = read_calibration(path)
    assert cal.distortion_model == model
    assert cal.distortion == pytest.approx(coeffs[: len(lens.DISTORTION_MODELS[model])])


def test_a_ros_file_names_its_model_and_wrong_counts_are_refused(tmp_path):
    path = tmp_path / "ost.yaml"
    text = calibration_to_yaml(CAMERAS["rational_polynomial"])
    path.write_text(text.replace("rational_polynomial", "equidistant"))
    with pytest.raises(ConfigError, match=rf"{path}: distortion_coefficients.data: expected the 4"):
        read_calibration(path)
    path.write_text(text.replace("rational_polynomial", "fisheye"))
    with pytest.raises(ConfigError, match=r"expected the 4 coefficients of equidistant"):
        read_calibration(path)


def test_a_camera_model_refuses_a_count_its_model_does_not_have():
    with pytest.raises(ValueError, match=r"distortion: expected the 8 coefficients"):
        CameraModel(distortion=(0.1, 0.0, 0.0, 0.0, 0.0), distortion_model="rational_polynomial")
    with pytest.raises(ValueError, match=r"distortion_model: expected one of plumb_bob"):
        CameraModel(distortion_model="kannala")
    with pytest.raises(ValueError, match=r"distortion\[13\] \(tau_y\): expected \|tau_y\| <= 0.5"):
        CameraModel(distortion=TILTED[:13] + (0.7,), distortion_model="tilted")


def test_an_experiment_takes_its_camera_from_a_calibration_file(tmp_path):
    from simgap.pipeline.experiment import load_experiment, with_calibration

    cal = CAMERAS["rational_polynomial"]
    (tmp_path / "cams").mkdir()
    (tmp_path / "cams" / "d415.yaml").write_text(calibration_to_yaml(cal))
    exp_path = tmp_path / "exp.yaml"
    exp_path.write_text(
        "name: d415\nrig:\n  camera:\n    calibration: cams/d415.yaml\n    fx: 1390.0\n"
    )
    # the file's camera, with the keys beside it winning
    assert load_experiment(exp_path).rig_model.camera == cal.replace(fx=1390.0)
    plain = tmp_path / "plain.yaml"
    plain.write_text("name: plain\n")
    fisheye = CAMERAS["equidistant"]
    (tmp_path / "fisheye.yaml").write_text(calibration_to_yaml(fisheye, "opencv"))
    exp = with_calibration(load_experiment(plain), tmp_path / "fisheye.yaml")
    assert exp.rig_model.camera == fisheye
    exp_path.write_text("name: bad\nrig:\n  camera:\n    calibration: absent.yaml\n")
    with pytest.raises(ConfigError, match=rf"{exp_path}: rig.camera.calibration: .*absent.yaml"):
        load_experiment(exp_path)


def test_a_radial_distortion_folds_where_its_derivative_vanishes():
    """k1 = -0.3 alone: r (1 - 0.3 r^2) stops growing at r = 1 / sqrt(0.9), r_d = 0.7027."""
    r, rd = lens.monotone_radius("plumb_bob", np.array([-0.3, 0.0, 0.0, 0.0, 0.0]))
    # the search's grid step is 1e-4 in normalised radius (lens.RADIUS_SAMPLES)
    assert r == pytest.approx(1 / np.sqrt(0.9), abs=2e-4)
    assert rd == pytest.approx(2 / 3 / np.sqrt(0.9), abs=1e-6)
    # a fisheye and a mild lens stay lenses out to 85 degrees
    assert lens.monotone_radius("plumb_bob", np.array([0.1, -0.2, 0.0, 0.0, 0.05]))[0] == np.inf
    assert lens.monotone_radius("equidistant", np.array([0.262, 2.52, -13.07, 21.75]))[0] == np.inf


def test_a_rational_fit_on_a_part_of_the_image_folds_inside_it():
    """The rational model fitted by ``simgap calibrate`` on 28 RealSense photos whose board
    points reach 435 px (docs/results/real_photos.md): numerator and denominator cross zero
    together near r^2 = 0.40, and the model folds back 535 px from the principal point, inside
    a 1280 x 720 image whose farthest corner is 744 px out. A mild plumb_bob lens does not.
    """
    matrix = np.array([[899.50, 0.0, 649.19], [0.0, 902.32, 362.96], [0.0, 0.0, 1.0]])
    rational = np.array([-1.250, 70.88, 0.0006, -0.0003, -185.9, -1.187, 69.08, -181.1])
    fold = lens.fold_in_image(matrix, "rational_polynomial", rational, 1280, 720)
    assert fold is not None
    # measured: 535.1 px and 744.4 px
    assert fold[0] == pytest.approx(535.1, abs=1.0) and fold[1] == pytest.approx(744.4, abs=1.0)
    plumb = np.array([0.1, -0.2, 0.0, 0.0, 0.05])
    assert lens.fold_in_image(matrix, "plumb_bob", plumb, 1280, 720) is None
    # a D415's factory rational file balances its terms out to 85 degrees: no fold anywhere
    assert lens.monotone_radius("rational_polynomial", np.array(D415_RATIONAL))[0] == np.inf
