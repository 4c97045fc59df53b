"""Reference numbers from the paper: Table 2 and the high-precision thresholds.

The paper (Gazebo simulation vs. PASS hardware, D435i RGB camera, ArUco tags 0 and 1) tabulates
the maximum and minimum *absolute* pose error per global-frame axis and per tag over its 270
configurations (15 pin holes x 18 visible turntable angles per tag). Translation errors are in
metres, rotation errors in radians. Our report prints its own envelope beside these numbers.

Examples
--------
>>> from simgap.analysis.paper import TABLE2, threshold_for
>>> TABLE2[("ty", 1)].hardware_max
0.0859
>>> threshold_for("rz")
0.0873
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, fields
from pathlib import Path
from types import MappingProxyType
from typing import Final

import numpy as np
import xarray as xr

from simgap.core.axes import AXES, AXIS_UNITS, ROTATION_AXES, TRANSLATION_AXES

__all__ = [
    "AXES",
    "AXIS_UNITS",
    "ROTATION_AXES",
    "TABLE2",
    "TAGS",
    "THRESHOLD_BY_UNIT",
    "TRANSLATION_AXES",
    "PaperEnvelope",
    "table2_dataarray",
    "threshold_for",
]

TRANSLATION_THRESHOLD_M: Final[float] = 0.005
"""High-precision threshold on the absolute translation error per axis, in metres."""

ROTATION_THRESHOLD_RAD: Final[float] = 0.0873
"""High-precision threshold on the absolute rotation error per axis, in radians (about 5 deg)."""

THRESHOLD_BY_UNIT: Final = MappingProxyType(
    {"m": TRANSLATION_THRESHOLD_M, "rad": ROTATION_THRESHOLD_RAD}
)
"""High-precision threshold per SI unit of the error (m, rad)."""

TAGS: Final[tuple[int, ...]] = (0, 1)
"""Tag ids for which the paper reports errors."""


@dataclass(frozen=True)
class PaperEnvelope:
    """Maximum and minimum absolute error of one axis and tag in the paper's Table 2.

    Parameters
    ----------
    simulation_max : float
        Largest absolute error of the Gazebo simulation (m for translation, rad for rotation).
    hardware_max : float
        Largest absolute error of the hardware test (m or rad).
    simulation_min : float
        Smallest absolute error of the simulation (m or rad).
    hardware_min : float
        Smallest absolute error of the hardware test (m or rad).
    """

    simulation_max: float
    hardware_max: float
    simulation_min: float
    hardware_min: float


TABLE2_FILE = Path(__file__).with_name("paper_table2.csv")


def _read_table2(path: Path) -> dict[tuple[str, int], PaperEnvelope]:
    """Rows of the transcribed Table 2: ``(axis, tag) -> PaperEnvelope``."""
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    table = {}
    for row in csv.DictReader(lines):
        values = [float(row[f.name]) for f in fields(PaperEnvelope)]
        table[(row["axis"], int(row["tag"]))] = PaperEnvelope(*values)
    return table


TABLE2: Final = MappingProxyType(_read_table2(TABLE2_FILE))
"""The paper's Table 2, keyed by ``(axis, tag)``; values in m (``t*``) or rad (``r*``)."""


def threshold_for(axis: str) -> float:
    """Return the high-precision threshold of one axis.

    Parameters
    ----------
    axis : str
        One of ``"tx", "ty", "tz", "rx", "ry", "rz"``.

    Returns
    -------
    float
        0.005 (m) for a translation axis, 0.0873 (rad) for a rotation axis.

    Raises
    ------
    ValueError
        If `axis` is not one of the six axes.
    """
    if axis in TRANSLATION_AXES:
        return TRANSLATION_THRESHOLD_M
    if axis in ROTATION_AXES:
        return ROTATION_THRESHOLD_RAD
    raise ValueError(f"axis must be one of {', '.join(AXES)}; got {axis!r}")


def table2_dataarray() -> xr.DataArray:
    """Return the paper's Table 2 as a labelled array.

    Returns
    -------
    xarray.DataArray
        Dims ``(axis, tag, source, statistic)`` with ``source`` in ``["simulation", "hardware"]``
        and ``statistic`` in ``["max", "min"]``; absolute error in m (translation axes) or rad
        (rotation axes). The ``units`` attr says so, and the ``unit`` coordinate gives each axis'
        unit.
    """
    values = np.array(
        [
            [
                [
                    [TABLE2[(axis, tag)].simulation_max, TABLE2[(axis, tag)].simulation_min],
                    [TABLE2[(axis, tag)].hardware_max, TABLE2[(axis, tag)].hardware_min],
                ]
                for tag in TAGS
            ]
            for axis in AXES
        ]
    )
    return xr.DataArray(
        values,
        dims=("axis", "tag", "source", "statistic"),
        coords={
            "axis": list(AXES),
            "tag": list(TAGS),
            "source": ["simulation", "hardware"],
            "statistic": ["max", "min"],
            "unit": ("axis", [AXIS_UNITS[a] for a in AXES]),
        },
        name="paper_table2_abs_error",
        attrs={"units": "m (tx, ty, tz) or rad (rx, ry, rz)", "source": "paper Table 2"},
    )
