"""External reference poses for board photos (issue 50): a poses CSV, robot poses + hand-eye.

The photo set is synthetic (tests.board_views: OpenCV's tutorial ChArUco board warped,
antialiased, into a 640 x 480 pinhole camera at six known poses), so every reference has a truth:
the poses the photos were made at.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
import xarray as xr
import yaml
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from simgap.cli import app
from simgap.core import transforms as tf
from simgap.core.board import Board, read_board
from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel
from simgap.pipeline.capture import calibration_to_yaml
from simgap.pipeline.photo_references import (
    PosesReference,
    RobotReference,
    read_pose_csv,
    read_transform_file,
    write_pose_csv,
)
from simgap.pipeline.photos import measure_photos
from tests.board_views import synthetic_view
from tests.cf_check import cf_check

BOARD = Path(__file__).resolve().parents[1] / "assets" / "real" / "opencv_charuco" / "board.yaml"
CAMERA = CameraModel(width=640, height=480, fx=600.0, fy=600.0, cx=319.5, cy=239.5)
#: The photos' board poses in the camera frame: rotation vector (rad), board origin (m).
VIEWS = [
    ((0.30, -0.20, 0.05), (-0.10, -0.14, 0.45)),
    ((-0.25, 0.15, 0.10), (-0.09, -0.15, 0.40)),
    ((0.10, 0.35, -0.05), (-0.12, -0.13, 0.55)),
    ((-0.35, -0.10, 0.20), (-0.08, -0.16, 0.50)),
    ((0.20, 0.20, 1.57), (0.12, -0.10, 0.48)),
    ((0.05, -0.30, -0.10), (-0.11, -0.12, 0.60)),
]
#: The robot's fixed transforms: the camera in the flange frame (a rotation about the flange's
#: x, so the flange's x is the camera's x) and the board in the base frame.
FLANGE_FROM_CAMERA = tf.make(tf.rotvec_to_matrix([0.1, 0.0, 0.0]), [0.03, -0.05, 0.12])
BASE_FROM_BOARD = tf.make(tf.rotvec_to_matrix([0.2, -0.1, 2.5]), [0.65, -0.2, 0.02])


def _write_transform(path: Path, m: np.ndarray, form: str = "quaternion") -> Path:
    """A transform file: translation + quaternion, or the 4 x 4 matrix."""
    if form == "matrix":
        data = {"matrix": [[float(v) for v in row] for row in m]}
    else:
        q = Rotation.from_matrix(m[:3, :3]).as_quat()
        data = {"translation": [float(v) for v in m[:3, 3]], "quaternion": [float(v) for v in q]}
    path.write_text(yaml.safe_dump(data))
    return path


def _robot_poses(truth: dict[str, np.ndarray], flange_from_camera: np.ndarray) -> dict:
    """``base_from_flange`` per photo, such that the chain gives the true board poses."""
    return {
        n: BASE_FROM_BOARD @ tf.invert(c) @ tf.invert(flange_from_camera) for n, c in truth.items()
    }


@pytest.fixture(scope="module")
def board() -> Board:
    return read_board(BOARD)


@pytest.fixture(scope="module")
def photo_set(board, tmp_path_factory) -> tuple[Path, dict[str, np.ndarray]]:
    """The photos' folder and each photo's true ``camera_from_board`` (4 x 4, m)."""
    folder = tmp_path_factory.mktemp("photos")
    truth = {}
    for i, (r, t) in enumerate(VIEWS):
        name = f"photo_{i:02d}.png"
        cv2.imwrite(str(folder / name), synthetic_view(board, CAMERA, np.array(r), np.array(t)))
        truth[name] = tf.make(tf.rotvec_to_matrix(r), t)
    return folder, truth


@pytest.fixture(scope="module")
def by_board(board, photo_set) -> xr.Dataset:
    return measure_photos(photo_set[0], board, CAMERA)


@pytest.fixture(scope="module")
def by_truth(board, photo_set, tmp_path_factory) -> xr.Dataset:
    csv = write_pose_csv(tmp_path_factory.mktemp("poses") / "poses.csv", photo_set[1])
    return measure_photos(photo_set[0], board, CAMERA, reference=PosesReference.read(csv))


def _translations(ds: xr.Dataset) -> np.ndarray:
    return ds.board_translation.values


def test_the_true_poses_as_reference_agree_with_the_board(photo_set, by_board, by_truth):
    """Against the true poses the markers' errors are the board reference's, within how far the
    board's own pose is from the truth.

    Measured (102 sightings): the board's pose within 0.19 mm of the truth; the marker errors
    against the two references within 0.28 mm (translation) and 1.29 mrad (rotation); their mean
    within 0.013 mm. Tolerances: about twice these.
    """
    truth = np.array([m[:3, 3] for m in photo_set[1].values()])
    np.testing.assert_allclose(_translations(by_truth), truth, atol=1e-12)
    assert by_truth.attrs["reference"] == "poses file"
    assert by_truth.attrs["board_points"] == by_board.attrs["reference"] == "chessboard corners"
    np.testing.assert_array_equal(
        by_truth.board_points_translation.values, by_board.board_translation.values
    )
    np.testing.assert_array_equal(by_truth.detected.values, by_board.detected.values)
    assert np.abs(by_board.board_translation.values - truth).max() < 0.5e-3
    diff = by_truth.error_translation - by_board.error_translation
    assert int(np.isfinite(diff).sum()) == 3 * int(by_board.detected.sum()) == 3 * 102
    assert float(np.abs(diff).max()) < 0.6e-3
    assert float(np.abs(by_truth.error_rotation - by_board.error_rotation).max()) < 2.6e-3
    mean_diff = diff.mean(("frame", "marker"))
    assert float(np.abs(mean_diff).max()) < 0.03e-3


def test_robot_poses_and_hand_eye_give_the_true_poses(board, photo_set, by_truth, tmp_path):
    """Robot poses built from the true poses through a known hand-eye and board-in-base give
    the true reference back, to 1e-9 m (the chain's round-off)."""
    folder, truth = photo_set
    robot = write_pose_csv(tmp_path / "robot.csv", _robot_poses(truth, FLANGE_FROM_CAMERA))
    hand_eye = _write_transform(tmp_path / "hand_eye.yaml", FLANGE_FROM_CAMERA)
    in_base = _write_transform(tmp_path / "board.yaml", BASE_FROM_BOARD, "matrix")
    ds = measure_photos(
        folder, board, CAMERA, reference=RobotReference.read(robot, hand_eye, in_base)
    )
    assert ds.attrs["reference"] == "robot poses and hand-eye"
    assert ds.attrs["board_in_base"] == str(in_base)
    np.testing.assert_allclose(_translations(ds), _translations(by_truth), rtol=0, atol=1e-9)
    np.testing.assert_allclose(ds.board_rotation, by_truth.board_rotation, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ds.error_translation, by_truth.error_translation, rtol=0, atol=1e-9)


def test_the_board_in_base_is_solved_from_the_photos(board, photo_set, by_board, tmp_path):
    """Without --board-in-base the board's base pose is solved from the photos' own board poses.

    Measured: solved within 0.011 mm of the truth, the photos scattering by 0.079 mm and 0.92
    mrad about it (the board's own pose error, test above); each photo's reference then within
    0.012 mm of its truth. Tolerances: 0.05 mm, 0.3 mm, 3 mrad, 0.05 mm.
    """
    folder, truth = photo_set
    robot = write_pose_csv(tmp_path / "robot.csv", _robot_poses(truth, FLANGE_FROM_CAMERA))
    hand_eye = _write_transform(tmp_path / "hand_eye.yaml", FLANGE_FROM_CAMERA, "matrix")
    ds = measure_photos(folder, board, CAMERA, reference=RobotReference.read(robot, hand_eye))
    assert ds.attrs["board_in_base"].startswith("solved from 6 photos' board poses")
    solved = np.array(eval(ds.attrs["board_in_base_translation_m"]))  # noqa: S307 (a repr list)
    assert np.abs(solved - BASE_FROM_BOARD[:3, 3]).max() < 0.05e-3
    assert ds.attrs["board_in_base_spread_m"] < 0.3e-3
    assert ds.attrs["board_in_base_spread_rad"] < 3e-3
    truth_t = np.array([m[:3, 3] for m in truth.values()])
    assert np.abs(_translations(ds) - truth_t).max() < 0.05e-3


def test_a_hand_eye_2mm_off_in_x_shows_as_2mm_lateral_error(board, photo_set, by_truth, tmp_path):
    """A hand-eye 2 mm off along the flange's x (the camera's x) moves every reference by
    -2 mm in x, so the markers' mean x error reads +2 mm.

    The difference to the true reference is exactly 2 mm (measured 2.000000 mm; tolerance 1e-9
    m, the chain's round-off). The mean itself, measured +1.762 mm, is 2 mm plus the markers' own
    mean x error against the truth, measured -0.238 mm (the single markers' depth bias, +10.4
    mm, seen along off-axis lines of sight): that is the tolerance's source, 0.5 mm.
    """
    folder, truth = photo_set
    robot = write_pose_csv(tmp_path / "robot.csv", _robot_poses(truth, FLANGE_FROM_CAMERA))
    off = FLANGE_FROM_CAMERA.copy()
    off[0, 3] += 0.002
    hand_eye = _write_transform(tmp_path / "hand_eye.yaml", off)
    in_base = _write_transform(tmp_path / "board.yaml", BASE_FROM_BOARD)
    ds = measure_photos(
        folder, board, CAMERA, reference=RobotReference.read(robot, hand_eye, in_base)
    )
    mean = ds.error_translation.mean(("frame", "marker")).values
    true_mean = by_truth.error_translation.mean(("frame", "marker")).values
    np.testing.assert_allclose(mean - true_mean, [0.002, 0.0, 0.0], rtol=0, atol=1e-9)
    assert abs(true_mean[0]) < 0.5e-3
    assert mean[0] == pytest.approx(0.002, abs=0.5e-3)
    np.testing.assert_allclose(ds.error_rotation, by_truth.error_rotation, rtol=0, atol=1e-9)


def test_the_default_reference_is_the_boards_own(by_board):
    """Without an external reference the dataset is as before: no reference file attributes."""
    assert by_board.attrs["reference"] == "chessboard corners"
    assert "board_points_translation" not in by_board and "reference_poses" not in by_board.attrs


#: Bad pose CSVs and transform files, and the message each gives after the file's name.
BAD_FILES = [
    ("poses.csv", "image,x,y,z,qx,qy,qz,qw\n",
     r"header: expected the columns image,tx,ty,tz,qx,qy,qz,qw"),
    ("poses.csv", "image,tx,ty,tz,qx,qy,qz,qw\na.png,0,0,0.5,0,0,0,2\n",
     r"row 1 \(line 2\): qx,qy,qz,qw: expected a unit quaternion qx, qy, qz, qw \(norm 1 "
     r"within 0.001\), got norm 2"),
    ("poses.csv", "image,tx,ty,tz,qx,qy,qz,qw\na.png,0,0,zero,0,0,0,1\n",
     r"row 1 \(line 2\): tz: expected a finite number, got 'zero'"),
    ("poses.csv", "image,tx,ty,tz,qx,qy,qz,qw\na.png,0,0,0.5,0,0,0,1\na.png,0,0,0.5,0,0,0,1\n",
     r"row 2 \(line 3\): image: a.png has a row already"),
    ("poses.csv", "image,tx,ty,tz,qx,qy,qz,qw\na.png,0,0,0.5,0,0,1\n",
     r"row 1 \(line 2\): expected 8 fields, got 7"),
    ("poses.csv", "image,tx,ty,tz,qx,qy,qz,qw\n", r"no rows \(expected one camera_from_board pose"),
    ("hand_eye.yaml", "translation: [0, 0, 0.1]\n",
     r"expected either translation: \[x, y, z\] \(m\) with quaternion"),
    ("hand_eye.yaml", "translation: [0, 0]\nquaternion: [0, 0, 0, 1]\n",
     r"translation: expected 3 numbers, got 2"),
    ("hand_eye.yaml", "translation: [0, 0, 0]\nquaternion: [0.5, 0.5, 0.5, 0.6]\n",
     r"quaternion: expected a unit quaternion"),
    ("hand_eye.yaml", "matrix: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]\n",
     r"matrix rotation block is not a proper rotation \(expected a rigid transform"),
    ("hand_eye.yaml", "matrix: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]\n",
     r"matrix: expected 4 rows of 4 numbers"),
]  # fmt: skip


@pytest.mark.parametrize(("name", "text", "message"), BAD_FILES)
def test_bad_pose_and_transform_files_are_named_errors(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ConfigError, match=rf"^{path}: {message}"):
        if name.endswith(".csv"):
            read_pose_csv(path, "camera_from_board")
        else:
            read_transform_file(path, "flange_from_camera")


def test_ingest_with_a_poses_file(board, photo_set, tmp_path):
    """``ingest --board --poses``: the dataset (CF) and the printout name the reference, and the
    calibration file is held against it (the true file describes the photos); a photo without a
    row and options that do not go together exit with code 2, no traceback."""
    folder, truth = photo_set
    cal = tmp_path / "camera.yaml"
    cal.write_text(calibration_to_yaml(CAMERA))
    poses = write_pose_csv(tmp_path / "poses.csv", truth)
    out = tmp_path / "photos.nc"
    base = ["ingest", str(folder), "--board", str(BOARD), "--calibration", str(cal)]
    res = CliRunner().invoke(app, [*base, "--poses", str(poses), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "marker sightings against the poses file" in res.output
    assert f"{cal} describes the photos" in res.output
    with xr.open_dataset(out) as ds:
        assert ds.attrs["reference_poses"] == str(poses)
        assert ds.board_points_translation.attrs["units"] == "m"
    report = cf_check(out)  # as the default dataset: one warning per string label dimension
    assert (report.fatal, report.errors, report.warnings) == (0, 0, 3), report.output
    short = write_pose_csv(tmp_path / "short.csv", dict(list(truth.items())[1:]))
    res = CliRunner().invoke(app, [*base, "--poses", str(short), "-o", str(out), "--overwrite"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert f"{short}: image: expected a row for every photo, none for photo_00.png" in res.output
    for extra, message in [
        (["--hand-eye", str(poses)], "--hand-eye"),
        (["--poses", str(poses), "--robot-poses", str(poses)], "two references"),
        (["--robot-poses", str(poses)], "needs --hand-eye"),
    ]:
        res = CliRunner().invoke(app, [*base, *extra, "-o", str(out), "--overwrite"])
        assert res.exit_code == 2 and message in res.output, res.output


def test_photos_simulated_against_their_poses_file(board, photo_set):
    """``ingest --board --poses --simulate``: each photo is rendered at its reference pose and
    the renders' markers are measured against that pose, so real and simulated errors share one
    reference.

    Measured at 16 spp on all six frames: the renders' board poses from their own points lie
    within 0.56 mm of the poses they were rendered at (0.18 mm for the photos' against their
    true poses); 1 mm is the bar.
    """
    from simgap.pipeline.photo_references import RENDERED_REFERENCE
    from simgap.pipeline.photos import render_photos, simulate_photos

    folder, truth = photo_set
    real = measure_photos(folder, board, CAMERA, reference=PosesReference(folder, truth))
    real = real.isel(frame=slice(0, 3))  # three frames are enough, and render in half the time
    sim = simulate_photos(real, render_photos(real, board, CAMERA, spp=16), board, CAMERA)
    assert sim.attrs["reference"] == f"{RENDERED_REFERENCE} (poses file)"
    np.testing.assert_array_equal(sim.board_translation.values, real.board_translation.values)
    off = sim.board_points_translation.values - sim.board_translation.values
    assert np.abs(off).max() < 1e-3
    assert int(sim.detected.sum()) == int(real.detected.sum())


def _poses_within(truth: dict[str, np.ndarray], metres: float, radians: float) -> list:
    """``truth``'s poses, each moved by a normal error of ``metres`` and ``radians`` per axis
    (seeded: the same every run)."""
    rng = np.random.default_rng(0)
    out = []
    for pose in truth.values():
        moved = pose.copy()
        moved[:3, 3] += rng.normal(0.0, metres, 3)
        moved[:3, :3] = tf.rotvec_to_matrix(rng.normal(0.0, radians, 3)) @ pose[:3, :3]
        out.append(moved)
    return out


def test_reference_poses_pin_a_focal_length_error(board, photo_set):
    """A file whose focal length is 2 % long, held against the photos with each board at a
    reference pose 1 mm and 2 mrad (per axis, sd) off the truth (a robot's chain with a
    hand-eye's error), is corrected by the -1.96 % that undoes it and called faulty; the true
    file is not.

    Measured: -2.09 +- 0.12 % (RMS 2.80 -> 1.78 px: the reference's error is most of what is
    left); the true file's largest correction cy -0.44 +- 0.35 px (RMS down 3 %), focal -0.13 +-
    0.12 %. Bar: the issue's 25 %. Posed from their own points instead, these noiseless photos
    name the long file too (-1.86 +- 0.06 %, RMS 0.087 -> 0.068 px); real photos do not
    (docs/results/real_photos.md).
    """
    from simgap.pipeline.photos import named_photo_points
    from simgap.pose.calibration_check import check_calibration

    folder, truth = photo_set
    names, points, _ = named_photo_points(folder, board)
    assert names == list(truth)
    reference = _poses_within(truth, 1e-3, 2e-3)
    long = dataclasses.replace(CAMERA, fx=CAMERA.fx * 1.02, fy=CAMERA.fy * 1.02)
    focal = check_calibration(points, long, reference=reference)[0]
    assert focal.name == "focal length" and focal.disagrees
    assert focal.correction == pytest.approx(100 * (1 / 1.02 - 1), rel=0.25)
    assert not any(c.disagrees for c in check_calibration(points, CAMERA, reference=reference))


def test_calibrate_holds_a_file_against_a_poses_file(board, photo_set, tmp_path):
    """``calibrate --calibration FILE --poses CSV`` (and the robot's chain) holds each board at
    its reference pose: the long focal length is named (exactly -1.96 %: the true poses). A
    robot without --board-in-base has the board's place solved from the photos through the
    camera being checked, re-solved for each correction tried: posed through the long file once
    and held there, it absorbed the error (focal -0.11 +- 0.32 %, nothing named); re-solved,
    -1.955 %. A reference without a file to check exits with code 2."""
    folder, truth = photo_set
    long = tmp_path / "long.yaml"
    long.write_text(
        calibration_to_yaml(dataclasses.replace(CAMERA, fx=CAMERA.fx * 1.02, fy=CAMERA.fy * 1.02))
    )
    poses = write_pose_csv(tmp_path / "poses.csv", truth)
    robot = write_pose_csv(tmp_path / "robot.csv", _robot_poses(truth, FLANGE_FROM_CAMERA))
    hand_eye = _write_transform(tmp_path / "hand_eye.yaml", FLANGE_FROM_CAMERA)
    in_base = _write_transform(tmp_path / "in_base.yaml", BASE_FROM_BOARD)
    base = ["calibrate", str(folder), "--board", str(BOARD), "--no-progress"]
    for reference, label, correction in [
        (["--poses", str(poses)], "poses file", "-1.96"),
        (["--robot-poses", str(robot), "--hand-eye", str(hand_eye), "--board-in-base",
          str(in_base)], "robot poses and hand-eye", "-1.96"),
        (["--robot-poses", str(robot), "--hand-eye", str(hand_eye)], "robot poses and hand-eye",
         "-1.955"),
    ]:  # fmt: skip
        res = CliRunner().invoke(app, [*base, "--calibration", str(long), *reference])
        assert res.exit_code == 0, res.output
        assert f"each board held at its pose from {label}" in res.output
        assert f"its focal length corrected by {correction} %" in res.output
    res = CliRunner().invoke(app, [*base, "--poses", str(poses)])
    assert res.exit_code == 2 and "give --calibration FILE" in res.output


@pytest.mark.parametrize(
    ("hand_eye_error", "board_error", "model", "expected"),
    [
        # the camera 2 mm along x and 5 mrad about y from where the hand-eye puts it
        (tf.make(tf.rotvec_to_matrix([0, 0.005, 0]), [0.002, 0, 0]), np.eye(4), "camera_offset",
         {"dx_m": -0.002, "wy_rad": -0.005}),
        # the board 1 mm / -2 mm along its x / y and 4 mrad about its normal from its base pose
        (np.eye(4), tf.make(tf.rotvec_to_matrix([0, 0, 0.004]), [0.001, -0.002, 0]),
         "board_offset", {"dx_m": 0.001, "dy_m": -0.002, "wz_rad": 0.004}),
    ],
)  # fmt: skip
def test_the_rigs_own_offsets_are_fitted_on_the_gap(
    board, photo_set, by_truth, tmp_path, hand_eye_error, board_error, model, expected
):
    """A hand-eye error and a board-in-base error, written into the robot's files, are fitted
    from the markers' errors against that chain less their errors against the truth (the gap a
    perfect simulation would leave): the right model, its values to 2 % (first order in the
    rotation: measured within 0.5 %), and no other model as good. Taken off each half of the
    photos as fitted on the other half (how far the gap shrinks), it leaves the errors against
    the truth within 0.05 mm (measured: 0.01 mm, the model's second order)."""
    from simgap.analysis.gap import fit_rig, rig_corrected

    folder, truth = photo_set
    robot = write_pose_csv(tmp_path / "robot.csv", _robot_poses(truth, FLANGE_FROM_CAMERA))
    hand_eye = _write_transform(tmp_path / "hand_eye.yaml", FLANGE_FROM_CAMERA @ hand_eye_error)
    in_base = _write_transform(tmp_path / "in_base.yaml", BASE_FROM_BOARD @ tf.invert(board_error))
    ds = measure_photos(
        folder, board, CAMERA, reference=RobotReference.read(robot, hand_eye, in_base)
    )
    fit = fit_rig(ds, by_truth, board)
    assert fit.found is not None and fit.found.name == model and fit.look_alikes == ()
    for name, value in fit.found.parameters.items():
        assert value == pytest.approx(expected.get(name, 0.0), rel=0.02, abs=2e-5), name
    assert fit.found.misfit_after < 0.01 * fit.found.misfit_before
    shown = [line for line in fit.lines("robot poses and hand-eye") if "FOUND" in line]
    assert len(shown) == 1 and shown[0].lstrip().startswith(model)
    fold = np.arange(ds.sizes["frame"]) % 2 == 0
    corrected = rig_corrected(ds, by_truth, board, fold, model)
    left = corrected.error_translation - by_truth.error_translation
    assert float(np.abs(left).max()) < 0.05e-3


@pytest.mark.slow
def test_a_hand_eye_error_is_found_in_rendered_photos(board, photo_set, by_truth, tmp_path):
    """Photos rendered by simgap at the true poses, measured against a robot chain whose
    hand-eye puts the camera 2 mm along x and 5 mrad about y from the truth, and simulated at
    the chain's poses (16 spp): the camera offset is found with its values within 25 % and the
    x gap falls below 1 mm.

    Marked slow (40 s on 2 cores); ``benchmarks/rig_fit.py`` runs the same code on this and two
    more cases. Measured: dx -2.32 +- 0.53 mm, wy -4.76 +- 1.03 mrad; the x gap +4.2 / +4.7 /
    +5.0 mm near / mid / far, after -0.58 / -0.04 / +0.09 mm.
    """
    from simgap.analysis.gap import diagnose_photos
    from simgap.pipeline.photos import photo_of, render_photos

    folder, truth = photo_set
    rendered = tmp_path / "photos"
    rendered.mkdir()
    for f, (name, hdr) in enumerate(
        zip(truth, render_photos(by_truth, board, CAMERA, spp=16, seed=100), strict=True)
    ):
        cv2.imwrite(str(rendered / name), photo_of(hdr, CAMERA, seed=50 + f))
    error = tf.make(tf.rotvec_to_matrix([0, 0.005, 0]), [0.002, 0, 0])
    robot = write_pose_csv(tmp_path / "robot.csv", _robot_poses(truth, FLANGE_FROM_CAMERA))
    hand_eye = _write_transform(tmp_path / "hand_eye.yaml", FLANGE_FROM_CAMERA @ error)
    in_base = _write_transform(tmp_path / "in_base.yaml", BASE_FROM_BOARD)
    real = measure_photos(
        rendered, board, CAMERA, reference=RobotReference.read(robot, hand_eye, in_base)
    )
    diagnosis = diagnose_photos(real, board, CAMERA, spp=16)
    assert diagnosis.gaps.rig is not None and diagnosis.gaps.rig.found is not None
    found = diagnosis.gaps.rig.found
    assert found.name == "camera_offset"
    assert found.parameters["dx_m"] == pytest.approx(-0.002, rel=0.25)
    assert found.parameters["wy_rad"] == pytest.approx(-0.005, rel=0.25)
    assert all(abs(b.gap_median_mm[0]) < 1.0 for b in diagnosis.gaps.after_rig["distance"])


def test_no_rig_offset_is_fitted_where_the_chain_is_right(board, photo_set, by_truth, tmp_path):
    """The robot's chain as it is: the gap is zero and no model is found."""
    from simgap.analysis.gap import fit_rig

    folder, truth = photo_set
    robot = write_pose_csv(tmp_path / "robot.csv", _robot_poses(truth, FLANGE_FROM_CAMERA))
    hand_eye = _write_transform(tmp_path / "hand_eye.yaml", FLANGE_FROM_CAMERA)
    in_base = _write_transform(tmp_path / "in_base.yaml", BASE_FROM_BOARD)
    ds = measure_photos(
        folder, board, CAMERA, reference=RobotReference.read(robot, hand_eye, in_base)
    )
    fit = fit_rig(ds, by_truth, board)
    assert fit.found is None and fit.sightings == 102 and fit.frames == 6
    few = fit_rig(ds.isel(frame=slice(0, 3)), by_truth.isel(frame=slice(0, 3)), board)
    assert len(few.models) == 3 and few.found is None and few.frames == 3  # no jackknife
    assert all(np.isnan(list(m.std.values())).all() for m in few.models)
    none = fit_rig(ds.isel(frame=slice(0, 0)), by_truth.isel(frame=slice(0, 0)), board)
    assert none.models == () and none.found is None and none.sightings == 0
    lines = fit.lines("robot poses and hand-eye")
    assert lines[-1].startswith("no rig offset: no model is both 3 sd from zero")


def test_a_print_1_percent_large_is_fitted_as_a_print_scale(board, photo_set, by_truth, tmp_path):
    """Photos of the board printed 1 % large, measured with its nominal size against the true
    poses, less the nominal print's errors: a print scale of +0.86 +- 0.04 % (measured; within
    the issue's 25 % of +1 %). A board offset explains the gap alike (2.07 against 2.09: the
    scale's mean shift of the markers is an offset) and is named as a look-alike; the print
    scale, one parameter against six, is the answer."""
    from simgap.analysis.gap import fit_rig

    folder, truth = photo_set
    large = dataclasses.replace(
        board, square_m=board.square_m * 1.01, marker_m=board.marker_m * 1.01
    )
    for (name, pose), (r, _) in zip(truth.items(), VIEWS, strict=True):
        image = synthetic_view(large, CAMERA, np.array(r), pose[:3, 3])
        cv2.imwrite(str(tmp_path / name), image)
    ds = measure_photos(tmp_path, board, CAMERA, reference=PosesReference(tmp_path, truth))
    fit = fit_rig(ds, by_truth, board)
    assert fit.found is not None and fit.found.name == "print_scale"
    assert fit.found.parameters["scale"] == pytest.approx(0.01, rel=0.25)
    assert fit.look_alikes == ("board_offset",)
