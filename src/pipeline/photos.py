"""A folder of real photos of a board: each marker's single-marker pose error against the board.

The rig beyond PASS (docs/conventions.md §6): photos of a planar board of markers
(:class:`simgap.core.board.Board`) taken by a calibrated camera from any poses. Each photo's
reference is the board's pose from all its points (:func:`simgap.pose.board_pose.view_board`), or
one an external source gives (:mod:`simgap.pipeline.photo_references`: a poses file, or robot
poses and a hand-eye); each detected marker is then posed from its own four corners, as a robot
that sees one marker would, and compared with it (:func:`simgap.pose.board_pose.marker_error`).

The dataset (:func:`measure_photos`) has a ``frame`` dimension (the photo's file name) and a
``marker`` dimension (board marker id); the board's reference pose per frame is a variable.
Every label dimension is indexed, so plain ``xarray.open_dataset`` selects by name
(``.sel(camera_axis="z")``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import xarray as xr

from simgap.core import transforms as tf
from simgap.core.aruco import marker_cells
from simgap.core.atomic import atomic_write
from simgap.core.board import Board
from simgap.core.config import ConfigError, to_mapping
from simgap.core.limits import MAX_PIXELS, PHOTO_SPP
from simgap.core.progress import ProgressCallback, Steps
from simgap.core.rig import CameraModel
from simgap.effects.image import ImageContext, run_pipeline
from simgap.effects.state import ImageState
from simgap.pipeline.capture.folder import check_pixel_budget, frame_size, read_image
from simgap.pipeline.photo_references import (
    EXTERNAL_REFERENCES,
    RENDERED_REFERENCE,
    PhotoReference,
    PosesReference,
    ResolvedReference,
)
from simgap.pose.board_calibration import PhotoCalibration, board_points, calibrate_from_photos
from simgap.pose.board_pose import BoardView, marker_error, view_board
from simgap.pose.calibration_check import FileCheck
from simgap.pose.detect import Detector, DetectorSettings
from simgap.pose.estimate import PnPSettings
from simgap.pose.image_stats import STAT_INDEX, MarkerLayout, tag_stats
from simgap.render.imaging import to_gray
from simgap.results.contract import PIXEL_UNITS
from simgap.scene.spec import SceneSpec

#: File endings read as photos (case-insensitive); PNG and JPEG only, whose size is read from
#: the header before any decode (the pixel budget).
PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg")
#: The ``source`` attribute of a photo dataset (what simgap's output checks recognise).
PHOTO_SOURCE = "board_photos"
#: The attribute of a photo dataset that holds its calibration file held against the photos
#: (:meth:`simgap.pose.calibration_check.FileCheck.to_mapping`, written as its ``repr``).
CALIBRATION_CHECK = "calibration_check"
#: Per-marker image statistics of a photo dataset: variable -> the statistic of
#: :mod:`simgap.pose.image_stats` it holds (the sticker's paper and ink levels, linear fraction of
#: full scale, and the 10-90 % edge width of its black border, px).
IMAGE_STATS = {
    "paper_level": "paper_linear",
    "ink_level": "ink_linear",
    "edge_width": "edge_width_px",
}
#: Per-marker variables of a photo dataset (frame x marker), besides the errors.
PER_MARKER = ("distance", "view_angle", "centre_u", "centre_v", "marker_reproj", *IMAGE_STATS)
#: White cells around a marker the image statistics read its paper from
#: (:class:`simgap.pose.image_stats.MarkerLayout`): their least. A ChArUco marker's white square
#: may be narrower (a calib.io board's: 1.1 cells); the ring then reaches the black squares
#: beside it and the paper's median holds while more than half the ring is paper.
QUIET_CELLS = 2
#: Labels of the camera-frame axes (OpenCV: x right, y down, z forward = depth).
CAMERA_AXES = ("x", "y", "z")
#: Labels of the board-frame axes (OpenCV's board frame: x along a row, y down, z into it).
BOARD_AXES = ("x", "y", "z")


def photo_files(folder: Path) -> list[Path]:
    """The photos of ``folder`` (:data:`PHOTO_SUFFIXES`), sorted by name.

    Raises
    ------
    simgap.core.config.ConfigError
        Where ``folder`` is not a folder or holds no photo.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"{folder}: expected a folder of photos (PNG or JPEG)")
    files = sorted(
        p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in PHOTO_SUFFIXES
    )
    if not files:
        raise ConfigError(f"{folder}: no photo in it (expected files ending {PHOTO_SUFFIXES})")
    return files


