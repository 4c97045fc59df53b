"""Real captures in and out: read and validate a capture folder, ingest it, write one.

A capture folder (DESIGN §3) is what a rig operator records on real hardware, and also what
pseudo-real data is written as::

    capture/
      camera.yaml     the calibration the operator believes in: ROS camera_info YAML or OpenCV
                      FileStorage YAML (first line ``%YAML:1.0`` or ``%YAML 1.2``)
      manifest.csv    header image,p,theta_rad (optional columns: repeat, note)
      images/...      8-bit PNG or JPEG frames, as the camera delivered them

:func:`read_capture` validates a folder against a rig, :func:`ingest` turns it into a result
dataset with the same contract as a simulated sweep (variant ``"real"``), and
:func:`write_capture` writes one. Every problem with a folder raises
:class:`~simgap.core.config.ConfigError` naming the file, the row or key, and what was expected; a
frame that cannot be decoded is not an error but a recorded detection failure (and a
:class:`CaptureWarning`).

Examples
--------
>>> from simgap.pipeline.capture import ingest
>>> ds = ingest(Path("captures/run-2024-05-01"))           # doctest: +SKIP
>>> ds.error.sel(axis="ty").mean().item()                   # doctest: +SKIP
"""

from __future__ import annotations

import csv
import io
import json
import math
import platform
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import xarray as xr
import yaml

from simgap.core.atomic import atomic_write
from simgap.core.config import ConfigError, parse_yaml, read_text, to_mapping
from simgap.core.rig import MAX_IMAGE_SIDE_PX, CameraModel, Rig, load_rig
from simgap.pose.detect import DetectorSettings
from simgap.pose.estimate import PnPSettings
from simgap.render.imaging import png_bit_depth, truncation

CALIBRATION_FILE = "camera.yaml"
MANIFEST_FILE = "manifest.csv"
IMAGES_DIR = "images"
REQUIRED_COLUMNS = ("image", "p", "theta_rad")
OPTIONAL_COLUMNS = ("repeat", "note")
#: How far a manifest angle may be from a turntable stop (rad).
THETA_TOLERANCE_RAD = 1e-3
#: Distortion models accepted in a calibration file (Brown-Conrady k1, k2, p1, p2, k3).
DISTORTION_MODELS = ("plumb_bob",)
VARIANT = "real"
DEFAULT_DETECTOR = DetectorSettings()
DEFAULT_PNP = PnPSettings()


class CaptureWarning(UserWarning):
    """A frame of a capture could not be used (it is recorded as a detection failure)."""


@dataclass(frozen=True)
class CaptureFrame:
    """One frame of a capture.

    Attributes
    ----------
    image : Path
        The image file (the capture folder joined with the manifest's path).
    p : int
        Carriage pin hole.
    theta : float
        Turntable angle (rad), snapped to the rig's stop and wrapped to [0, 2 pi).
    repeat : int
        Repeat index (0 when the manifest has no ``repeat`` column).
    note : str
        The manifest's ``note`` ("" when absent).
    """

    image: Path
    p: int
    theta: float
    repeat: int = 0
    note: str = ""


@dataclass
class Capture:
    """A validated capture folder.

    Attributes
    ----------
    folder : Path
        The capture folder.
    calibration : CameraModel
        The calibration of ``camera.yaml`` (what the estimator assumes).
    frames : list of CaptureFrame
        One per manifest row, in manifest order.
    """

    folder: Path
    calibration: CameraModel
    frames: list[CaptureFrame] = field(default_factory=list)


# --- calibration files ------------------------------------------------------------------------


def _is_opencv_yaml(text: str) -> bool:
    first = next((line for line in text.splitlines() if line.strip()), "")
    return first.lstrip().startswith("%YAML")


def _numbers(values: Any, where: str, count: int | None = None) -> list[float]:
    """A list of finite numbers, optionally of a given length."""
    if not isinstance(values, (list, tuple)):
        raise ConfigError(f"{where}: expected a list of numbers, got {values!r}")
    if count is not None and len(values) != count:
        raise ConfigError(f"{where}: expected {count} numbers, got {len(values)}")
    out = []
    for i, v in enumerate(values):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{where}[{i}]: expected a finite number, got {v!r}")
        out.append(float(v))
    return out


