"""Write a capture folder (what pseudo-real data is written as): calibration, images, manifest."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from simgap.core.atomic import atomic_write
from simgap.core.paths import CALIBRATION_FILE, IMAGES_DIR, MANIFEST_FILE
from simgap.core.rig import CameraModel
from simgap.pipeline.capture.calibration import calibration_format, calibration_to_yaml
from simgap.pipeline.capture.manifest import REQUIRED_COLUMNS
from simgap.render import imaging


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
    calibration_format(fmt)  # an unknown format fails before anything is written
    if image_format not in ("png", "jpg"):
        raise ValueError(f"image_format: expected 'png' or 'jpg', got {image_format!r}")
    if not 0 <= jpeg_quality <= 100:
        raise ValueError(f"jpeg_quality: expected 0..100, got {jpeg_quality}")
    folder = Path(folder)
    (folder / IMAGES_DIR).mkdir(parents=True, exist_ok=True)
    atomic_write(folder / CALIBRATION_FILE, calibration_to_yaml(calibration, fmt).encode())
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
        if image_format == "png":
            data = imaging.encode_png(bgr)
        else:
            ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
            if not ok:
                raise OSError(f"{folder / name}: could not encode the image")
            data = buf.tobytes()
        atomic_write(folder / name, data)
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
    atomic_write(manifest, out.getvalue().encode())
    return manifest
