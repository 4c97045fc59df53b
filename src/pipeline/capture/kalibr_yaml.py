"""Kalibr camchain calibration files (``camchain.yaml``, ``camchain-imucam.yaml``).

Kalibr (ethz-asl/kalibr, wiki "YAML formats") writes one mapping per camera of a chain, ``cam0``,
``cam1``, ...; the keys read of the chosen one (``cam0`` unless the path says ``FILE:camN``,
:func:`~simgap.pipeline.capture.calibration.calibration_source`):

- ``camera_model``: ``pinhole`` (the only projection OpenCV has; Kalibr's ``omni``, ``ds`` and
  ``eucm`` are refused, :data:`REFUSED_CAMERA_MODELS`);
- ``intrinsics``: ``[fu, fv, pu, pv]`` (px), OpenCV's ``fx, fy, cx, cy`` (Kalibr projects as
  OpenCV does, ``u = fu x + pu``, pixel centres at integers);
- ``distortion_model`` and ``distortion_coeffs`` (:data:`DISTORTIONS`): ``radtan``
  ``[k1, k2, r1, r2]`` is OpenCV's ``plumb_bob`` ``(k1, k2, p1, p2, k3 = 0)``, ``equidistant``
  ``[k1, k2, k3, k4]`` OpenCV's fisheye (``equidistant``) as it is, ``none`` zeros; ``fov``
  (the FOV / ATAN model) is refused (:data:`REFUSED_DISTORTIONS`);
- ``resolution``: ``[width, height]`` (px).

The chain's other keys (``T_cn_cnm1``, ``T_cam_imu``, ``timeshift_cam_imu``, ``rostopic``,
``cam_overlaps``) describe the cameras' extrinsics and streams, which simgap does not need; they
are ignored. The writer writes one camera, ``cam0``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from simgap.core.config import ConfigError, parse_yaml
from simgap.core.lens import DISTORTION_MODELS
from simgap.core.rig import CameraModel
from simgap.pipeline.capture.calibration import (
    MODEL_ALIASES,
    CalibrationFormat,
    first_line,
    image_side,
    numbers,
    register_format,
)

#: A camera's key in a camchain: ``cam0``, ``cam1``, ...
CAMERA_KEY = re.compile(r"cam[0-9]+")
#: The camera read when the path chooses none.
DEFAULT_CAMERA = "cam0"
#: Kalibr's projection model simgap reads (its ``intrinsics`` are ``[fu, fv, pu, pv]``).
PINHOLE = "pinhole"
#: Kalibr's distortion models simgap reads: name -> (the OpenCV model of
#: :data:`simgap.core.lens.DISTORTION_MODELS`, the number of coefficients Kalibr writes). Kalibr's
#: ``radtan`` is OpenCV's ``plumb_bob`` without k3 (:data:`~.calibration.MODEL_ALIASES`), its
#: ``equidistant`` OpenCV's fisheye; ``none`` has no coefficients.
DISTORTIONS: dict[str, tuple[str, int]] = {
    "radtan": (MODEL_ALIASES["radtan"], 4),
    "equidistant": ("equidistant", 4),
    "none": (MODEL_ALIASES["radtan"], 0),
}
#: Kalibr's projection models without an OpenCV equivalent, and what they are.
REFUSED_CAMERA_MODELS = {
    "omni": "the unified omnidirectional model, intrinsics [xi, fu, fv, pu, pv]",
    "ds": "the double sphere model, intrinsics [xi, alpha, fu, fv, pu, pv]",
    "eucm": "the extended unified model, intrinsics [alpha, beta, fu, fv, pu, pv]",
}
#: Kalibr's distortion models without an OpenCV equivalent, and what they are.
REFUSED_DISTORTIONS = {"fov": "the FOV (ATAN) model, one coefficient w"}


def _can_open(text: str) -> bool:
    """A YAML mapping (no ``%YAML`` directive) with a ``camN`` key holding a mapping."""
    if first_line(text).startswith("%YAML"):
        return False
    try:
        data = parse_yaml(text, "calibration")
    except ConfigError:
        return False
    return isinstance(data, dict) and any(
        CAMERA_KEY.fullmatch(str(key)) and isinstance(value, dict) for key, value in data.items()
    )


def _required(node: dict[str, Any], key: str, where: str, expected: str) -> Any:
    """``node[key]``, or a ConfigError naming the key and what it should hold."""
    if key not in node:
        raise ConfigError(f"{where}{key}: required key is missing ({expected})")
    return node[key]


def _read(path: Path, text: str, width: int | None, height: int | None) -> CameraModel:
    """The camchain's ``cam0`` (:func:`_read_camera`)."""
    return _read_camera(path, text, width, height, DEFAULT_CAMERA)


