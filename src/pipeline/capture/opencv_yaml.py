"""OpenCV FileStorage YAML calibration files (``cv::FileStorage``; first line ``%YAML:1.0``).

Keys read: ``camera_matrix`` (an ``!!opencv-matrix`` or a list of 9 numbers),
``distortion_coefficients``, optional ``image_width``, ``image_height``, ``distortion_model``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2

from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel
from simgap.pipeline.capture import calibration as cal_checks
from simgap.pipeline.capture.calibration import CalibrationFormat, register_format


def _can_open(text: str) -> bool:
    """OpenCV writes a ``%YAML:1.0`` (or ``%YAML 1.2``) directive as the first line."""
    return cal_checks.first_line(text).startswith("%YAML")


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
    values = cal_checks.numbers(values, label, count)
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


def _read(path: Path, text: str, width: int | None, height: int | None) -> CameraModel:
    """Read an OpenCV FileStorage YAML file (OpenCV parses the file itself, not ``text``)."""
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
    """The camera model of an open FileStorage (released before returning)."""
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
    return cal_checks.camera_model(where, size[0], size[1], k, dist, model)


def _write(cal: CameraModel) -> str:
    """OpenCV FileStorage YAML text of ``cal``."""
    fs = cv2.FileStorage(".yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("image_width", int(cal.width))
    fs.write("image_height", int(cal.height))
    fs.write("camera_matrix", cal.matrix)
    fs.write("distortion_model", cal.distortion_model)
    fs.write("distortion_coefficients", cal.dist_coeffs.reshape(1, -1))
    return fs.releaseAndGetString()


OPENCV_YAML = register_format(CalibrationFormat("opencv", _can_open, _read, _write))