def _gray(path: Path, width: int, height: int, max_pixels: int) -> np.ndarray | str:
    """A photo as 8-bit grey, or why it cannot be used (the pixel budget checked first)."""
    size = frame_size(path)
    if size is not None:
        check_pixel_budget(*size, max_pixels, str(path), key="image size")
    img = read_image(path, width, height)
    return img if isinstance(img, str) else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def photo_points(
    folder: Path, board: Board, max_pixels: int = MAX_PIXELS
) -> tuple[list[tuple[np.ndarray, np.ndarray]], tuple[int, int]]:
    """Each photo's board points and image points, and the photos' size (w, h px).

    :func:`named_photo_points` without the names.
    """
    _, points, size = named_photo_points(folder, board, max_pixels)
    return points, size


def named_photo_points(
    folder: Path, board: Board, max_pixels: int = MAX_PIXELS
) -> tuple[list[str], list[tuple[np.ndarray, np.ndarray]], tuple[int, int]]:
    """The photos that show the board, their board and image points, and their size (w, h px).

    :func:`simgap.pose.board_calibration.board_points` on every photo of ``folder`` that has
    the size of the first one (px) and can be decoded; simgap's detector with the board's
    dictionary. The names are the photos' file names, in the points' order.

    Raises
    ------
    simgap.core.config.ConfigError
        For a folder without photos, a photo over the pixel budget or a first photo whose size
        cannot be read.
    """
    files = photo_files(folder)
    size = frame_size(files[0])
    if size is None:
        raise ConfigError(f"{files[0]}: cannot be decoded (its size is not readable)")
    detector = Detector(DetectorSettings(board.dictionary))
    names, points = [], []
    for path in files:
        gray = _gray(path, *size, max_pixels)
        if isinstance(gray, str):
            continue
        for found in board_points([gray], board, detector):
            names.append(path.name)
            points.append(found)
    return names, points, size


def calibrate_photos(
    folder: Path, board: Board, model: str = "plumb_bob", max_pixels: int = MAX_PIXELS
) -> PhotoCalibration:
    """Calibrate the camera of a folder of board photos.

    :func:`photo_points`, then :func:`simgap.pose.board_calibration.calibrate_from_photos`.

    Raises
    ------
    simgap.core.config.ConfigError
        As :func:`photo_points`, and for too few photos that show the board.
    """
    points, size = photo_points(folder, board, max_pixels)
    try:
        return calibrate_from_photos(points, size, model)
    except ValueError as exc:
        raise ConfigError(f"{folder}: {exc}") from exc


