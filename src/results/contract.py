"""The result dataset's contract: its variables, coordinates and their attrs, and the check.

The contract is docs/conventions.md §3. :func:`check_dataset` checks a dataset from elsewhere
against it before any work; :class:`DatasetError` names the file, the variable and what was
expected.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from simgap.core.axes import AXES
from simgap.core.config import ConfigError, from_mapping, parse_yaml
from simgap.core.rig import CameraModel
from simgap.results.cf import AXIS_LONG_NAME

#: ``units`` attr of pixel quantities: CF has no pixel unit (udunits knows none); a distance in
#: pixels is a number of pixel pitches, dimensionless (the long_name says "px").
PIXEL_UNITS = "1"
FULL_DIMS = ("variant", "repeat", "tag", "p", "theta")
#: The contract (docs/conventions.md §3): variable -> (dims, kind), kind "number" or "boolean".
#: ``visible`` may also have a leading ``variant`` dim.
CONTRACT: dict[str, tuple[tuple[str, ...], str]] = {
    "expected": (("tag", "p", "theta", "axis"), "number"),
    "estimated": (FULL_DIMS + ("axis",), "number"),
    "error": (FULL_DIMS + ("axis",), "number"),
    "visible": (("tag", "p", "theta"), "boolean"),
    "detected": (FULL_DIMS, "boolean"),
    "reproj_px": (FULL_DIMS, "number"),
    "corners": (FULL_DIMS + ("corner", "uv"), "number"),
}
#: Coordinates every result dataset has: name -> kind ("integer", "angle", "string").
COORDS = {
    "variant": "string",
    "repeat": "integer",
    "tag": "integer",
    "p": "integer",
    "theta": "angle",
    "axis": "string",
}
#: ``long_name`` and ``units`` attrs of the coordinates (docs/conventions.md §3, "On disk"): ids
#: and indices are dimensionless numbers, units "1"; labels have none.
COORD_ATTRS: dict[str, dict[str, str]] = {
    "variant": {"long_name": "variant: effects applied to the renders, or real"},
    "repeat": {"long_name": "repeat index (another noise draw or frame)", "units": "1"},
    "tag": {"long_name": "ArUco tag id", "units": "1"},
    "p": {"long_name": "carriage pin hole index", "units": "1"},
    "theta": {"long_name": "turntable angle", "units": "rad"},
    "axis": {"long_name": AXIS_LONG_NAME},
    "corner": {"long_name": "marker corner index: 0 TL, 1 TR, 2 BR, 3 BL", "units": "1"},
    "uv": {"long_name": "image coordinate: u right, v down"},
    "stat": {"long_name": "image statistic"},
    "stat_units": {"long_name": "scale of the image statistic (DN, px or 1)"},
    "stat_long_name": {"long_name": "meaning of the image statistic"},
}
#: Variables the analyses read unless they say otherwise.
REQUIRED = ("error", "detected", "visible")
#: ``conventions`` attr of every result dataset: the frame the poses are expressed in.
CONVENTIONS = "docs/conventions.md §1: global frame = eyepoint (+X right, +Y forward, +Z up)"


class DatasetError(ConfigError):
    """A result dataset does not follow the contract (docs/conventions.md §3).

    The message names the file and the variable.
    """


def kind_problem(da: xr.DataArray, kind: str) -> str | None:
    """What is wrong with the values of ``da`` for ``kind`` (see :data:`CONTRACT`), or None."""
    k = da.dtype.kind
    if kind == "number":
        return None if k in "fiu" else f"expected numbers, got dtype {da.dtype}"
    if k == "b":
        return None
    if k in "iuf":
        values = np.unique(da.values[~np.isnan(da.values)] if k == "f" else da.values)
        if np.isin(values, (0, 1)).all():
            return None
        return f"expected boolean values (0/1), got {values[:5].tolist()}"
    return f"expected booleans, got dtype {da.dtype}"


def _coord_problem(values: np.ndarray, kind: str) -> str | None:
    """What is wrong with a coordinate's values for ``kind`` (see :data:`COORDS`), or None."""
    k = values.dtype.kind
    if kind == "string":
        if k == "U" or (k == "O" and all(isinstance(v, str) for v in values.tolist())):
            return None
        return f"expected strings, got dtype {values.dtype}"
    if kind == "integer":
        if k in "iu":
            return None
        return f"expected integers, got dtype {values.dtype}"
    if k != "f":
        return f"expected angles in radians (floats), got dtype {values.dtype}"
    if not np.isfinite(values).all():
        return "expected finite angles (rad), got NaN or infinity"
    if values.min() < -1e-9 or values.max() > 2 * math.pi + 1e-6:
        hint = " (degrees?)" if values.max() <= 360.0 + 1e-6 else ""
        return (
            f"expected angles in radians within [0, 2 pi], got {values.min():g}..{values.max():g}"
            f"{hint}"
        )
    return None