def _size(value: Any, where: str) -> int:
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 < value <= MAX_IMAGE_SIDE_PX:
        raise ConfigError(
            f"{where}: expected a positive integer <= {MAX_IMAGE_SIDE_PX} (px), got {value!r}"
        )
    return value


def _camera_model(
    where: str,
    width: Any,
    height: Any,
    k: list[float],
    dist: list[float],
    model: Any,
) -> CameraModel:
    """Validate the parts read from either format and build the camera model."""
    if model is not None and model not in DISTORTION_MODELS:
        raise ConfigError(
            f"{where}distortion_model: expected one of {', '.join(DISTORTION_MODELS)} "
            f"(k1, k2, p1, p2, k3), got {model!r}"
        )
    w = _size(width, f"{where}image_width")
    h = _size(height, f"{where}image_height")
    if abs(k[1]) > 1e-9 or any(abs(v) > 1e-9 for v in k[3:4] + k[6:8]) or abs(k[8] - 1) > 1e-9:
        raise ConfigError(
            f"{where}camera_matrix.data: expected [fx, 0, cx, 0, fy, cy, 0, 0, 1] (no skew), "
            f"got {k}"
        )
    if k[0] <= 0 or k[4] <= 0:
        raise ConfigError(
            f"{where}camera_matrix.data: expected positive focal lengths fx, fy (px), "
            f"got {k[0]}, {k[4]}"
        )
    if len(dist) > 5 and any(v != 0.0 for v in dist[5:]):
        raise ConfigError(
            f"{where}distortion_coefficients.data: expected at most 5 coefficients "
            f"(k1, k2, p1, p2, k3; plumb_bob), got {len(dist)} with non-zero k4 and beyond"
        )
    dist = (dist + [0.0] * 5)[:5]
    try:  # plausibility relative to the image size (CameraModel's checks)
        return CameraModel(w, h, k[0], k[4], k[2], k[5], tuple(dist))
    except ValueError as exc:
        field = str(exc).split(":", 1)[0]
        key = "distortion_coefficients.data" if "distortion" in field else "camera_matrix.data"
        raise ConfigError(f"{where}{key}: {exc}") from None


def _matrix_data(node: Any, where: str, shape: tuple[int, int] | None) -> list[float]:
    """``{rows, cols, data}`` of a ROS matrix entry (``shape``: required rows, cols)."""
    if not isinstance(node, dict):
        raise ConfigError(f"{where}: expected a mapping with rows, cols and data, got {node!r}")
    if "data" not in node:
        raise ConfigError(f"{where}.data: required key is missing (a list of numbers)")
    data = node["data"]
    if shape is not None:
        for key, n in zip(("rows", "cols"), shape, strict=True):
            if key in node and node[key] != n:
                raise ConfigError(f"{where}.{key}: expected {n}, got {node[key]!r}")
        return _numbers(data, f"{where}.data", shape[0] * shape[1])
    values = _numbers(data, f"{where}.data")
    if "rows" in node and "cols" in node:
        rows, cols = node["rows"], node["cols"]
        if not (isinstance(rows, int) and isinstance(cols, int)) or rows * cols != len(values):
            raise ConfigError(
                f"{where}: rows x cols = {rows!r} x {cols!r} does not match {len(values)} numbers"
            )
    return values


def _read_ros(path: Path, text: str, width: int | None, height: int | None) -> CameraModel:
    where = f"{path}: "
    data = parse_yaml(text, str(path))
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a ROS camera_info mapping, got {type(data).__name__}")
    for key in ("camera_matrix", "distortion_coefficients"):
        if key not in data:
            raise ConfigError(f"{where}{key}: required key is missing")
    k = _matrix_data(data["camera_matrix"], f"{where}camera_matrix", (3, 3))
    dist = _matrix_data(data["distortion_coefficients"], f"{where}distortion_coefficients", None)
    w = data.get("image_width", width)
    h = data.get("image_height", height)
    for key, v in (("image_width", w), ("image_height", h)):
        if v is None:
            raise ConfigError(f"{where}{key}: required key is missing (and no image size given)")
    return _camera_model(where, w, h, k, dist, data.get("distortion_model"))