def measure_photos(
    folder: Path,
    board: Board,
    camera: CameraModel,
    detector: DetectorSettings | None = None,
    pnp: PnPSettings | None = None,
    max_pixels: int = MAX_PIXELS,
    progress: ProgressCallback | None = None,
    reference: PhotoReference | None = None,
) -> xr.Dataset:
    """Every marker's single-marker pose error against its board, photo by photo.

    Parameters
    ----------
    folder : Path
        Photos (:func:`photo_files`), each ``camera.width`` x ``camera.height`` px.
    board : Board
        The printed board.
    camera : CameraModel
        The photos' calibration (any distortion model).
    detector : DetectorSettings, optional
        The ArUco detector; by default simgap's (SUBPIX) with the board's dictionary.
    pnp : PnPSettings, optional
        The single-marker PnP solver (default :class:`~simgap.pose.estimate.PnPSettings`).
    max_pixels : int
        Pixel budget checked from each file's header before decoding (px).
    progress : ProgressCallback, optional
        Told of each photo measured (step ``"photos"``).
    reference : PhotoReference, optional
        Where each photo's reference pose comes from (:mod:`simgap.pipeline.photo_references`:
        a poses file, or robot poses and a hand-eye); by default the board's pose from its own
        points.

    Returns
    -------
    xarray.Dataset
        Dimensions ``frame``, ``marker``, ``camera_axis``, ``board_axis``. Variables:
        ``detected`` (0/1), ``error_translation`` (m, camera frame), ``error_rotation`` (rad),
        ``error_board_translation`` (m, board frame), ``distance`` (m), ``view_angle`` (deg),
        ``centre_u`` / ``centre_v`` (px), ``marker_reproj`` (px); per frame ``reference_points``,
        ``reference_reproj`` (px): the board's points and their RMS reprojection through its own
        pose, and ``board_translation`` (m) and ``board_rotation`` (rad): the board's reference
        pose in the camera frame. With an external ``reference`` the latter two are its pose,
        ``board_points_translation`` / ``board_points_rotation`` keep the board's pose from its
        points, and the attributes name the reference and its files (``reference``,
        :class:`~simgap.pipeline.photo_references.ResolvedReference`). NaN where a marker was
        not seen or a photo had no reference. A photo that cannot be decoded or is of another
        size is listed in the ``frames_unreadable`` attribute with the reason.

    Raises
    ------
    simgap.core.config.ConfigError
        For a folder without photos or a photo over the pixel budget; a photo the
        ``reference`` has no pose for (before any photo is read).
    """
    files = photo_files(folder)
    return _measure(
        [p.name for p in files],
        lambda f: _gray(files[f], camera.width, camera.height, max_pixels),
        board, camera, detector, pnp, Steps(progress), "photos", reference,
    )  # fmt: skip


def render_photos(
    real: xr.Dataset,
    board: Board,
    camera: CameraModel,
    spec: SceneSpec | None = None,
    spp: int = PHOTO_SPP,
    seed: int = 0,
    progress: ProgressCallback | None = None,
) -> list[np.ndarray | None]:
    """Each photo of ``real`` rendered at its reference pose: linear RGB, or None without one.

    :class:`simgap.render.board_scene.BoardScene` through ``camera`` (the scene's tag print,
    integrator and pixel filter; path traced at ``spp`` samples per pixel, sampler seed
    ``seed`` + the frame's index). ``real`` is :func:`measure_photos`'s dataset.
    """
    from simgap.render.board_scene import BoardScene
    from simgap.scene.spec import default_scene_spec

    scene = BoardScene(board, camera, spec or default_scene_spec(), spp)
    poses = reference_poses(real)
    steps = Steps(progress)
    steps.start("rendering", len(poses))
    out: list[np.ndarray | None] = []
    for f, pose in enumerate(poses):
        out.append(None if pose is None else scene.render(pose, seed + f))
        steps.advance()
    return out


def reference_poses(real: xr.Dataset) -> list[np.ndarray | None]:
    """Each frame's reference ``camera_from_board`` (4 x 4, m; None where it has none).

    From the dataset's ``board_rotation`` (rad) and ``board_translation`` (m)
    (:func:`measure_photos`).
    """
    rotations, translations = real["board_rotation"].values, real["board_translation"].values
    return [
        tf.make(tf.rotvec_to_matrix(r), t)
        if np.isfinite(r).all() and np.isfinite(t).all()
        else None
        for r, t in zip(rotations, translations, strict=True)
    ]


def photo_of(
    hdr: np.ndarray, camera: CameraModel, image: ImageState | None = None, seed: int = 0
) -> np.ndarray:
    """A render (linear RGB) as the 8-bit grey photo a camera writes.

    The camera pipeline ``image`` (:func:`simgap.effects.image.run_pipeline`: the catalogue's
    image effects, then the encoding; default: sRGB alone), its noise drawn from ``seed``.
    """
    ctx = ImageContext((0, 0), camera, np.random.default_rng(seed))
    return to_gray(run_pipeline(hdr, image or ImageState(), ctx))


