"""The capture manifest (``manifest.csv``): one row per frame, checked against the rig.

Header ``image,p,theta_rad`` (optional columns ``repeat``, ``note``); ``p`` must be a pin hole of
the rig, ``theta_rad`` a turntable stop (within :data:`THETA_TOLERANCE_RAD`), ``image`` a file
inside the capture folder. Every problem is a :class:`~simgap.core.config.ConfigError` naming the
file, the row and its line.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simgap.core.config import ConfigError, shown
from simgap.core.paths import resolved
from simgap.core.rig import Rig
from simgap.render.imaging import png_bit_depth

REQUIRED_COLUMNS = ("image", "p", "theta_rad")
OPTIONAL_COLUMNS = ("repeat", "note")
#: How far a manifest angle may be from a turntable stop (rad).
THETA_TOLERANCE_RAD = 1e-3
#: Bit depth of PNG frames simgap refuses (docs/conventions.md §3 frames are 8-bit).
REFUSED_PNG_BITS = 16


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


def _holes(ps: Sequence[int]) -> str:
    """Pin holes for a message: ``"0..14"`` when contiguous, else listed."""
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
            f"{math.radians(step):.6f} rad, within {THETA_TOLERANCE_RAD:g} rad), got {shown(value)}"
        )
    return stop


def _parse_int(text: str) -> int | None:
    """An integer written as ``3`` or ``3.0``; None otherwise."""
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
        docs/conventions.md §3: the scaling of 16-bit data depends on the sensor's bit depth, so
        it is not guessed; convert the frames to 8 bits first).
    """
    if not name:
        raise ConfigError(f"{where}: image: expected a path, got an empty field")
    rel = Path(name)
    if "\x00" in name or rel.is_absolute() or ".." in rel.parts:
        raise ConfigError(
            f"{where}: image: expected a path inside the capture folder (relative, without "
            f"'..'), got {shown(name)}"
        )
    image = folder / rel
    try:
        root, real = resolved(folder), resolved(image)
    except OSError as exc:
        raise ConfigError(
            f"{where}: image: {shown(name)}: cannot resolve the path ({exc})"
        ) from None
    if not real.is_relative_to(root):
        raise ConfigError(
            f"{where}: image: {name!r} resolves to {real}, outside the capture "
            f"folder {root} (a symbolic link?); expected a file inside the folder"
        )
    if not image.is_file():
        raise ConfigError(f"{where}: image: file not found: {image}")
    try:
        with open(image, "rb") as handle:
            head = handle.read(32)
    except OSError as exc:
        raise ConfigError(f"{where}: image: cannot read {image}: {exc.strerror or exc}") from exc
    if png_bit_depth(head) == REFUSED_PNG_BITS:
        raise ConfigError(
            f"{where}: image: {image} is a 16-bit PNG; expected 8-bit PNG or JPEG frames "
            "(the scaling to 8 bits depends on the sensor's bit depth: convert the frames first)"
        )
    return image


def read_manifest(path: Path, folder: Path, rig: Rig) -> list[CaptureFrame]:
    """The frames of a manifest, validated against the rig and the capture folder.

    Parameters
    ----------
    path : Path
        ``manifest.csv``.
    folder : Path
        The capture folder that image paths are relative to.
    rig : Rig
        Pin holes and turntable stops.

    Raises
    ------
    simgap.core.config.ConfigError
        For an unknown, repeated or missing column, a bad row, a duplicate (p, theta, repeat),
        one image file on rows of different poses (the same pose's repeats may share it: ingest
        warns of identical frames) or no rows at all; naming the file, row and line.
    """
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
                f"{path}: column {shown(name)}: unknown; allowed columns: {', '.join(allowed)}"
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
    images: dict[Path, tuple[int, int, float]] = {}  # file -> its first row, p, theta
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
                f"got {shown(rec['p'])}"
            )
        theta = turntable_stop(rec["theta_rad"], rig, f"{where}: theta_rad")
        repeat = _parse_int(rec["repeat"]) if "repeat" in rec else 0
        if repeat is None or repeat < 0:
            raise ConfigError(
                f"{where}: repeat: expected an integer >= 0, got {shown(rec['repeat'])}"
            )
        image = _image_path(folder, rec["image"], where)
        key = (p, round(theta, 9), repeat)
        if key in seen:
            raise ConfigError(
                f"{where}: duplicate of row {seen[key]} (p={p}, theta={math.degrees(theta):g} deg, "
                f"repeat={repeat})"
            )
        seen[key] = row
        first = images.setdefault(image.resolve(), (row, p, theta))
        if first[1:] != (p, theta):
            raise ConfigError(
                f"{where}: image: {rec['image']} is also row {first[0]}'s, at another pose "
                f"(p={first[1]}, theta={math.degrees(first[2]):g} deg); expected one image file "
                "for one pose"
            )
        frames.append(CaptureFrame(image, p, theta, repeat, rec.get("note", "")))
    if not frames:
        raise ConfigError(f"{path}: no frames (the manifest has a header but no rows)")
    return frames
