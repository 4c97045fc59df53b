"""Time-range CSV files: which (p, theta) the fixture stood at during each span of a bag."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

from simgap.core.config import ConfigError
from simgap.core.rig import Rig
from simgap.pipeline.bag.formats import (
    RANGE_COLUMNS,
)
from simgap.pipeline.capture.manifest import turntable_stop


@dataclass(frozen=True)
class TimeRange:
    """A time range of a bag during which the fixture stood still (ns, inclusive; rad)."""

    start_ns: int
    end_ns: int
    p: int
    theta: float
    row: int


def _int_field(text: str, where: str, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise ConfigError(f"{where}: {what}: expected an integer, got {text!r}") from None
    return value


def read_time_ranges(path: Path, rig: Rig) -> list[TimeRange]:
    """Read and validate a time-range CSV (header ``start_ns,end_ns,p,theta_rad``).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file, row and column: missing or unknown column, a non-integer time,
        ``end_ns < start_ns``, a ``p`` that is not a pin hole, a ``theta_rad`` that is not a
        turntable stop, overlapping ranges, or no rows.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the time-range CSV: {exc}") from exc
    reader = csv.reader(io.StringIO(text))
    header = [h.strip() for h in next(reader, [])]
    if sorted(header) != sorted(RANGE_COLUMNS):
        raise ConfigError(
            f"{path}: header: expected the columns {','.join(RANGE_COLUMNS)}, got {header}"
        )
    ranges: list[TimeRange] = []
    for cells in reader:
        if not any(c.strip() for c in cells):
            continue
        row = len(ranges) + 1
        where = f"{path}: row {row} (line {reader.line_num})"
        if len(cells) != len(header):
            raise ConfigError(f"{where}: expected {len(header)} fields, got {len(cells)}")
        rec = {k: c.strip() for k, c in zip(header, cells, strict=True)}
        start = _int_field(rec["start_ns"], where, "start_ns")
        end = _int_field(rec["end_ns"], where, "end_ns")
        if end < start:
            raise ConfigError(f"{where}: end_ns: expected >= start_ns ({start}), got {end}")
        p = _int_field(rec["p"], where, "p")
        if p not in rig.grid.p:
            raise ConfigError(f"{where}: p: expected a pin hole of the rig, got {p}")
        theta = turntable_stop(rec["theta_rad"], rig, f"{where}: theta_rad")
        ranges.append(TimeRange(start, end, p, theta, row))
    if not ranges:
        raise ConfigError(f"{path}: no rows (expected one time range per fixture configuration)")
    ordered = sorted(ranges, key=lambda r: r.start_ns)
    for a, b in zip(ordered, ordered[1:], strict=False):
        if b.start_ns <= a.end_ns:
            raise ConfigError(f"{path}: row {b.row}: overlaps row {a.row}")
    return ranges
