"""Calibration files: a registry of formats, each a reader, a writer and a can-open check.

Like xarray's backends, every format is a small :class:`CalibrationFormat` registered under its name
(:data:`CALIBRATION_FORMATS`); :func:`read_calibration` asks each format whether it can open a
file's text, in registration order with the catch-all formats (:attr:`CalibrationFormat.catch_all`)
last, and reads it with the first that can; :func:`calibration_to_yaml` writes with the named one.
The formats of docs/conventions.md §3 are :mod:`~simgap.pipeline.capture.opencv_yaml` (OpenCV
FileStorage YAML, recognised by its ``%YAML`` first line),
:mod:`~simgap.pipeline.capture.kalibr_yaml` (Kalibr camchain YAML, recognised by its ``cam0``,
``cam1``, ... cameras) and :mod:`~simgap.pipeline.capture.ros_yaml` (ROS camera_info YAML, the
catch-all); this module holds the checks they share.

A file of several cameras (a Kalibr camchain) is read for its first, ``cam0``; the path
``FILE:camN`` (:func:`calibration_source`) chooses camera N wherever a calibration file is named
(``--calibration``, ``rig.camera.calibration``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simgap.core.config import ConfigError, read_text
from simgap.core.lens import DISTORTION_MODELS, MODEL_OF_COUNT
from simgap.core.rig import MAX_IMAGE_SIDE_PX, CameraModel

#: Other names calibration tools write for a model of :data:`simgap.core.lens.DISTORTION_MODELS`
#: (Kalibr and camodocal: ``radtan``, ``fisheye``; OpenCV's own flag names).
MODEL_ALIASES = {"radtan": "plumb_bob", "fisheye": "equidistant", "kannala_brandt": "equidistant"}
#: Tolerance on the fixed zeros and one of a camera matrix ``[fx, 0, cx, 0, fy, cy, 0, 0, 1]``.
MATRIX_TOLERANCE = 1e-9


@dataclass(frozen=True)
class CalibrationFormat:
    """One calibration file format.

    Attributes
    ----------
    name : str
        Registry key (the ``fmt`` of :func:`calibration_to_yaml`).
    can_open : callable
        ``can_open(text) -> bool``: whether the file's text is in this format.
    read : callable
        ``read(path, text, width, height) -> CameraModel``; ``width``/``height`` (px) are used
        when the file does not give the image size. Raises ConfigError naming the file and key.
    write : callable
        ``write(calibration) -> str``: the file's text. Raises ValueError for a camera the
        format cannot hold.
    catch_all : bool
        Whether ``can_open`` takes any text (ROS camera_info YAML): such a format is asked after
        every other, whatever the registration order.
    read_camera : callable or None
        For a format of several cameras in one file: ``read_camera(path, text, width, height,
        camera) -> CameraModel`` reads the camera named ``camera`` (``FILE:camera``,
        :func:`calibration_source`); None for a format of one camera, which refuses a choice.
    """

    name: str
    can_open: Callable[[str], bool]
    read: Callable[[Path, str, int | None, int | None], CameraModel]
    write: Callable[[CameraModel], str]
    catch_all: bool = False
    read_camera: Callable[[Path, str, int | None, int | None, str], CameraModel] | None = None


CALIBRATION_FORMATS: dict[str, CalibrationFormat] = {}
#: ``FILE:camN``: camera N of a file of several cameras (Kalibr's names, ``cam0``, ``cam1``, ...).
CAMERA_SUFFIX = re.compile(r"(?P<file>.+):(?P<camera>cam[0-9]+)")


def register_format(fmt: CalibrationFormat) -> CalibrationFormat:
    """Add a format to :data:`CALIBRATION_FORMATS` (asked after those registered before it)."""
    if fmt.name in CALIBRATION_FORMATS:
        raise ValueError(f"calibration format {fmt.name!r} registered twice")
    CALIBRATION_FORMATS[fmt.name] = fmt
    return fmt


def formats_in_order() -> Iterator[CalibrationFormat]:
    """The registered formats in the order :func:`read_calibration` asks them: catch-alls last."""
    yield from (f for f in CALIBRATION_FORMATS.values() if not f.catch_all)
    yield from (f for f in CALIBRATION_FORMATS.values() if f.catch_all)


def calibration_source(path: str | Path) -> tuple[Path, str | None]:
    """The file a calibration path names, and the camera it chooses (None: the file's first).

    A path that is a file is that file. Otherwise a path ending ``:camN`` (:data:`CAMERA_SUFFIX`)
    whose part before the colon is a file names camera N of it: ``camchain.yaml:cam1``. Any other
    path is returned as it is (reading it then says it is not found).
    """
    path = Path(path)
    match = CAMERA_SUFFIX.fullmatch(str(path))
    if path.is_file() or match is None or not Path(match["file"]).is_file():
        return path, None
    return Path(match["file"]), match["camera"]


def first_line(text: str) -> str:
    """The first non-blank line of ``text``, without leading spaces ("" for a blank text)."""
    return next((line for line in text.splitlines() if line.strip()), "").lstrip()


def numbers(values: Any, where: str, count: int | None = None) -> list[float]:
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


def image_side(value: Any, where: str) -> int:
    """An image side (px): a positive integer up to ``MAX_IMAGE_SIDE_PX`` (integral floats too)."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 < value <= MAX_IMAGE_SIDE_PX:
        raise ConfigError(
            f"{where}: expected a positive integer <= {MAX_IMAGE_SIDE_PX} (px), got {value!r}"
        )
    return value


def distortion_model(where: str, model: Any, dist: list[float]) -> tuple[str, list[float]]:
    """The distortion model a file names (or its coefficient count implies) and its coefficients.

    A named model (:data:`simgap.core.lens.DISTORTION_MODELS`, or an alias of
    :data:`MODEL_ALIASES`) takes exactly its count, a short list padded with zeros. Without a
    name (OpenCV files write none), the count says it as OpenCV reads it: up to 5 ``plumb_bob``,
    8 ``rational_polynomial``, 12 ``thin_prism``, 14 ``tilted``; coefficients beyond the fifth
    that are all 0 mean ``plumb_bob``.
    """
    if model is not None:
        name = MODEL_ALIASES.get(str(model), str(model))
        if name not in DISTORTION_MODELS:
            raise ConfigError(
                f"{where}distortion_model: expected one of {', '.join(DISTORTION_MODELS)}, "
                f"got {model!r}"
            )
        count = len(DISTORTION_MODELS[name])
        if len(dist) > count and any(v != 0.0 for v in dist[count:]):
            raise ConfigError(
                f"{where}distortion_coefficients.data: expected the {count} coefficients of "
                f"{name} ({', '.join(DISTORTION_MODELS[name])}), got {len(dist)}"
            )
        return name, (dist + [0.0] * count)[:count]
    if len(dist) <= 5 or not any(v != 0.0 for v in dist[5:]):
        return "plumb_bob", (dist + [0.0] * 5)[:5]
    if len(dist) not in MODEL_OF_COUNT:
        raise ConfigError(
            f"{where}distortion_coefficients.data: expected 4, 5, 8, 12 or 14 coefficients "
            f"(OpenCV's models), got {len(dist)}"
        )
    return MODEL_OF_COUNT[len(dist)], dist


def camera_model(
    where: str,
    width: Any,
    height: Any,
    k: list[float],
    dist: list[float],
    model: Any,
) -> CameraModel:
    """Validate the parts read from either format and build the camera model."""
    name, dist = distortion_model(where, model, dist)
    w = image_side(width, f"{where}image_width")
    h = image_side(height, f"{where}image_height")
    if (
        abs(k[1]) > MATRIX_TOLERANCE
        or any(abs(v) > MATRIX_TOLERANCE for v in k[3:4] + k[6:8])
        or abs(k[8] - 1) > MATRIX_TOLERANCE
    ):
        raise ConfigError(
            f"{where}camera_matrix.data: expected [fx, 0, cx, 0, fy, cy, 0, 0, 1] (no skew), "
            f"got {k}"
        )
    if k[0] <= 0 or k[4] <= 0:
        raise ConfigError(
            f"{where}camera_matrix.data: expected positive focal lengths fx, fy (px), "
            f"got {k[0]}, {k[4]}"
        )
    try:  # plausibility relative to the image size (CameraModel's checks)
        return CameraModel(w, h, k[0], k[4], k[2], k[5], tuple(dist), name)
    except ValueError as exc:
        field = str(exc).split(":", 1)[0]
        key = "distortion_coefficients.data" if "distortion" in field else "camera_matrix.data"
        raise ConfigError(f"{where}{key}: {exc}") from None


def read_calibration(
    path: Path, width: int | None = None, height: int | None = None
) -> CameraModel:
    """Read a calibration file: ROS camera_info, OpenCV FileStorage or Kalibr camchain YAML.

    Parameters
    ----------
    path : Path
        The file. OpenCV FileStorage is recognised by its first line (``%YAML:1.0`` or
        ``%YAML 1.2``), a Kalibr camchain by its top-level ``cam0``, ``cam1``, ... mappings
        (:mod:`~simgap.pipeline.capture.kalibr_yaml`; its ``cam0``, or camera N given as
        ``FILE:camN``, :func:`calibration_source`); anything else is read as ROS camera_info
        YAML (``image_width``, ``image_height``, ``camera_matrix{rows, cols, data}``,
        ``distortion_model`` (any of :data:`simgap.core.lens.DISTORTION_MODELS`, e.g.
        ``plumb_bob``, ``rational_polynomial``, ``equidistant``),
        ``distortion_coefficients{data: [...]}``; other keys are ignored).
    width, height : int, optional
        Image size (px) used when the file does not give ``image_width`` / ``image_height``
        (OpenCV files often do not). The file's values win when present.

    Returns
    -------
    CameraModel
        Focal lengths and principal point (px), the distortion model and its coefficients
        (:func:`distortion_model`).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file, the key and what was expected, e.g.
        ``capture/camera.yaml: camera_matrix.data: expected 9 numbers, got 8``; also for a
        distortion model OpenCV does not have and for a camera matrix with skew; for a camera
        chosen (``FILE:camN``) in a format of one camera or absent from the file.
    """
    path, camera = calibration_source(path)
    text = read_text(path, "calibration file")
    for fmt in formats_in_order():
        if not fmt.can_open(text):
            continue
        if camera is None:
            return fmt.read(path, text, width, height)
        if fmt.read_camera is None:
            raise ConfigError(
                f"{path}: :{camera}: expected a file of several cameras (a Kalibr camchain) to "
                f"choose a camera from, got a {fmt.name} calibration file of one camera"
            )
        return fmt.read_camera(path, text, width, height, camera)
    raise ConfigError(
        f"{path}: not a calibration file of a known format (one of "
        f"{', '.join(CALIBRATION_FORMATS)})"
    )


def calibration_to_yaml(cal: CameraModel, fmt: str = "ros") -> str:
    """The text of a calibration file for ``cal`` in format ``fmt``.

    ``fmt`` is a :data:`CALIBRATION_FORMATS` name: ``"ros"``, ``"opencv"`` or ``"kalibr"``.

    Raises
    ------
    ValueError
        For a format name that is not in :data:`CALIBRATION_FORMATS`, or a camera the format
        cannot hold (Kalibr: a ``plumb_bob`` k3, a rational, thin-prism or tilted model).
    """
    return calibration_format(fmt).write(cal)


def calibration_format(name: str) -> CalibrationFormat:
    """The registered format called ``name``.

    Raises
    ------
    ValueError
        ``"fmt: expected 'kalibr' or 'opencv' or 'ros', got ..."`` (the registered names).
    """
    if name not in CALIBRATION_FORMATS:
        names = " or ".join(repr(n) for n in CALIBRATION_FORMATS)
        raise ValueError(f"fmt: expected {names}, got {name!r}")
    return CALIBRATION_FORMATS[name]
