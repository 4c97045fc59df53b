"""Tests of real captures (simgap.pipeline.capture): reading and validating capture folders,
ingesting the
shared sample capture (whose camera has a 2 % longer focal length than its calibration says),
writing captures, and ``simgap ingest``. No rendering: the sample's frames, copies of them, and
blank frames for the bad-folder checks."""

from __future__ import annotations

import csv
import json
import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from simgap.cli import app
from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel, load_rig
from simgap.pipeline.capture import (
    CaptureWarning,
    calibration_to_yaml,
    image_name,
    ingest,
    read_calibration,
    read_capture,
    snap_theta,
    write_capture,
)
from simgap.pose.estimate import project_tag_corners
from simgap.results.dataset import read_netcdf, write_netcdf
from tests.cf_check import assert_cf_valid
from tests.plain_xarray import assert_plain_selection

TRUE_FOCAL_PX = 1413.72  # the sample's README: the camera's true fx = fy (2 % over camera.yaml)
#: the sample's configurations (p, theta in deg): the synthetic bad-folder captures use them too
SAMPLE_GRID = [(p, deg) for p in (0, 7, 14) for deg in (0, 30, 200)]


def slope(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of y against x (with intercept)."""
    return float(np.polyfit(x, y, 1)[0])


def visible_ty(ds):
    """Expected ty and ty error (m) of the detected, visible items."""
    ok = (ds.detected.isel(variant=0, repeat=0) & ds.visible).values
    expected = ds.expected.sel(axis="ty").values[ok]
    error = ds.error.isel(variant=0, repeat=0).sel(axis="ty").values[ok]
    return expected, error


@pytest.fixture(scope="module")
def sample_ds(sample):
    return ingest(sample)


@pytest.fixture(scope="module")
def sample_rgb(sample):
    """Three sample frames (p, theta, 8-bit RGB) read with OpenCV."""
    out = []
    for name, p, deg in (("p00_t000", 0, 0), ("p07_t030", 7, 30), ("p14_t200", 14, 200)):
        bgr = cv2.imread(str(sample / "images" / f"{name}.png"), cv2.IMREAD_COLOR)
        out.append((p, math.radians(deg), cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)))
    return out


def make_capture(
    tmp_path: Path, rig, manifest: str | None = None, camera: str | None = None
) -> Path:
    """A capture folder of blank frames of the nominal camera at the sample's configurations,
    written by ``write_capture``; its manifest or camera.yaml replaced by the given texts."""
    black = np.zeros((rig.camera.height, rig.camera.width, 3), np.uint8)
    frames = [(p, math.radians(deg), 0, black) for p, deg in SAMPLE_GRID]
    folder = tmp_path / "capture"
    write_capture(folder, frames, rig.camera)
    if manifest is not None:
        (folder / "manifest.csv").write_text(manifest)
    if camera is not None:
        (folder / "camera.yaml").write_text(camera)
    return folder


# --- the sample capture -------------------------------------------------------------------------


def test_sample_every_visible_tag_detected(sample_ds):
    ds = sample_ds
    assert ds.attrs["source"] == "capture"
    assert ds.attrs["frames"] == 9 and ds.attrs["frames_unreadable"] == 0
    assert list(ds.variant.values) == ["real"] and list(ds.repeat.values) == [0]
    assert list(ds.p.values) == [0, 7, 14]
    np.testing.assert_array_equal(ds.theta.values, np.deg2rad([0.0, 30.0, 200.0]))  # snapped
    assert list(ds.tag.values) == [0, 1]
    detected = ds.detected.isel(variant=0, repeat=0).values
    visible = ds.visible.values
    # 9 frames, exactly one tag faces the camera in each (tag 0 at 0/30 deg, tag 1 at 200 deg)
    assert visible.sum() == 9
    np.testing.assert_array_equal(detected, visible)
    err = ds.error.isel(variant=0, repeat=0).values
    assert np.isfinite(err[visible]).all() and np.isnan(err[~visible]).all()
    assert float(ds.reproj_px.max()) < 0.5  # measured 0.22 px
    assert "fx: 1386.0" in ds.attrs["calibration_yaml"]
    assert "SUBPIX" in ds.attrs["detector"] and "IPPE_SQUARE" in ds.attrs["pnp"]


def test_sample_images_are_magnified_by_the_focal_length_error(sample_ds, rig, sample):
    """The images are 2 % larger about the principal point than camera.yaml predicts: the tag
    centres, measured from the principal point, scale by the focal-length ratio 1.02."""
    ds, cal = sample_ds, read_calibration(sample / "camera.yaml")
    centre = np.array([cal.cx, cal.cy])
    measured, predicted = [], []
    for tag in ds.tag.values:
        for p in ds.p.values:
            for theta in ds.theta.values:
                c = ds.corners.sel(variant="real", repeat=0, tag=tag, p=p, theta=theta).values
                if not bool(ds.visible.sel(tag=tag, p=p, theta=theta)):
                    continue
                pred = project_tag_corners(
                    rig.eyepoint_from_tag(int(tag), int(p), float(theta)),
                    rig.tags.size,
                    cal,
                )
                measured.append(c.mean(axis=0) - centre)
                predicted.append(pred.mean(axis=0) - centre)
    m, q = np.ravel(measured), np.ravel(predicted)
    magnification = float(m @ q / (q @ q))
    # measured 1.01983 (residuals <= 0.16 px); truth 1413.72 / 1386.0 = 1.0200. Centroids are
    # immune to the detector's edge bias (it moves all four corners inwards symmetrically).
    assert magnification == pytest.approx(TRUE_FOCAL_PX / 1386.0, abs=0.003)


def test_sample_focal_error_shortens_the_estimated_distance(sample_ds, sample):
    """The focal-length effect on ty: the calibration's focal length is 1.96 % short, so every
    estimated distance is 1.96 % short (pinhole model: -0.02 / 1.02 = -0.0196).

    On this sample the *raw* slope of error_ty against expected ty is not -0.0196 but
    +0.0154 (SUBPIX; NONE +0.019, CONTOUR +0.034, APRILTAG -0.004): the detected marker sides
    come out about 1 px shorter than projected (an edge bias of the sRGB + blur + quantisation
    chain), which makes the distance too long by 1 px / side_px, i.e. in proportion to the
    distance, and that dominates at 0.2-0.7 m. With the true focal length the raw slope is
    +0.0357. The focal effect is therefore measured as the difference of the two ingests, on the
    same detected corners: its slope is -0.0203 against -0.0196 expected (the difference scales
    with the *estimated* distance, which carries the edge bias); tolerance 0.004 as the brief
    asks, several times the 0.0007 seen.
    """
    x, raw = visible_ty(sample_ds)
    true_ds = ingest(sample, calibration=CameraModel(fx=TRUE_FOCAL_PX, fy=TRUE_FOCAL_PX))
    assert true_ds.attrs["calibration_source"] == "override"
    x_true, err_true = visible_ty(true_ds)
    np.testing.assert_array_equal(x, x_true)
    assert len(x) == 9
    focal_effect = slope(x, raw - err_true)
    assert focal_effect == pytest.approx(-0.02 / 1.02, abs=0.004)
    # and every single configuration's distance is shorter with the capture's calibration
    assert np.all(raw < err_true)


# --- writing and reading back ------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["ros", "opencv"])
def test_write_read_round_trip(tmp_path, sample_rgb, rig, fmt, sample):
    cal = read_calibration(sample / "camera.yaml")
    frames = [(p, theta, 0, rgb) for p, theta, rgb in sample_rgb]
    frames.append((0, 0.0, 1, sample_rgb[0][2], "second repeat"))  # a repeat with a note
    folder = tmp_path / fmt
    manifest = write_capture(folder, frames, cal, fmt=fmt)
    assert manifest == folder / "manifest.csv"
    text = (folder / "camera.yaml").read_text()
    assert text.startswith("%YAML") == (fmt == "opencv")
    with open(manifest, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["image", "p", "theta_rad", "repeat", "note"]
    assert [r["image"] for r in rows] == [
        "images/p00_t000.png",
        "images/p07_t030.png",
        "images/p14_t200.png",
        "images/p00_t000_r1.png",
    ]
    cap = read_capture(folder, rig)
    assert cap.calibration == cal
    assert [(f.p, f.repeat, f.note) for f in cap.frames] == [
        (0, 0, ""),
        (7, 0, ""),
        (14, 0, ""),
        (0, 1, "second repeat"),
    ]
    thetas = [f.theta for f in cap.frames]
    np.testing.assert_allclose(thetas, [fr[1] for fr in frames], rtol=0, atol=1e-12)
    for f, fr in zip(cap.frames, frames, strict=True):
        rgb = fr[3]
        back = cv2.cvtColor(cv2.imread(str(f.image)), cv2.COLOR_BGR2RGB)
        np.testing.assert_array_equal(back, rgb)  # PNG is lossless
    assert not list(folder.rglob("*.tmp"))  # atomic writes leave no temporaries


def test_written_capture_ingests_like_the_original(tmp_path, sample_rgb, sample_ds, sample):
    cal = read_calibration(sample / "camera.yaml")
    folder = tmp_path / "copy"
    write_capture(folder, ((p, t, 0, rgb) for p, t, rgb in sample_rgb), cal)
    ds = ingest(folder)
    # 3 frames on a 3 x 3 grid of coords: the 6 configurations absent from the manifest are empty
    assert int(ds.detected.sum()) == 3 and int(np.isfinite(ds.error).sum()) == 3 * 6
    for p, theta, _ in sample_rgb:
        got = ds.sel(p=p, theta=theta, method="nearest")
        ref = sample_ds.sel(p=p, theta=theta, method="nearest")
        np.testing.assert_array_equal(got.detected.values, ref.detected.values)
        np.testing.assert_array_equal(got.corners.values, ref.corners.values)


def test_two_frames_of_a_pose_give_its_temporal_noise(tmp_path, sample_rgb, sample):
    from simgap.diagnosis.items import repeats_of_simulation

    cal = read_calibration(sample / "camera.yaml")
    rng = np.random.default_rng(5)
    frames = []
    for k, (p, t, rgb) in enumerate(sample_rgb):
        frames.append((p, t, 0, rgb))
        if k == 0:  # the same frame again: a copied file, no second exposure
            frames.append((p, t, 1, rgb))
        else:  # 3 DN of new noise in every channel
            noisy = rgb + rng.normal(0.0, 3.0, rgb.shape)
            frames.append((p, t, 1, np.clip(np.round(noisy), 0, 255).astype(np.uint8)))
    folder = tmp_path / "repeats"
    write_capture(folder, frames, cal)
    with pytest.warns(CaptureWarning, match=r"1 pose\(s\) offer identical frames as repeats"):
        ds = ingest(folder)
    temporal = ds.image_stats.sel(stat="temporal_noise_paper_linear", variant="real")
    seen = ds.detected.isel(variant=0, repeat=0) & ds.visible
    first, second = temporal.sel(repeat=0).values[seen], temporal.sel(repeat=1).values[seen]
    assert seen.sum() == 3 and np.isnan(second).all()  # measured once per pose, on its first
    (same, *new) = [temporal.sel(repeat=0, p=p, theta=t, method="nearest") for p, t, _ in
                    sample_rgb]  # fmt: skip
    # the copy is no second exposure: no temporal noise (it had read 0, "no noise"; issue 51)
    assert bool(same.isnull().all())
    assert all(float(v.max(skipna=True)) > 0 for v in new)
    copied = json.loads(ds.attrs["frames_identical_repeats"])
    assert len(copied) == 1 and copied[0].endswith("_r1.png")
    # against a simulation with one frame a pose, the first frames are compared and the
    # temporal noise stays
    one = repeats_of_simulation(ds, ds.isel(repeat=[0]))
    assert list(one.repeat.values) == [0]
    np.testing.assert_array_equal(one.error.values, ds.error.isel(repeat=[0]).values)
    np.testing.assert_array_equal(
        one.image_stats.sel(stat="temporal_noise_paper_linear").values[0, 0][seen.values],
        first,
    )


def test_write_jpeg(tmp_path, sample_rgb, rig, sample):
    p, theta, rgb = sample_rgb[0]
    cal = read_calibration(sample / "camera.yaml")
    folder = tmp_path / "jpg"
    write_capture(folder, [(p, theta, 0, rgb)], cal, image_format="jpg", jpeg_quality=90)
    (frame,) = read_capture(folder, rig).frames
    assert frame.image.name == "p00_t000.jpg"
    back = cv2.cvtColor(cv2.imread(str(frame.image)), cv2.COLOR_BGR2RGB)
    assert 0 < np.abs(back.astype(int) - rgb).mean() < 4.0  # lossy: 2.3 on this noisy frame


def test_write_capture_rejects_bad_frames(tmp_path):
    cal = CameraModel(width=64, height=48, fx=60.0, fy=60.0, cx=31.5, cy=23.5)
    with pytest.raises(ValueError, match="expected uint8 48x64"):
        write_capture(tmp_path / "a", [(0, 0.0, 0, np.zeros((48, 64, 3), np.float32))], cal)
    frame = np.zeros((48, 64, 3), np.uint8)
    with pytest.raises(ValueError, match="same p, theta and repeat"):
        write_capture(tmp_path / "b", [(0, 0.0, 0, frame), (0, 2 * math.pi, 0, frame)], cal)
    with pytest.raises(ValueError, match="fmt"):
        write_capture(tmp_path / "c", [], cal, fmt="json")


def test_image_names():
    assert image_name(3, math.radians(200)) == "p03_t200.png"
    assert image_name(14, math.radians(350), 2, "jpg") == "p14_t350_r2.jpg"
    assert image_name(0, math.radians(12.5)) == "p00_t012p5.png"


@pytest.mark.parametrize("fmt", ["ros", "opencv"])
def test_calibration_round_trip_with_distortion(tmp_path, fmt):
    cal = CameraModel(1280, 720, 912.3, 910.8, 641.2, 359.9, (0.11, -0.23, 0.001, -0.002, 0.05))
    path = tmp_path / "camera.yaml"
    path.write_text(calibration_to_yaml(cal, fmt))
    assert read_calibration(path) == cal


def test_snap_theta(rig):
    assert snap_theta(0.523599, rig) == np.deg2rad(30.0)
    assert snap_theta(-math.radians(10) + 5e-4, rig) == np.deg2rad(350.0)  # wrapped
    assert snap_theta(2 * math.pi - 1e-4, rig) == 0.0
    assert snap_theta(math.radians(5), rig) is None


# --- calibration files ------------------------------------------------------------------------

OPENCV_CAL = """%YAML:1.0
---
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1386., 0., 959.5, 0., 1386., 539.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 4
   dt: d
   data: [ 0.1, -0.05, 0., 0. ]
"""


def test_opencv_calibration_without_size_and_short_distortion(tmp_path):
    path = tmp_path / "camera.yaml"
    path.write_text(OPENCV_CAL)
    cal = read_calibration(path, 1920, 1080)
    assert cal == CameraModel(distortion=(0.1, -0.05, 0.0, 0.0, 0.0))  # padded with zeros
    with pytest.raises(ConfigError, match=r"camera.yaml: image_width: required key is missing"):
        read_calibration(path)


def test_opencv_calibration_bad_matrix(tmp_path):
    path = tmp_path / "camera.yaml"
    path.write_text(OPENCV_CAL.replace("0., 0., 1. ]", "0., 0. ]"))
    with pytest.raises(ConfigError, match=r"camera_matrix.data: expected 9 numbers, got 8"):
        read_calibration(path, 1920, 1080)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("- 1.0\ndistortion_model", "distortion_model", r"camera_matrix.data: expected 9 numbers"),
        ("plumb_bob", "ocam", r"distortion_model: expected one of plumb_bob.*'ocam'"),
        ("image_width: 1920", "image_width: -1", r"image_width: expected a positive integer"),
        ("distortion_coefficients:", "dist_coeffs:", r"distortion_coefficients: required key"),
        ("  - 0.0\n  - 1386.0", "  - 5.0\n  - 1386.0", r"camera_matrix.data: expected .* skew"),
        ("  - 0.0\n  - 959.5", "  - 0.0\n  - oops", r"camera_matrix.data\[2\]: expected a finite"),
    ],
)
def test_ros_calibration_errors(tmp_path, old, new, message, rig):
    text = calibration_to_yaml(rig.camera)  # ROS camera_info, as the sample's camera.yaml
    assert old in text
    path = tmp_path / "camera.yaml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(ConfigError, match=rf"{path}: {message}"):
        read_calibration(path)


# --- bad capture folders ----------------------------------------------------------------------

HEADER = "image,p,theta_rad"


def test_missing_folder(tmp_path, rig):
    with pytest.raises(ConfigError, match=r"nowhere: capture folder not found"):
        read_capture(tmp_path / "nowhere", rig)


@pytest.mark.parametrize("name", ["camera.yaml", "manifest.csv"])
def test_missing_calibration_or_manifest(tmp_path, rig, name):
    folder = make_capture(tmp_path, rig)
    (folder / name).unlink()
    with pytest.raises(ConfigError, match=rf"{folder / name}: \w+ file not found"):
        read_capture(folder, rig)


def test_unknown_column(tmp_path, rig):
    folder = make_capture(tmp_path, rig, f"{HEADER},exposure\nimages/p00_t000.png,0,0.0,1.0\n")
    with pytest.raises(
        ConfigError,
        match=r"manifest.csv: column 'exposure': unknown; allowed columns: "
        r"image, p, theta_rad, repeat, note",
    ):
        read_capture(folder, rig)


def test_missing_column(tmp_path, rig):
    folder = make_capture(tmp_path, rig, "image,p\nimages/p00_t000.png,0\n")
    with pytest.raises(ConfigError, match=r"manifest.csv: header: missing column 'theta_rad'"):
        read_capture(folder, rig)


def test_off_grid_p(tmp_path, rig):
    folder = make_capture(
        tmp_path, rig, f"{HEADER}\nimages/p00_t000.png,0,0.0\nimages/p07_t000.png,15,0.0\n"
    )
    with pytest.raises(
        ConfigError,
        match=r"row 2 \(line 3\): p: expected a pin hole of the rig \(0..14\), got '15'",
    ):
        read_capture(folder, rig)


def test_off_grid_theta(tmp_path, rig):
    folder = make_capture(tmp_path, rig, f"{HEADER}\nimages/p00_t000.png,0,0.6\n")
    with pytest.raises(
        ConfigError, match=r"row 1 \(line 2\): theta_rad: expected a turntable stop .* got '0.6'"
    ):
        read_capture(folder, rig)


def test_missing_image(tmp_path, rig):
    folder = make_capture(
        tmp_path, rig, f"{HEADER}\nimages/p00_t000.png,0,0.0\nimages/p09_t000.png,9,0.0\n"
    )
    with pytest.raises(
        ConfigError,
        match=rf"row 2 \(line 3\): image: file not found: {folder / 'images/p09_t000.png'}",
    ):
        read_capture(folder, rig)


def test_calibration_size_differs_from_images(tmp_path, rig):
    camera = calibration_to_yaml(rig.camera).replace("image_width: 1920", "image_width: 1280")
    folder = make_capture(tmp_path, rig, camera=camera)
    with pytest.raises(
        ConfigError, match=r"camera.yaml: image size 1280x1080 differs from the images' 1920x1080"
    ):
        read_capture(folder, rig)


def test_duplicate_rows(tmp_path, rig):
    folder = make_capture(
        tmp_path,
        rig,
        f"{HEADER}\nimages/p00_t000.png,0,0.0\nimages/p07_t000.png,7,0\n"
        "images/p00_t030.png,0,6.283185\n",  # 2 pi is the stop 0
    )
    with pytest.raises(
        ConfigError, match=r"row 3 \(line 4\): duplicate of row 1 \(p=0, theta=0 deg, repeat=0\)"
    ):
        read_capture(folder, rig)


def test_one_image_file_for_two_poses_is_refused(tmp_path, rig):
    """The same file on every manifest row had given median pose errors of 192 mm (issue 51)."""
    folder = make_capture(
        tmp_path, rig, f"{HEADER}\nimages/p00_t000.png,0,0.0\nimages/p00_t000.png,7,0\n"
    )
    with pytest.raises(
        ConfigError,
        match=r"row 2 \(line 3\): image: images/p00_t000.png is also row 1's, at another pose "
        r"\(p=0, theta=0 deg\)",
    ):
        read_capture(folder, rig)


def test_bad_camera_matrix_length(tmp_path, rig):
    text = calibration_to_yaml(rig.camera)
    camera = text.replace("  - 1.0\ndistortion_model", "distortion_model")
    folder = make_capture(tmp_path, rig, camera=camera)
    with pytest.raises(
        ConfigError,
        match=rf"{folder / 'camera.yaml'}: camera_matrix.data: expected 9 numbers, got 8",
    ):
        read_capture(folder, rig)


def test_repeats_in_manifest(tmp_path, rig):
    folder = make_capture(
        tmp_path,
        rig,
        f"{HEADER},repeat,note\nimages/p00_t000.png,0,0.0,0,first\n"
        'images/p00_t030.png,0,0.0,1,"second, with a comma"\n',
    )
    cap = read_capture(folder, rig)
    assert [(f.repeat, f.note) for f in cap.frames] == [(0, "first"), (1, "second, with a comma")]
    with pytest.raises(ConfigError, match=r"row 1 \(line 2\): repeat: expected an integer >= 0"):
        (folder / "manifest.csv").write_text(f"{HEADER},repeat\nimages/p00_t000.png,0,0.0,-1\n")
        read_capture(folder, rig)


def test_unreadable_frame_is_a_recorded_failure(tmp_path, rig, sample):
    folder = tmp_path / "capture"  # the sample's real frames (copied): the other 8 detect
    (folder / "images").mkdir(parents=True)
    for img in (sample / "images").iterdir():  # copies: links leaving the folder are refused
        (folder / "images" / img.name).write_bytes(img.read_bytes())
    for name in ("manifest.csv", "camera.yaml"):
        (folder / name).write_text((sample / name).read_text())
    bad = folder / "images" / "p00_t000.png"  # the first frame: the size check uses the next one
    bad.unlink()
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + b"not really a png" * 10)
    with pytest.warns(CaptureWarning, match=r"p00_t000.png: frame cannot be decoded"):
        ds = ingest(folder, rig)
    assert ds.attrs["frames_unreadable"] == 1 and "p00_t000.png" in ds.attrs["frames_failed"]
    det = ds.detected.isel(variant=0, repeat=0)
    assert not det.sel(p=0, theta=0.0).any()
    assert np.isnan(ds.error.sel(p=0, theta=0.0)).all()
    visible = ds.visible.values.copy()
    visible[:, 0, 0] = False
    np.testing.assert_array_equal(det.values, visible)  # the other 8 frames are all detected


# --- command line -----------------------------------------------------------------------------


def test_cli_ingest(tmp_path, sample):
    out = tmp_path / "real.nc"
    res = CliRunner().invoke(app, ["ingest", str(sample), "-o", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    said = "9 frame(s), 0 unreadable; 9 visible items (tag x configuration), 9 detected"
    assert said in res.output
    ds = read_netcdf(out)
    assert ds.attrs["source"] == "capture" and ds.attrs["capture_dir"] == str(sample.resolve())
    assert ds.detected.dtype == bool and int(ds.detected.sum()) == 9
    assert list(ds.variant.values) == ["real"]


def test_ingested_capture_is_cf_valid(tmp_path, sample_ds):
    """A real capture's dataset (image statistics, calibration attrs) passes cfchecks (CF-1.10)."""
    nc = write_netcdf(sample_ds, tmp_path / "real.nc")
    assert_cf_valid(nc)
    assert_plain_selection(nc, {"variant", "stat", "translation_axis", "rotation_axis"})
    assert read_netcdf(nc).identical(sample_ds)


def test_cli_ingest_bad_folder(tmp_path, rig):
    folder = make_capture(tmp_path, rig, f"{HEADER}\nimages/p00_t000.png,0,0.6\n")
    out = tmp_path / "real.nc"
    res = CliRunner().invoke(app, ["ingest", str(folder), "-o", str(out)])
    assert res.exit_code == 2, res.output
    assert "manifest.csv: row 1 (line 2): theta_rad" in res.output
    assert not out.exists()


def test_cli_ingest_bad_experiment(tmp_path, rig):
    folder = make_capture(tmp_path, rig)
    res = CliRunner().invoke(
        app, ["ingest", str(folder), "-o", str(tmp_path / "r.nc"), "--experiment", "nope.yaml"]
    )
    assert res.exit_code == 2, res.output
    assert "nope.yaml: file not found" in res.output


def test_calibration_file_under_any_name(tmp_path, sample, sample_ds):
    """``--calibration FILE`` replaces camera.yaml: a ROS ost.yaml in a folder without one, and
    an OpenCV file winning over the folder's camera.yaml; both give the same poses (same
    calibration, same frames), and the dataset names the file it read."""
    true_cal = CameraModel(fx=TRUE_FOCAL_PX, fy=TRUE_FOCAL_PX)
    ost = tmp_path / "ost.yaml"
    ost.write_text(calibration_to_yaml(true_cal, "ros"))
    opencv = tmp_path / "calib_opencv.yml"
    opencv.write_text(calibration_to_yaml(true_cal, "opencv"))
    bare = tmp_path / "bare"
    shutil.copytree(sample, bare, ignore=shutil.ignore_patterns("camera.yaml"))
    with pytest.raises(ConfigError, match="camera.yaml: calibration file not found"):
        read_capture(bare, load_rig())
    from_ost = ingest(bare, calibration_file=ost)
    out = tmp_path / "real.nc"
    args = ["ingest", str(sample), "-o", str(out), "--no-progress", "--calibration", str(opencv)]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    both = read_netcdf(out)
    for ds, path in ((from_ost, ost), (both, opencv)):
        assert ds.attrs["calibration_source"] == "--calibration"
        assert ds.attrs["calibration_path"] == str(path.resolve())
        assert ds.attrs["calibration_file"] == path.read_text()
        assert f"fx: {TRUE_FOCAL_PX}" in ds.attrs["calibration_yaml"]
    np.testing.assert_allclose(both.error.values, from_ost.error.values, rtol=1e-9, equal_nan=True)
    # the true focal length moves every visible distance error (the camera.yaml one is 2 % short)
    _, err_file = visible_ty(sample_ds)
    _, err_opt = visible_ty(both)
    assert np.all(err_file < err_opt)
    assert sample_ds.attrs["calibration_source"] == "camera.yaml"


@pytest.mark.parametrize(
    "text,message",
    [
        (None, "--calibration {path}: calibration file not found"),
        ("image_width: 1920\n", "{path}: camera_matrix"),
    ],
)
def test_cli_ingest_bad_calibration_file(tmp_path, rig, text, message):
    folder = make_capture(tmp_path, rig)
    path = tmp_path / "ost.yaml"
    if text is not None:
        path.write_text(text)
    out = tmp_path / "r.nc"
    args = ["ingest", str(folder), "-o", str(out), "--calibration", str(path)]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, res.output
    assert message.format(path=path) in res.output and "Traceback" not in res.output
    assert not out.exists()


def test_a_manifest_linked_out_of_the_capture_is_refused_unread(tmp_path, rig):
    """A manifest.csv that links to a file elsewhere is refused before it is read, so no line of
    that file reaches the terminal (issue 51)."""
    folder = make_capture(tmp_path, rig)
    secret = tmp_path / "secret.txt"
    secret.write_text("password=hunter2\n")
    (folder / "manifest.csv").unlink()
    (folder / "manifest.csv").symlink_to(secret)
    with pytest.raises(ConfigError, match=r"manifest.csv: resolves to .*secret.txt, outside") as e:
        read_capture(folder, rig)
    assert "hunter2" not in str(e.value)


def test_a_long_value_is_cut_in_the_message(tmp_path, rig):
    folder = make_capture(tmp_path, rig, f"{HEADER}\nimages/p00_t000.png,{'9' * 5000},0.0\n")
    pattern = r"p: expected a pin hole .* got '9{59}\.\.\. \(4942 more characters\)$"
    with pytest.raises(ConfigError, match=pattern) as e:
        read_capture(folder, rig)
    assert len(str(e.value)) < 400


def test_an_image_that_is_a_link_loop_is_named(tmp_path, rig):
    """A manifest image that links to itself had raised "RuntimeError: Symlink loop" (issue 51)."""
    folder = make_capture(tmp_path, rig, f"{HEADER}\nimages/loop.png,0,0.0\n")
    (folder / "images" / "loop.png").symlink_to("loop.png")
    with pytest.raises(
        ConfigError, match=r"row 1 \(line 2\): image: 'images/loop.png': cannot resolve the path"
    ):
        read_capture(folder, rig)
