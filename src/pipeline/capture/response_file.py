"""A camera's response on disk: its exposure bracket in, its response file out and in again.

The bracket is a folder of photos of one still scene with ``exposures.csv`` (header
``image,exposure_s``: each photo's file inside the folder and its exposure time in seconds). The
response file is YAML (after a header line the command writes) with ``linear_at_dn``: the relative
exposure at each 8-bit code (:class:`simgap.pose.camera_response.CameraResponse`), the
``camera_response`` effect's parameter. Every problem of a file is a
:class:`~simgap.core.config.ConfigError` naming the file, the key or row, and what was expected
(a bracket whose photos estimate no response is the estimation's ``ValueError``).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import cv2
import numpy as np
import yaml

from simgap.core.config import ConfigError
from simgap.pose.camera_response import RESPONSE_VALUES, CameraResponse

#: The bracket folder's list of photos and exposure times.
BRACKET_MANIFEST = "exposures.csv"
BRACKET_COLUMNS = ("image", "exposure_s")


def read_bracket(folder: Path) -> tuple[list[np.ndarray], list[float]]:
    """The photos (8-bit, as stored: grey or BGR) and exposure times (s) of a bracket folder."""
    manifest = folder / BRACKET_MANIFEST
    if not manifest.is_file():
        raise ConfigError(f"{manifest}: no such file (expected {','.join(BRACKET_COLUMNS)})")
    try:
        rows = list(csv.DictReader(io.StringIO(manifest.read_text(encoding="utf-8"))))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{manifest}: not a readable UTF-8 CSV file ({exc})") from None
    missing = [c for c in BRACKET_COLUMNS if rows and c not in rows[0]]
    if not rows or missing:
        raise ConfigError(f"{manifest}: expected a header {','.join(BRACKET_COLUMNS)} and rows")
    photos, times = [], []
    for line, row in enumerate(rows, start=2):
        where = f"{manifest}: line {line}"
        try:
            seconds = float(row["exposure_s"])
        except (TypeError, ValueError):
            raise ConfigError(
                f"{where}: exposure_s: expected a number, got {row['exposure_s']!r}"
            ) from None
        if not (np.isfinite(seconds) and seconds > 0):
            raise ConfigError(f"{where}: exposure_s: expected a finite time > 0 s, got {seconds}")
        path = folder / str(row["image"])
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED) if path.is_file() else None
        if image is None:
            raise ConfigError(f"{where}: image: {path} is no readable image")
        if image.dtype != np.uint8:
            raise ConfigError(f"{where}: image: expected an 8-bit image, got {image.dtype}")
        photos.append(image[..., :3] if image.ndim == 3 else image)
        times.append(seconds)
    return photos, times


def response_to_yaml(response: CameraResponse) -> str:
    """The response file's YAML body: ``linear_at_dn``, six significant digits."""
    values = [float(f"{v:.6g}") for v in response.linear]
    return yaml.safe_dump({"linear_at_dn": values}, default_flow_style=None, width=100)


def read_response(path: Path) -> CameraResponse:
    """A camera's response from its file (``linear_at_dn``: 256 non-decreasing values)."""
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f"{path}: not a readable YAML file ({exc})") from None
    values = data.get("linear_at_dn") if isinstance(data, dict) else None
    expected = f"{RESPONSE_VALUES} (relative exposure per 8-bit code)"
    numbers = isinstance(values, list) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in values
    )
    try:
        if not numbers:
            raise ValueError(expected)
        return CameraResponse(np.asarray(values, float))
    except ValueError:
        raise ConfigError(f"{path}: linear_at_dn: expected {expected}") from None


__all__ = [
    "BRACKET_COLUMNS",
    "BRACKET_MANIFEST",
    "read_bracket",
    "read_response",
    "response_to_yaml",
]