def check_dataset(
    ds: xr.Dataset, path: str | Path | None = None, required: Sequence[str] = REQUIRED
) -> xr.Dataset:
    """Check a result dataset against the contract (docs/conventions.md §3) before working on it.

    Checks that the ``required`` variables and every coordinate are present, that every contract
    variable present has the contract's dims (in order) and values (numbers; booleans or 0/1 for
    ``visible`` and ``detected``), that coordinates have their types (integer ``tag``, ``p`` and
    ``repeat``, string ``variant`` and ``axis`` with all six axes, ``theta`` in radians within
    [0, 2 pi]), are non-empty and have no repeated values.

    Parameters
    ----------
    ds : xarray.Dataset
        The dataset.
    path : str or Path, optional
        Its file, for messages (default: the file xarray read it from, else ``<dataset>``).
    required : sequence of str
        Variables the caller needs.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself (for chaining).

    Raises
    ------
    DatasetError
        ``"<file>: <variable>: expected ..., got ..."`` for the first problem found.
    """
    where = f"{path or ds.encoding.get('source') or '<dataset>'}: "
    missing = [n for n in required if n not in ds.data_vars]
    if missing:
        raise DatasetError(
            f"{where}{missing[0]}: required variable is missing (a simgap result dataset has "
            f"{', '.join(CONTRACT)}; missing: {', '.join(missing)})"
        )
    for name, kind in COORDS.items():
        if name not in ds.coords:
            raise DatasetError(f"{where}{name}: required coordinate is missing")
        values = np.asarray(ds[name].values)
        if values.ndim != 1 or values.size == 0:
            raise DatasetError(f"{where}{name}: expected a non-empty 1-d coordinate")
        problem = _coord_problem(values, kind)
        if problem:
            raise DatasetError(f"{where}{name}: {problem}")
        if len(np.unique(values)) != values.size:
            raise DatasetError(f"{where}{name}: expected distinct values, got {values.tolist()}")
    absent = [a for a in AXES if a not in ds["axis"].values.tolist()]
    if absent:
        raise DatasetError(f"{where}axis: expected the values {', '.join(AXES)}; lacks {absent}")
    for name, (dims, kind) in CONTRACT.items():
        if name not in ds.data_vars:
            continue
        allowed = [dims, ("variant",) + dims] if name == "visible" else [dims]
        if ds[name].dims not in allowed:
            raise DatasetError(f"{where}{name}: expected dims {dims}, got {ds[name].dims}")
        problem = kind_problem(ds[name], kind)
        if problem:
            raise DatasetError(f"{where}{name}: {problem}")
    if "calibration_yaml" in ds.attrs:  # the calibration a capture was ingested with
        _check_calibration_attr(ds.attrs["calibration_yaml"], where)
    return ds


def _check_calibration_attr(text: object, where: str) -> None:
    """Refuse a ``calibration_yaml`` attr that is not a valid :class:`CameraModel` mapping."""
    label = f"{where}attrs.calibration_yaml"
    data = parse_yaml(text, label) if isinstance(text, str) else None
    if not isinstance(data, dict):
        raise DatasetError(f"{label}: expected a CameraModel mapping (YAML text), got {text!r:.60}")
    try:
        from_mapping(CameraModel, data, where=label)
    except ConfigError as exc:
        raise DatasetError(str(exc)) from exc