def simulate_photos(
    real: xr.Dataset,
    renders: list[np.ndarray | None],
    board: Board,
    camera: CameraModel,
    image: ImageState | None = None,
    detector: DetectorSettings | None = None,
    pnp: PnPSettings | None = None,
    progress: ProgressCallback | None = None,
) -> xr.Dataset:
    """The photo set simulated: its renders (:func:`render_photos`) measured as photos are.

    Each render goes through the camera pipeline ``image`` (:func:`simgap.effects.image.
    run_pipeline`: the catalogue's image effects, then the encoding; default: sRGB alone) and is
    measured as a photo is: its own reference from its points, then each marker; where
    ``real`` was measured against an external reference (a poses file, a robot), each render's
    markers against the pose it was rendered at, that reference
    (:class:`~simgap.pipeline.photo_references.PosesReference`). A frame without a render is
    listed in ``frames_unreadable``. The layout of :func:`measure_photos`.
    """
    def load(f: int) -> np.ndarray | str:
        hdr = renders[f]
        return "no reference pose in the photo" if hdr is None else photo_of(hdr, camera, image, f)

    names = [str(n) for n in real["frame"].values]
    reference = None
    if real.attrs.get("reference") in EXTERNAL_REFERENCES:
        poses = dict(zip(names, reference_poses(real), strict=True))
        reference = PosesReference(
            None,
            {n: pose for n, pose in poses.items() if pose is not None},
            f"{RENDERED_REFERENCE} ({real.attrs['reference']})",
        )
    return _measure(
        names, load, board, camera, detector, pnp, Steps(progress), "measuring", reference
    )


def _measure(
    names: list[str],
    load: Callable[[int], np.ndarray | str],
    board: Board,
    camera: CameraModel,
    detector: DetectorSettings | None,
    pnp: PnPSettings | None,
    steps: Steps,
    step: str,
    reference: PhotoReference | None = None,
) -> xr.Dataset:
    """Measure frames ``names``: ``load(f)`` gives frame f as 8-bit grey, or why not.

    Two passes: each frame's board view and its markers' image statistics, then each marker's
    error against the reference (the board's own pose, or ``reference``'s, resolved once every
    frame's board pose is known).
    """
    settings = detector or DetectorSettings(dictionary=board.dictionary)
    pnp = pnp or PnPSettings()
    if reference is not None:
        reference.check(names)
    det = Detector(settings)
    layout = MarkerLayout(marker_cells(board.dictionary), QUIET_CELLS)
    ids = sorted(board.marker_corners)
    n_f, n_m = len(names), len(ids)
    nan3 = np.full((n_f, n_m, 3), np.nan)
    out = {
        "error_translation": nan3.copy(),
        "error_rotation": nan3.copy(),
        "error_board_translation": nan3.copy(),
    }
    per_marker = {k: np.full((n_f, n_m), np.nan) for k in PER_MARKER}
    detected = np.zeros((n_f, n_m), np.int8)
    ref_points = np.zeros(n_f, np.int32)
    ref_reproj = np.full(n_f, np.nan)
    board_t, board_r = np.full((n_f, 3), np.nan), np.full((n_f, 3), np.nan)
    views: list[BoardView | None] = []
    stats: list[dict[int, np.ndarray]] = []
    unreadable: list[str] = []
    reference_kind = ""
    steps.start(step, n_f)
    for f, name in enumerate(names):
        gray = load(f)
        if isinstance(gray, str):
            unreadable.append(f"{name}: {gray}")
            views.append(None)
            stats.append({})
            steps.advance()
            continue
        view = view_board(gray, board, camera, det)
        reference_kind = view.reference
        ref_points[f], ref_reproj[f] = view.points, view.reproj_px
        if view.rvec_cv is not None and view.tvec_cv is not None:
            board_r[f], board_t[f] = view.rvec_cv, view.tvec_cv
        views.append(view)
        stats.append({
            m: tag_stats(gray, corners, layout, edge_widths=("edge_width_px",))
            for m, corners in view.markers.items()
        })  # fmt: skip
        steps.advance()
    resolved = None
    if reference is not None:
        resolved = reference.resolve(names, [v.camera_from_board() if v else None for v in views])
    for f, seen in enumerate(views):
        if seen is None:
            continue
        view = seen
        if resolved is not None:  # the external reference stands in for the board's own pose
            pose = resolved.camera_from_board[f]
            view = replace(seen, rvec_cv=tf.matrix_to_rotvec(pose[:3, :3]), tvec_cv=pose[:3, 3])
        for m, marker in enumerate(ids):
            detected[f, m] = marker in view.markers
            err = marker_error(view, board, marker, camera, pnp)
            if err is None:
                continue
            out["error_translation"][f, m] = err.translation_m
            out["error_rotation"][f, m] = err.rotation_rad
            out["error_board_translation"][f, m] = err.board_translation_m
            per_marker["distance"][f, m] = err.distance_m
            per_marker["view_angle"][f, m] = err.view_angle_deg
            per_marker["centre_u"][f, m], per_marker["centre_v"][f, m] = err.centre_px
            per_marker["marker_reproj"][f, m] = err.reproj_px
            for var, stat in IMAGE_STATS.items():
                per_marker[var][f, m] = stats[f][marker][STAT_INDEX[stat]]
    ds = _dataset(
        names, ids, out, per_marker, detected, ref_points, ref_reproj, board_t, board_r,
        board, camera, settings, pnp, unreadable, reference_kind,
    )  # fmt: skip
    return ds if resolved is None else _with_reference(ds, resolved, board_t, board_r)