def _fs_matrix(fs: Any, key: str, where: str, count: int | None) -> list[float]:
    """Numbers of an OpenCV FileStorage matrix (``!!opencv-matrix``) or sequence node."""
    node = fs.getNode(key)
    if node.empty():
        raise ConfigError(f"{where}{key}: required key is missing")
    if node.isSeq():
        seq, label = node, f"{where}{key}"
    elif node.isMap() and not node.getNode("data").empty():
        seq, label = node.getNode("data"), f"{where}{key}.data"
    else:
        raise ConfigError(f"{where}{key}: expected an !!opencv-matrix or a list of numbers")
    if not seq.isSeq():
        raise ConfigError(f"{label}: expected a list of numbers")
    values = []
    for i in range(seq.size()):
        item = seq.at(i)
        if not (item.isReal() or item.isInt()):
            raise ConfigError(f"{label}[{i}]: expected a number")
        values.append(item.real())
    values = _numbers(values, label, count)
    if node.isMap():
        rows, cols = node.getNode("rows"), node.getNode("cols")
        if not (rows.empty() or cols.empty()):
            r, c = int(rows.real()), int(cols.real())
            if count == 9 and (r, c) != (3, 3):
                raise ConfigError(f"{where}{key}: expected a 3x3 matrix, got {r}x{c}")
            if r * c != len(values):
                raise ConfigError(
                    f"{where}{key}: rows x cols = {r} x {c} does not match {len(values)} numbers"
                )
    return values


def _read_opencv(path: Path, width: int | None, height: int | None) -> CameraModel:
    import cv2

    try:
        return _read_opencv_nodes(
            cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ), path, width, height
        )
    except ConfigError:
        raise
    except (cv2.error, SystemError, OverflowError, ValueError) as exc:  # truncated: SystemError
        inner = exc.__cause__ or exc.__context__ or exc  # SystemError wraps OpenCV's error
        reason = (str(inner).strip().splitlines() or [""])[-1]
        raise ConfigError(
            f"{path}: not a valid OpenCV FileStorage YAML file (truncated or malformed: {reason})"
        ) from exc


def _read_opencv_nodes(fs: Any, path: Path, width: int | None, height: int | None) -> CameraModel:
    where = f"{path}: "
    try:
        if not fs.isOpened():
            raise ConfigError(f"{path}: cannot be opened as an OpenCV FileStorage YAML file")
        k = _fs_matrix(fs, "camera_matrix", where, 9)
        dist = _fs_matrix(fs, "distortion_coefficients", where, None)
        size = []
        for key, default in (("image_width", width), ("image_height", height)):
            node = fs.getNode(key)
            if node.empty():
                if default is None:
                    raise ConfigError(
                        f"{where}{key}: required key is missing (and no image size given)"
                    )
                size.append(default)
            elif not (node.isInt() or node.isReal()):
                raise ConfigError(f"{where}{key}: expected a positive integer (px)")
            else:
                size.append(node.real())
        node = fs.getNode("distortion_model")
        model = None if node.empty() else node.string()
    finally:
        fs.release()
    return _camera_model(where, size[0], size[1], k, dist, model)


def read_calibration(
    path: Path, width: int | None = None, height: int | None = None
) -> CameraModel:
    """Read a calibration file: ROS camera_info YAML or OpenCV FileStorage YAML.

    Parameters
    ----------
    path : Path
        The file. OpenCV FileStorage is recognised by its first line (``%YAML:1.0`` or
        ``%YAML 1.2``); anything else is read as ROS camera_info YAML (``image_width``,
        ``image_height``, ``camera_matrix{rows, cols, data}``, ``distortion_model: plumb_bob``,
        ``distortion_coefficients{data: [k1, k2, p1, p2, k3]}``; other keys are ignored).
    width, height : int, optional
        Image size (px) used when the file does not give ``image_width`` / ``image_height``
        (OpenCV files often do not). The file's values win when present.

    Returns
    -------
    CameraModel
        Focal lengths and principal point (px), distortion ``(k1, k2, p1, p2, k3)``; shorter
        distortion lists are padded with zeros.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file, the key and what was expected, e.g.
        ``capture/camera.yaml: camera_matrix.data: expected 9 numbers, got 8``; also for a
        distortion model other than ``plumb_bob`` and for a camera matrix with skew.
    """
    path = Path(path)
    text = read_text(path, "calibration file")
    if _is_opencv_yaml(text):
        return _read_opencv(path, width, height)
    return _read_ros(path, text, width, height)


