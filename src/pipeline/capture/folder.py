"""A capture folder (docs/conventions.md §3) read and validated against a rig.

::

    capture/
      camera.yaml     the calibration the operator believes in (ROS camera_info or OpenCV YAML)
      manifest.csv    header image,p,theta_rad (optional columns: repeat, note)
      images/...      8-bit PNG or JPEG frames, as the camera delivered them
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from simgap.core.config import ConfigError
from simgap.core.limits import MAX_PIXELS
from simgap.core.paths import CALIBRATION_FILE, MANIFEST_FILE, resolved
from simgap.core.rig import CameraModel, Rig
from simgap.pipeline.capture.calibration import read_calibration
from simgap.pipeline.capture.manifest import CaptureFrame, read_manifest
from simgap.render.imaging import encoded_size, truncation

#: Frames over this many pixels are read only when ``camera.yaml`` states the image size itself
#: (else the first frame's header would set it and a 600 KB PNG of 25000 x 25000 px would be
#: decoded): Pillow's decompression-bomb threshold, ``PIL.Image.MAX_IMAGE_PIXELS`` (89.5 MP,
#: 268 MB decoded as 8-bit colour).
UNSTATED_SIZE_MAX_PIXELS = 89_478_485


class CaptureWarning(UserWarning):
    """A frame of a capture could not be used (it is recorded as a detection failure)."""


@dataclass
class Capture:
    """A validated capture folder.

    Attributes
    ----------
    folder : Path
        The capture folder.
    calibration : CameraModel
        The calibration of ``calibration_path`` (what the estimator assumes).
    frames : list of CaptureFrame
        One per manifest row, in manifest order.
    calibration_path : Path or None
        The calibration file read: ``camera.yaml`` in the folder, or the one given instead.
    """

    folder: Path
    calibration: CameraModel
    frames: list[CaptureFrame] = field(default_factory=list)
    calibration_path: Path | None = None


def frame_size(path: Path) -> tuple[int, int] | None:
    """Width and height (px) of a complete PNG or JPEG frame from its header, or None.

    None when the file cannot be read, is truncated (:func:`simgap.render.imaging.truncation`)
    or is not a PNG or JPEG whose header can be parsed. Nothing is decoded, so a frame of
    25000 x 25000 px costs its file's bytes, not the gigabytes of its pixels.
    """
    try:
        data = path.read_bytes()
    except OSError:
        return None
    return None if truncation(data) is not None else encoded_size(data)


def read_image(path: Path, width: int, height: int) -> np.ndarray | str:
    """A frame as 8-bit BGR, or why it cannot be used (its size is checked before decoding).

    Returns
    -------
    ndarray or str
        The ``(height, width, 3)`` image, or ``"cannot be decoded"`` (unreadable, truncated, not
        a PNG or JPEG, or refused by the decoder) or ``"is WxH, expected WxH"``: the header's
        size differs from ``width`` x ``height`` (px), and the frame is not decoded. Truncation
        is checked on the bytes, because decoders return a grey-filled image for a truncated
        JPEG with only a warning on stderr.
    """
    try:
        data = path.read_bytes()
    except OSError:
        return "cannot be decoded"
    size = None if truncation(data) is not None else encoded_size(data)
    if size is None:
        return "cannot be decoded"
    if size != (width, height):
        return f"is {size[0]}x{size[1]}, expected {width}x{height}"
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    except cv2.error:
        return "cannot be decoded"
    if img is None or img.size == 0:
        return "cannot be decoded"
    if img.shape[:2] != (height, width):  # e.g. turned by its EXIF orientation
        return f"is {img.shape[1]}x{img.shape[0]} decoded, expected {width}x{height}"
    return img


def check_pixel_budget(
    width: int, height: int, max_pixels: int, where: str, key: str = "image_width x image_height"
) -> None:
    """Refuse an image size over the pixel budget, naming ``where`` and ``key``.

    The budget is :data:`simgap.core.limits.MAX_PIXELS` unless raised (``--max-pixels``).

    Raises
    ------
    simgap.core.config.ConfigError
        ``"{where}: {key}: WxH = N px, expected at most M px (the pixel budget; --max-pixels
        raises it)"``.
    """
    if width * height > max_pixels:
        raise ConfigError(
            f"{where}: {key}: {width}x{height} = {width * height} px, expected at most "
            f"{max_pixels} px (the pixel budget: no frame is decoded beyond it; --max-pixels "
            "raises it)"
        )


def read_capture(
    folder: Path,
    rig: Rig,
    calibration_file: Path | None = None,
    max_pixels: int = MAX_PIXELS,
) -> Capture:
    """Read and validate a capture folder against a rig.

    Parameters
    ----------
    folder : Path
        The capture folder (``camera.yaml``, ``manifest.csv``, images).
    rig : Rig
        The rig: its pin holes and turntable stops are the valid ``p`` and ``theta_rad``.
    calibration_file : Path, optional
        Read the calibration from this file (any name: ROS ``ost.yaml`` / camera_info YAML or
        OpenCV YAML) instead of the folder's ``camera.yaml``, which then need not exist.
    max_pixels : int
        The pixel budget (:data:`simgap.core.limits.MAX_PIXELS`): a calibration whose image
        is larger is refused.

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
        is not a turntable stop (within ``THETA_TOLERANCE_RAD``), a bad ``repeat`` or a
        duplicate (p, theta, repeat); the calibration is invalid, or its image size differs from
        the images' (read from the header of the first complete PNG or JPEG, before any
        frame is decoded); or no image is a complete PNG or JPEG. Messages name the file and
        the manifest row.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"{folder}: capture folder not found")
    cal_path, manifest_path = folder / CALIBRATION_FILE, folder / MANIFEST_FILE
    if calibration_file is not None:
        cal_path = Path(calibration_file)
        if not cal_path.is_file():
            raise ConfigError(
                f"--calibration {cal_path}: calibration file not found (expected a ROS "
                "camera_info YAML such as ost.yaml, or an OpenCV FileStorage YAML)"
            )
    for path, what in ((cal_path, "calibration"), (manifest_path, "manifest")):
        if not path.is_file():
            raise ConfigError(
                f"{path}: {what} file not found (a capture folder needs {CALIBRATION_FILE}, "
                f"{MANIFEST_FILE} and the images; or give the calibration with --calibration)"
            )
    try:
        root, real = resolved(folder), resolved(manifest_path)
    except OSError as exc:
        raise ConfigError(f"{manifest_path}: cannot resolve the path ({exc})") from None
    if not real.is_relative_to(root):
        raise ConfigError(
            f"{manifest_path}: resolves to {real}, outside the capture folder "
            f"{root} (a symbolic link?); expected the capture's own {MANIFEST_FILE}"
        )
    frames = read_manifest(manifest_path, folder, rig)
    first = next(((f, size) for f in frames if (size := frame_size(f.image)) is not None), None)
    if first is None:
        raise ConfigError(
            f"{folder}: none of the {len(frames)} images can be decoded (expected complete "
            "8-bit PNG or JPEG frames)"
        )
    frame, (w, h) = first
    cal = read_calibration(cal_path, w, h)
    if w * h > UNSTATED_SIZE_MAX_PIXELS:
        try:
            read_calibration(cal_path)  # the file's own size (an OpenCV file may not state one)
        except ConfigError:
            raise ConfigError(
                f"{cal_path}: image_width, image_height: required for frames over "
                f"{UNSTATED_SIZE_MAX_PIXELS} px ({frame.image} is {w}x{h}); state the camera's "
                "image size"
            ) from None
    check_pixel_budget(cal.width, cal.height, max_pixels, str(cal_path))
    if (cal.width, cal.height) != (w, h):
        raise ConfigError(
            f"{cal_path}: image size {cal.width}x{cal.height} differs from the images' "
            f"{w}x{h} ({frame.image})"
        )
    return Capture(folder, cal, frames, cal_path)