def _with_reference(
    ds: xr.Dataset, resolved: ResolvedReference, board_t: np.ndarray, board_r: np.ndarray
) -> xr.Dataset:
    """``ds`` with an external reference: its poses as ``board_translation`` / ``_rotation``.

    The board's own poses (``board_t``, m; ``board_r``, rad) move to ``board_points_*``; the
    attributes name the reference (:attr:`ResolvedReference.attrs`) and the points the board's
    own pose was solved from (``board_points``).
    """
    poses = resolved.camera_from_board
    ds = ds.assign(
        board_points_translation=(("frame", "camera_axis"), board_t),
        board_points_rotation=(("frame", "camera_axis"), board_r),
        board_translation=(("frame", "camera_axis"), np.array([p[:3, 3] for p in poses])),
        board_rotation=(
            ("frame", "camera_axis"),
            np.array([tf.matrix_to_rotvec(p[:3, :3]) for p in poses]),
        ),
    )
    for name in ("board_translation", "board_rotation"):
        units, long_name = _ATTRS[name]
        ds[name].attrs.update(units=units, long_name=f"{long_name}: {resolved.attrs['reference']}")
    for name, (units, long_name) in _BOARD_POINTS_ATTRS.items():
        ds[name].attrs.update(units=units, long_name=long_name)
    ds.attrs.update(board_points=ds.attrs["reference"], **resolved.attrs)
    return ds


#: long_name of each coordinate of a photo dataset.
COORD_LONG_NAMES = {
    "frame": "photo file name",
    "marker": "board marker id",
    "camera_axis": "OpenCV camera axis (x right, y down, z forward)",
    "board_axis": "board axis (x along a row, y down a column, z into the board)",
}
#: (units, long_name) of each variable of a photo dataset.
_ATTRS = {
    "error_translation": (
        "m",
        "single-marker position error (estimated - reference), camera frame",
    ),
    "error_rotation": ("rad", "single-marker rotation error rotvec(R_est R_ref^T), camera frame"),
    "error_board_translation": ("m", "single-marker position error in the board frame"),
    "distance": ("m", "distance from the camera centre to the marker centre (reference)"),
    "view_angle": ("degree", "angle between the marker normal and its line of sight"),
    "centre_u": (PIXEL_UNITS, "marker centre's image column (px, reference projection)"),
    "centre_v": (PIXEL_UNITS, "marker centre's image row (px, reference projection)"),
    "marker_reproj": (PIXEL_UNITS, "RMS reprojection error of the single-marker pose (px)"),
    "reference_points": ("1", "number of board points the reference pose was solved from"),
    "reference_reproj": (PIXEL_UNITS, "RMS reprojection error of the board's reference pose (px)"),
    "board_translation": ("m", "board origin in the camera frame (reference pose)"),
    "board_rotation": ("rad", "board rotation vector in the camera frame (reference pose)"),
    "detected": ("1", "marker detected in the photo"),
    "paper_level": ("1", "median linear level of the paper around the marker (of full scale)"),
    "ink_level": ("1", "median linear level of the marker's black border (of full scale)"),
    "edge_width": (PIXEL_UNITS, "10-90 % edge width of the marker's black border (px)"),
}
#: (units, long_name) of the board's own pose where an external reference replaces it.
_BOARD_POINTS_ATTRS = {
    "board_points_translation": ("m", "board origin in the camera frame from its own points"),
    "board_points_rotation": ("rad", "board rotation vector in the camera frame from its points"),
}


