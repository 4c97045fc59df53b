"""ROS camera_info YAML calibration files (``sensor_msgs/CameraInfo`` as YAML).

Keys read: ``image_width``, ``image_height``, ``camera_matrix{rows, cols, data}``,
``distortion_model`` (``plumb_bob``, ``rational_polynomial``, ``equidistant``, ... :
:mod:`simgap.core.lens`), ``distortion_coefficients{data: [...]}``; other keys are ignored.
Any file that no other format opens is read as this format (the registry's catch-all).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from simgap.core.config import ConfigError, parse_yaml
from simgap.core.rig import CameraModel
from simgap.pipeline.capture.calibration import (
    CalibrationFormat,
    camera_model,
    first_line,
    numbers,
    register_format,
)


def _can_open(text: str) -> bool:
    """Anything without a ``%YAML`` directive line (ROS writes plain YAML)."""
    return not first_line(text).startswith("%YAML")


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
        return numbers(data, f"{where}.data", shape[0] * shape[1])
    values = numbers(data, f"{where}.data")
    if "rows" in node and "cols" in node:
        rows, cols = node["rows"], node["cols"]
        if not (isinstance(rows, int) and isinstance(cols, int)) or rows * cols != len(values):
            raise ConfigError(
                f"{where}: rows x cols = {rows!r} x {cols!r} does not match {len(values)} numbers"
            )
    return values


def _read(path: Path, text: str, width: int | None, height: int | None) -> CameraModel:
    """Read ROS camera_info YAML text (keys: see the module docstring)."""
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
    return camera_model(where, w, h, k, dist, data.get("distortion_model"))


def _write(cal: CameraModel) -> str:
    """ROS camera_info YAML text of ``cal`` (identity rectification, projection = K | 0)."""
    k = [float(v) for v in cal.matrix.ravel()]
    dist = [float(v) for v in cal.distortion]
    proj = [cal.fx, 0.0, cal.cx, 0.0, 0.0, cal.fy, cal.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    data = {
        "image_width": int(cal.width),
        "image_height": int(cal.height),
        "camera_name": "simgap",
        "camera_matrix": {"rows": 3, "cols": 3, "data": k},
        "distortion_model": cal.distortion_model,
        "distortion_coefficients": {"rows": 1, "cols": len(dist), "data": dist},
        "rectification_matrix": {
            "rows": 3,
            "cols": 3,
            "data": [float(v) for v in np.eye(3).ravel()],
        },
        "projection_matrix": {"rows": 3, "cols": 4, "data": [float(v) for v in proj]},
    }
    return yaml.safe_dump(data, sort_keys=False)


ROS_YAML = register_format(CalibrationFormat("ros", _can_open, _read, _write, catch_all=True))