def calibration_to_yaml(cal: CameraModel, fmt: Literal["ros", "opencv"] = "ros") -> str:
    """The text of a calibration file for ``cal``: ROS camera_info or OpenCV FileStorage YAML."""
    k = [float(v) for v in cal.matrix.ravel()]
    dist = [float(v) for v in cal.distortion]
    if fmt == "ros":
        proj = [cal.fx, 0.0, cal.cx, 0.0, 0.0, cal.fy, cal.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        data = {
            "image_width": int(cal.width),
            "image_height": int(cal.height),
            "camera_name": "simgap",
            "camera_matrix": {"rows": 3, "cols": 3, "data": k},
            "distortion_model": "plumb_bob",
            "distortion_coefficients": {"rows": 1, "cols": 5, "data": dist},
            "rectification_matrix": {
                "rows": 3,
                "cols": 3,
                "data": [float(v) for v in np.eye(3).ravel()],
            },
            "projection_matrix": {"rows": 3, "cols": 4, "data": [float(v) for v in proj]},
        }
        return yaml.safe_dump(data, sort_keys=False)
    if fmt == "opencv":
        import cv2

        fs = cv2.FileStorage(".yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
        fs.write("image_width", int(cal.width))
        fs.write("image_height", int(cal.height))
        fs.write("camera_matrix", cal.matrix)
        fs.write("distortion_model", "plumb_bob")
        fs.write("distortion_coefficients", cal.dist_coeffs.reshape(1, 5))
        return fs.releaseAndGetString()
    raise ValueError(f"fmt: expected 'ros' or 'opencv', got {fmt!r}")


# --- manifest and folder ----------------------------------------------------------------------


def _holes(ps: Sequence[int]) -> str:
    ps = sorted(ps)
    if ps == list(range(ps[0], ps[-1] + 1)):
        return f"{ps[0]}..{ps[-1]}"
    return ", ".join(map(str, ps))


def snap_theta(theta: float, rig: Rig) -> float | None:
    """The rig's turntable stop within :data:`THETA_TOLERANCE_RAD` of ``theta`` (rad), or None."""
    stops = rig.grid.theta
    wrapped = math.fmod(theta, 2 * math.pi) % (2 * math.pi)
    dist = np.abs((wrapped - stops + math.pi) % (2 * math.pi) - math.pi)
    i = int(np.argmin(dist))
    return float(stops[i]) if dist[i] <= THETA_TOLERANCE_RAD else None


def turntable_stop(value: Any, rig: Rig, where: str) -> float:
    """The rig's turntable stop (rad) for an angle given as text or number (rad).

    Raises
    ------
    simgap.core.config.ConfigError
        ``where`` and the expected stops when ``value`` is not within
        :data:`THETA_TOLERANCE_RAD` of one.
    """
    try:
        theta = float(value)
    except (TypeError, ValueError):
        theta = math.nan
    stop = snap_theta(theta, rig) if math.isfinite(theta) else None
    if stop is None:
        step = rig.grid.theta_step_deg
        raise ConfigError(
            f"{where}: expected a turntable stop (a multiple of {step:g} deg = "
            f"{math.radians(step):.6f} rad, within {THETA_TOLERANCE_RAD:g} rad), got {value!r}"
        )
    return stop


def _parse_int(text: str) -> int | None:
    try:
        return int(text)
    except ValueError:
        try:
            value = float(text)
        except ValueError:
            return None
        return int(value) if value.is_integer() else None


class _CsvRows:
    """A ``csv.reader`` whose format errors (e.g. a field over the size limit) are ConfigErrors."""

    def __init__(self, path: Path, reader: Any) -> None:
        self.path, self.reader = path, reader

    @property
    def line_num(self) -> int:
        """Current line of the CSV text (1-based)."""
        return self.reader.line_num

    def __iter__(self) -> _CsvRows:
        return self

    def __next__(self) -> list[str]:
        try:
            return next(self.reader)
        except csv.Error as exc:
            raise ConfigError(
                f"{self.path}: line {self.reader.line_num}: not valid CSV ({exc})"
            ) from exc


def _image_path(folder: Path, name: str, where: str) -> Path:
    """The image of a manifest row, confined to the capture folder.

    Raises
    ------
    simgap.core.config.ConfigError
        For an empty, absolute or ``..`` path, one that resolves outside the folder (through a
        symbolic link), a missing or unreadable file, or a 16-bit PNG (simgap reads 8-bit frames,
        DESIGN §3: the scaling of 16-bit data depends on the sensor's bit depth, so it is not
        guessed; convert the frames to 8 bits first).
    """
    if not name:
        raise ConfigError(f"{where}: image: expected a path, got an empty field")
    rel = Path(name)
    if "\x00" in name or rel.is_absolute() or ".." in rel.parts:
        raise ConfigError(
            f"{where}: image: expected a path inside the capture folder (relative, without "
            f"'..'), got {name!r}"
        )
    image = folder / rel
    root = folder.resolve()
    if not image.resolve().is_relative_to(root):
        raise ConfigError(
            f"{where}: image: {name!r} resolves to {image.resolve()}, outside the capture "
            f"folder {root} (a symbolic link?); expected a file inside the folder"
        )
    if not image.is_file():
        raise ConfigError(f"{where}: image: file not found: {image}")
    try:
        with open(image, "rb") as handle:
            head = handle.read(32)
    except OSError as exc:
        raise ConfigError(f"{where}: image: cannot read {image}: {exc.strerror or exc}") from exc
    if png_bit_depth(head) == 16:
        raise ConfigError(
            f"{where}: image: {image} is a 16-bit PNG; expected 8-bit PNG or JPEG frames "
            "(the scaling to 8 bits depends on the sensor's bit depth: convert the frames first)"
        )
    return image


def _read_manifest(path: Path, folder: Path, rig: Rig) -> list[CaptureFrame]:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read manifest: {exc}") from exc
    reader = _CsvRows(path, csv.reader(io.StringIO(text)))
    header = next(reader, None)
    if header is None:
        raise ConfigError(
            f"{path}: empty manifest; expected the header {','.join(REQUIRED_COLUMNS)}"
        )
    header = [h.strip() for h in header]
    allowed = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
    for name in header:
        if name not in allowed:
            raise ConfigError(
                f"{path}: column {name!r}: unknown; allowed columns: {', '.join(allowed)}"
            )
        if header.count(name) > 1:
            raise ConfigError(f"{path}: column {name!r}: appears more than once")
    for name in REQUIRED_COLUMNS:
        if name not in header:
            raise ConfigError(
                f"{path}: header: missing column {name!r} "
                f"(required: {', '.join(REQUIRED_COLUMNS)}; "
                f"optional: {', '.join(OPTIONAL_COLUMNS)})"
            )
    frames: list[CaptureFrame] = []
    seen: dict[tuple[int, float, int], int] = {}
    row = 0
    for cells in reader:
        if not any(c.strip() for c in cells):
            continue
        row += 1
        where = f"{path}: row {row} (line {reader.line_num})"
        if len(cells) != len(header):
            raise ConfigError(f"{where}: expected {len(header)} fields, got {len(cells)}")
        rec = {name: c.strip() for name, c in zip(header, cells, strict=True)}
        p = _parse_int(rec["p"])
        if p is None or p not in rig.grid.p:
            raise ConfigError(
                f"{where}: p: expected a pin hole of the rig ({_holes(rig.grid.p)}), "
                f"got {rec['p']!r}"
            )
        theta = turntable_stop(rec["theta_rad"], rig, f"{where}: theta_rad")
        repeat = _parse_int(rec["repeat"]) if "repeat" in rec else 0
        if repeat is None or repeat < 0:
            raise ConfigError(f"{where}: repeat: expected an integer >= 0, got {rec['repeat']!r}")
        image = _image_path(folder, rec["image"], where)
        key = (p, round(theta, 9), repeat)
        if key in seen:
            raise ConfigError(
                f"{where}: duplicate of row {seen[key]} (p={p}, theta={math.degrees(theta):g} deg, "
                f"repeat={repeat})"
            )
        seen[key] = row
        frames.append(CaptureFrame(image, p, theta, repeat, rec.get("note", "")))
    if not frames:
        raise ConfigError(f"{path}: no frames (the manifest has a header but no rows)")
    return frames


def _read_image(path: Path) -> np.ndarray | None:
    """An image as 8-bit BGR, or None when it cannot be read, is truncated or cannot be decoded.

    Truncation is checked on the bytes (:func:`simgap.render.imaging.truncation`: a PNG must end
    with its IEND chunk, a JPEG with the end-of-image marker), because decoders return a
    grey-filled image for a truncated JPEG with only a warning on stderr.
    """
    import cv2

    try:
        data = path.read_bytes()
    except OSError:
        return None
    if truncation(data) is not None:
        return None
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    except cv2.error:
        return None
    return img if img is not None and img.size > 0 else None


def read_capture(folder: Path, rig: Rig) -> Capture:
    """Read and validate a capture folder against a rig.

    Parameters
    ----------
    folder : Path
        The capture folder (``camera.yaml``, ``manifest.csv``, images).
    rig : Rig
        The rig: its pin holes and turntable stops are the valid ``p`` and ``theta_rad``.

    Returns
    -------
    Capture
        The calibration and the frames; each frame's ``theta`` is the rig's stop (rad, in
        [0, 2 pi)) nearest to the manifest's value.

    Raises
    ------
    simgap.core.config.ConfigError
        If the folder, ``camera.yaml``, ``manifest.csv`` or an image is missing; the manifest
        has an unknown or missing column, a ``p`` that is not a pin hole, a ``theta_rad`` that
        is not a turntable stop (within :data:`THETA_TOLERANCE_RAD`), a bad ``repeat`` or a
        duplicate (p, theta, repeat); the calibration is invalid, or its image size differs from
        the images' (checked on the first image that can be decoded); or no image can be
        decoded. Messages name the file and the manifest row.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"{folder}: capture folder not found")
    cal_path, manifest_path = folder / CALIBRATION_FILE, folder / MANIFEST_FILE
    for path, what in ((cal_path, "calibration"), (manifest_path, "manifest")):
        if not path.is_file():
            raise ConfigError(
                f"{path}: {what} file not found (a capture folder needs {CALIBRATION_FILE}, "
                f"{MANIFEST_FILE} and the images)"
            )
    frames = _read_manifest(manifest_path, folder, rig)
    first = next(((f, img) for f in frames if (img := _read_image(f.image)) is not None), None)
    if first is None:
        raise ConfigError(f"{folder}: none of the {len(frames)} images can be decoded")
    frame, img = first
    h, w = img.shape[:2]
    cal = read_calibration(cal_path, w, h)
    if (cal.width, cal.height) != (w, h):
        raise ConfigError(
            f"{cal_path}: image size {cal.width}x{cal.height} differs from the images' "
            f"{w}x{h} ({frame.image})"
        )
    return Capture(folder, cal, frames)


# --- ingest -----------------------------------------------------------------------------------


def _progress(show: bool):
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        disable=not show,
    )


def ingest(
    folder: Path,
    rig: Rig | None = None,
    detector: DetectorSettings = DEFAULT_DETECTOR,
    pnp: PnPSettings = DEFAULT_PNP,
    calibration: CameraModel | None = None,
    show_progress: bool = False,
) -> xr.Dataset:
    """Detect markers and estimate poses in a capture; return the result dataset.

    The dataset follows the contract of a simulated sweep (DESIGN §3): variant ``"real"``;
    coords ``p``, ``theta`` and ``repeat`` are the sorted unique values of the manifest,
    ``tag`` the rig's tag ids; configurations absent from the manifest are not detected (NaN).
    Poses are estimated with the capture's calibration, exactly as
    :func:`simgap.pipeline.sweep.measure_tags` does for renders (image evidence included).

    Parameters
    ----------
    folder : Path
        The capture folder.
    rig : Rig, optional
        Ground truth (expected poses, visibility, grid); default: the packaged rig.
    detector : DetectorSettings
        ArUco detector settings.
    pnp : PnPSettings
        PnP settings.
    calibration : CameraModel, optional
        Estimate with this calibration instead of ``camera.yaml`` (e.g. to test a corrected
        calibration on real corners); recorded in the attrs.
    show_progress : bool
        Show a progress bar.

    Returns
    -------
    xarray.Dataset
        Attrs: ``source = "capture"``, ``capture_dir``, ``calibration_yaml`` (the calibration
        used, as a CameraModel mapping: px, dimensionless distortion), ``calibration_file`` (the
        text of ``camera.yaml``), ``detector``, ``pnp``, ``frames``, ``frames_unreadable``
        (count of frames that could not be decoded or had the wrong size, each recorded as
        not detected) and ``frames_failed`` (JSON list of their paths), versions.

    Raises
    ------
    simgap.core.config.ConfigError
        As :func:`read_capture`.

    Warns
    -----
    CaptureWarning
        For each frame that cannot be decoded or has the wrong size.
    """
    import cv2

    from simgap.effects.state import EstimationState, VariantState
    from simgap.pipeline.sweep import measure_tags
    from simgap.pose.detect import Detector
    from simgap.results.dataset import build_dataset, empty_results

    rig = rig or load_rig()
    cap = read_capture(folder, rig)
    cal = calibration or cap.calibration
    state = VariantState(estimation=EstimationState(calibration=cal, detector=detector, pnp=pnp))
    det = Detector(detector)
    tags = rig.tags.ids
    ps = sorted({f.p for f in cap.frames})
    thetas = sorted({f.theta for f in cap.frames})
    repeats = sorted({f.repeat for f in cap.frames})
    shape = (1, len(repeats), len(tags), len(ps), len(thetas))
    res = empty_results(shape)
    failed: list[str] = []
    with _progress(show_progress) as bar:
        task = bar.add_task(f"ingest {cap.folder.name}", total=len(cap.frames))
        for frame in cap.frames:
            bar.advance(task)
            img = _read_image(frame.image)
            if img is None or img.shape[:2] != (cal.height, cal.width):
                why = (
                    "cannot be decoded"
                    if img is None
                    else f"is {img.shape[1]}x{img.shape[0]}, expected {cal.width}x{cal.height}"
                )
                warnings.warn(
                    f"{frame.image}: frame {why}; recorded as not detected",
                    CaptureWarning,
                    stacklevel=2,
                )
                failed.append(str(frame.image))
                continue
            gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
            found, rejected = det.detect_with_rejected(gray)
            out = measure_tags(
                rig, state, tags, gray, (0, 0), found, rejected, frame.p, frame.theta
            )
            idx = (0, repeats.index(frame.repeat), slice(None), ps.index(frame.p))
            idx = idx + (thetas.index(frame.theta),)
            for k, v in out.arrays().items():
                res[k][idx] = v
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in thetas] for p in ps] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in thetas] for p in ps] for t in tags])
    attrs = {
        "title": f"simgap result: capture {cap.folder.name}",
        "source": "capture",
        "capture_dir": str(cap.folder.resolve()),
        "calibration_yaml": yaml.safe_dump(to_mapping(cal), sort_keys=False),
        "calibration_source": "override" if calibration is not None else CALIBRATION_FILE,
        "calibration_file": (cap.folder / CALIBRATION_FILE).read_text(),
        "rig_yaml": yaml.safe_dump(to_mapping(rig), sort_keys=False),
        "repeats": str(len(repeats)),
        "frames": len(cap.frames),
        "frames_unreadable": len(failed),
        "frames_failed": json.dumps(failed),
        "detector": json.dumps({VARIANT: f"{detector}"}),
        "pnp": json.dumps({VARIANT: f"{pnp}"}),
        "simgap_version": _version(),
        "opencv_version": cv2.__version__,
        "numpy_version": np.__version__,
        "xarray_version": xr.__version__,
        "python_version": platform.python_version(),
        "conventions": "DESIGN.md §1: global frame = eyepoint (+X right, +Y forward, +Z up)",
    }
    return build_dataset(
        tags,
        tuple(ps),
        np.asarray(thetas),
        expected,
        visible,
        res,
        variants=(VARIANT,),
        repeats=tuple(repeats),
        attrs=attrs,
    )


def _version() -> str:
    import simgap

    return simgap.__version__


# --- writing ----------------------------------------------------------------------------------


def _write_bytes(path: Path, data: bytes) -> None:
    """Write a file atomically (:func:`simgap.core.atomic.atomic_write`)."""
    atomic_write(path, data)


def image_name(p: int, theta: float, repeat: int = 0, ext: str = "png") -> str:
    """``pXX_tYYY[_rN].ext``: pin hole, angle in whole degrees (``012p5`` if fractional)."""
    deg = math.degrees(theta) % 360.0
    if abs(deg - round(deg)) < 1e-6:
        t = f"{round(deg) % 360:03d}"
    else:
        t = f"{deg:07.3f}".rstrip("0").replace(".", "p")
    suffix = f"_r{repeat}" if repeat else ""
    return f"p{p:02d}_t{t}{suffix}.{ext}"


def write_capture(
    folder: Path,
    frames: Iterable[tuple],
    calibration: CameraModel,
    fmt: Literal["ros", "opencv"] = "ros",
    image_format: Literal["png", "jpg"] = "png",
    jpeg_quality: int = 95,
) -> Path:
    """Write a capture folder: ``camera.yaml``, ``images/``, ``manifest.csv``.

    Every file is written atomically (temporary file + rename); the manifest last, so a folder
    with a manifest is complete.

    Parameters
    ----------
    folder : Path
        The folder to write (created if needed; files of the same name are replaced).
    frames : iterable of (p, theta, repeat, rgb8) or (p, theta, repeat, rgb8, note)
        Pin hole (int), turntable angle (rad), repeat index (int >= 0), the frame as an 8-bit
        RGB array (H, W, 3) of the calibration's size (or a grey (H, W) array), and optionally a
        note for the manifest. Consumed once, so a generator keeps only one frame in memory.
        Images are named ``images/pXX_tYYY[_rN].png`` (``_rN`` for repeats other than 0).
    calibration : CameraModel
        Written as ``camera.yaml`` (px; distortion k1, k2, p1, p2, k3).
    fmt : {"ros", "opencv"}
        ``camera.yaml`` as ROS camera_info YAML or OpenCV FileStorage YAML.
    image_format : {"png", "jpg"}
        Lossless PNG or JPEG.
    jpeg_quality : int
        JPEG quality, 0..100.

    Returns
    -------
    Path
        The manifest's path.

    Raises
    ------
    ValueError
        For a frame that is not 8-bit, of the wrong size, a negative p or repeat, a non-finite
        theta or a repeated image name.
    """
    import cv2

    if fmt not in ("ros", "opencv"):
        raise ValueError(f"fmt: expected 'ros' or 'opencv', got {fmt!r}")
    if image_format not in ("png", "jpg"):
        raise ValueError(f"image_format: expected 'png' or 'jpg', got {image_format!r}")
    if not 0 <= jpeg_quality <= 100:
        raise ValueError(f"jpeg_quality: expected 0..100, got {jpeg_quality}")
    folder = Path(folder)
    (folder / IMAGES_DIR).mkdir(parents=True, exist_ok=True)
    _write_bytes(folder / CALIBRATION_FILE, calibration_to_yaml(calibration, fmt).encode())
    params = (
        [cv2.IMWRITE_PNG_COMPRESSION, 1]
        if image_format == "png"
        else [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)]
    )
    rows: list[tuple[str, int, float, int, str]] = []
    names: set[str] = set()
    for item in frames:
        if len(item) not in (4, 5):
            raise ValueError(
                f"frames: expected (p, theta, repeat, rgb8[, note]) tuples, got {len(item)} items"
            )
        p, theta, repeat, rgb8 = item[:4]
        note = str(item[4]) if len(item) == 5 else ""
        p, repeat, theta = int(p), int(repeat), float(theta)
        if p < 0 or repeat < 0 or not math.isfinite(theta):
            raise ValueError(f"frame (p={p}, theta={theta}, repeat={repeat}): invalid values")
        img = np.asarray(rgb8)
        size = (calibration.height, calibration.width)
        if img.dtype != np.uint8 or img.shape[:2] != size or img.ndim not in (2, 3):
            raise ValueError(
                f"frame (p={p}, theta={theta:.6f}, repeat={repeat}): expected uint8 "
                f"{size[0]}x{size[1]}(x3), got {img.dtype} {img.shape}"
            )
        name = f"{IMAGES_DIR}/{image_name(p, theta, repeat, image_format)}"
        if name in names:
            raise ValueError(f"{name}: two frames with the same p, theta and repeat")
        names.add(name)
        bgr = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
        ok, buf = cv2.imencode(f".{image_format}", bgr, params)
        if not ok:
            raise OSError(f"{folder / name}: could not encode the image")
        _write_bytes(folder / name, buf.tobytes())
        rows.append((name, p, theta % (2 * math.pi), repeat, note))
    header = list(REQUIRED_COLUMNS)
    with_repeat = any(r[3] for r in rows)
    with_note = any(r[4] for r in rows)
    header += ["repeat"] if with_repeat else []
    header += ["note"] if with_note else []
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header)
    for name, p, theta, repeat, note in rows:
        line = [name, p, f"{theta:.9f}"] + ([repeat] if with_repeat else [])
        writer.writerow(line + ([note] if with_note else []))
    manifest = folder / MANIFEST_FILE
    _write_bytes(manifest, out.getvalue().encode())
    return manifest