def _dataset(
    files, ids, out, per_marker, detected, ref_points, ref_reproj, board_t, board_r,
    board, camera, settings, pnp, unreadable, reference_kind,
) -> xr.Dataset:  # fmt: skip
    """The photo dataset of :func:`measure_photos` (its Returns section)."""
    fm, fma, fmb = (
        ("frame", "marker"),
        ("frame", "marker", "camera_axis"),
        ("frame", "marker", "board_axis"),
    )
    data = {
        "error_translation": (fma, out["error_translation"]),
        "error_rotation": (fma, out["error_rotation"]),
        "error_board_translation": (fmb, out["error_board_translation"]),
        **{k: (fm, v) for k, v in per_marker.items()},
        "detected": (fm, detected),
        "reference_points": (("frame",), ref_points),
        "reference_reproj": (("frame",), ref_reproj),
        "board_translation": (("frame", "camera_axis"), board_t),
        "board_rotation": (("frame", "camera_axis"), board_r),
    }
    coords = {
        "frame": list(files),
        "marker": np.asarray(ids, np.int32),
        "camera_axis": list(CAMERA_AXES),
        "board_axis": list(BOARD_AXES),
    }
    ds = xr.Dataset(data, coords=coords)
    for name, long_name in COORD_LONG_NAMES.items():
        ds[name].attrs["long_name"] = long_name
    ds["marker"].attrs["units"] = "1"
    for name, (units, long_name) in _ATTRS.items():
        ds[name].attrs.update(units=units, long_name=long_name)
    ds["detected"].attrs.update(flag_values=np.array([0, 1], np.int8), flag_meanings="no yes")
    ds.attrs.update(
        Conventions="CF-1.10",
        title="single-marker pose errors against a board's reference, real photos",
        source=PHOTO_SOURCE,
        reference=reference_kind or "none",
        board=repr(to_mapping(board)),
        calibration=repr(to_mapping(camera)),
        detector=repr(to_mapping(settings)),
        pnp=repr(to_mapping(pnp)),
        frames=len(files),
        frames_unreadable=len(unreadable),
        unreadable="; ".join(unreadable),
    )
    return ds


def with_calibration_check(ds: xr.Dataset, check: FileCheck) -> xr.Dataset:
    """``ds`` with its calibration file's check (:data:`CALIBRATION_CHECK`), for its report."""
    return ds.assign_attrs({CALIBRATION_CHECK: repr(check.to_mapping())})


def write_photo_dataset(ds: xr.Dataset, path: str | Path) -> Path:
    """Write a photo dataset as netCDF4 atomically (temporary file + rename); return the path.

    String labels (``frame``, the axes, ``image``) are written as character arrays, the string
    type CF has (a netCDF-4 variable-length string is not CF); plain ``xarray.open_dataset``
    reads them back as indexed labels, so it selects by name. CF's data model wants a
    coordinate variable numeric: ``cfchecks`` warns once per label dimension and finds no
    error (tests/test_board_photos.py).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    encoding = {name: {"dtype": "S1"} for name, c in ds.coords.items() if c.dtype.kind in "US"}
    return atomic_write(
        path,
        lambda tmp: ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=encoding),
    )


__all__ = [
    "BOARD_AXES",
    "CALIBRATION_CHECK",
    "CAMERA_AXES",
    "PHOTO_SOURCE",
    "PHOTO_SUFFIXES",
    "calibrate_photos",
    "measure_photos",
    "named_photo_points",
    "photo_points",
    "photo_files",
    "photo_of",
    "reference_poses",
    "render_photos",
    "simulate_photos",
    "with_calibration_check",
    "write_photo_dataset",
]