def _read_camera(
    path: Path, text: str, width: int | None, height: int | None, camera: str
) -> CameraModel:
    """Camera ``camera`` of a Kalibr camchain's text (keys: the module docstring).

    ``width`` / ``height`` (px) are used where the camera has no ``resolution``. Raises
    ConfigError naming the file, the camera's key and what was expected.
    """
    data = parse_yaml(text, str(path))
    cameras = [str(k) for k in data if CAMERA_KEY.fullmatch(str(k))]
    if camera not in data:
        raise ConfigError(
            f"{path}: {camera}: no such camera in the camchain (it has {', '.join(cameras)})"
        )
    node = data[camera]
    where = f"{path}: {camera}."
    if not isinstance(node, dict):
        raise ConfigError(f"{path}: {camera}: expected a mapping of camera keys, got {node!r}")
    model = _required(node, "camera_model", where, PINHOLE)
    if model in REFUSED_CAMERA_MODELS:
        raise ConfigError(
            f"{where}camera_model: expected {PINHOLE}, got {model} ("
            f"{REFUSED_CAMERA_MODELS[model]}), which OpenCV has no model of; recalibrate with "
            f"Kalibr's pinhole-radtan or pinhole-equi"
        )
    if model != PINHOLE:
        raise ConfigError(f"{where}camera_model: expected {PINHOLE}, got {model!r}")
    fu, fv, pu, pv = numbers(
        _required(node, "intrinsics", where, "[fu, fv, pu, pv] in px"), f"{where}intrinsics", 4
    )
    dist_name = _required(node, "distortion_model", where, f"one of {', '.join(DISTORTIONS)}")
    if dist_name in REFUSED_DISTORTIONS:
        raise ConfigError(
            f"{where}distortion_model: expected one of {', '.join(DISTORTIONS)}, got "
            f"{dist_name} ({REFUSED_DISTORTIONS[dist_name]}), which OpenCV has no model of"
        )
    if dist_name not in DISTORTIONS:
        raise ConfigError(
            f"{where}distortion_model: expected one of {', '.join(DISTORTIONS)}, got {dist_name!r}"
        )
    opencv_model, count = DISTORTIONS[dist_name]
    coeffs = numbers(node.get("distortion_coeffs", []), f"{where}distortion_coeffs", count)
    if "resolution" in node:
        w, h = numbers(node["resolution"], f"{where}resolution", 2)
    elif width is None or height is None:
        raise ConfigError(
            f"{where}resolution: required key is missing ([width, height] in px, and no image "
            "size given)"
        )
    else:
        w, h = width, height
    size = [image_side(v, f"{where}resolution[{i}]") for i, v in enumerate((w, h))]
    padded = coeffs + [0.0] * (len(DISTORTION_MODELS[opencv_model]) - count)
    try:  # plausibility relative to the image size (CameraModel's checks)
        return CameraModel(size[0], size[1], fu, fv, pu, pv, tuple(padded), opencv_model)
    except ValueError as exc:
        key = "distortion_coeffs" if str(exc).startswith("distortion") else "intrinsics"
        raise ConfigError(f"{where}{key}: {exc}") from None


def _write(cal: CameraModel) -> str:
    """Kalibr camchain text of ``cal`` as ``cam0`` (``radtan`` or ``equidistant``).

    Raises
    ------
    ValueError
        For a camera Kalibr's pinhole models cannot hold: a ``plumb_bob`` with a k3, or a
        rational, thin-prism or tilted model.
    """
    if cal.distortion_model == "equidistant":
        name, coeffs = "equidistant", list(cal.distortion)
    elif cal.distortion_model == MODEL_ALIASES["radtan"] and cal.distortion[4] == 0.0:
        name, coeffs = "radtan", list(cal.distortion[:4])
    else:
        raise ValueError(
            f"distortion_model: Kalibr's pinhole models hold plumb_bob without k3 (radtan) or "
            f"equidistant, got {cal.distortion_model} {cal.distortion}"
        )
    data = {
        DEFAULT_CAMERA: {
            "camera_model": PINHOLE,
            "intrinsics": [float(cal.fx), float(cal.fy), float(cal.cx), float(cal.cy)],
            "distortion_model": name,
            "distortion_coeffs": [float(v) for v in coeffs],
            "resolution": [int(cal.width), int(cal.height)],
        }
    }
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


KALIBR_YAML = register_format(
    CalibrationFormat("kalibr", _can_open, _read, _write, read_camera=_read_camera)
)
