"""The result dataset: names, dims and units are a contract other tools read.

The contract is docs/conventions.md §3.

Build it with :func:`build_dataset`, write it with :func:`write_netcdf` (atomic), read it with
:func:`read_netcdf` and check a dataset from elsewhere against the contract with
:func:`check_dataset` before working on it.
"""

from __future__ import annotations

import math
import platform
from collections.abc import Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np
import xarray as xr

import simgap
from simgap.core.atomic import atomic_write
from simgap.core.axes import AXES
from simgap.core.config import ConfigError, from_mapping, parse_yaml
from simgap.core.rig import CameraModel, Rig
from simgap.pose.image_stats import STATS
from simgap.pose.tags import empty_tag_arrays
from simgap.results.cf import AXIS_LONG_NAME, ERROR_UNITS, decode_cf, encode_cf

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


def _kind_problem(da: xr.DataArray, kind: str) -> str | None:
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
        problem = _kind_problem(ds[name], kind)
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


def empty_results(shape: tuple[int, ...]) -> dict[str, np.ndarray]:
    """Result arrays of ``shape`` (variant, repeat, tag, p, theta): none detected, NaN poses.

    See :func:`simgap.pose.tags.empty_tag_arrays` (fields, dtypes and units).
    """
    return empty_tag_arrays(shape)


def result_nbytes(n_configurations: int) -> int:
    """Bytes of the :func:`empty_results` arrays for ``n_configurations`` entries.

    An entry is one (variant, repeat, tag, p, theta): 169 B (flag, two poses, reprojection error,
    four corners).
    """
    per = sum(a.nbytes for a in empty_results((1,)).values())
    return int(n_configurations) * per


def ground_truth(
    rig: Rig, tags: Sequence[int], ps: Sequence[int], thetas: Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    """The ``expected`` and ``visible`` arrays of a dataset, from the rig's CAD tree.

    Parameters
    ----------
    rig : Rig
        The nominal rig (ground truth).
    tags, ps, thetas
        Tag ids, pin holes and turntable angles (rad).

    Returns
    -------
    expected : ndarray (tag, p, theta, 6)
        Expected poses, global frame (m, rad).
    visible : ndarray of bool (tag, p, theta)
        Whether each tag is expected to be detectable.
    """
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in thetas] for p in ps] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in thetas] for p in ps] for t in tags])
    return expected, visible


def software_versions() -> dict[str, str]:
    """Provenance attrs shared by every result dataset: simgap, OpenCV, NumPy, xarray, Python."""
    return {
        "simgap_version": simgap.__version__,
        "opencv_version": cv2.__version__,
        "numpy_version": np.__version__,
        "xarray_version": xr.__version__,
        "python_version": platform.python_version(),
    }


def build_dataset(
    tags: tuple[int, ...],
    ps: tuple[int, ...],
    thetas: np.ndarray,
    expected: np.ndarray,
    visible: np.ndarray,
    results: Mapping[str, np.ndarray],
    variants: tuple[str, ...] = ("baseline",),
    repeats: tuple[int, ...] = (0,),
    attrs: Mapping[str, str] | None = None,
) -> xr.Dataset:
    """Assemble the result dataset.

    Parameters
    ----------
    tags, ps, thetas
        Coordinates: tag ids, pin holes, turntable angles (rad).
    expected : ndarray (tag, p, theta, 6)
        Ground-truth poses, global frame (m, rad).
    visible : ndarray of bool (tag, p, theta) or (variant, tag, p, theta)
        Whether each tag is expected to be detectable.
    results : mapping
        ``detected`` (V, R, tag, p, theta), ``estimated`` and ``error`` (V, R, tag, p, theta, 6),
        ``reproj_px`` (V, R, tag, p, theta), ``corners`` (V, R, tag, p, theta, 4, 2) and
        optionally ``image_stats`` (V, R, tag, p, theta, stat), see
        :data:`simgap.pose.image_stats.STATS`.
    variants, repeats
        Variant names and repeat indices.
    attrs
        Dataset attributes (strings).
    """
    estimated = np.asarray(results["estimated"], float)
    error = np.asarray(results["error"], float)
    vdims = ("variant", "tag", "p", "theta") if visible.ndim == 4 else ("tag", "p", "theta")
    full = ("variant", "repeat", "tag", "p", "theta")
    coords = {
        "variant": np.asarray(variants, dtype=str),
        "repeat": np.asarray(repeats, dtype=int),
        "tag": np.asarray(tags, dtype=int),
        "p": np.asarray(ps, dtype=int),
        "theta": np.asarray(thetas, dtype=float),
        "axis": np.asarray(AXES, dtype=str),
        "corner": np.arange(4),
        "uv": np.array(["u", "v"]),
    }
    ds = xr.Dataset(
        {
            "expected": (
                ("tag", "p", "theta", "axis"),
                expected,
                {
                    "units": ERROR_UNITS,
                    "long_name": "ground-truth pose, global frame (translation, rotation vector)",
                },
            ),
            "estimated": (
                full + ("axis",),
                estimated,
                {
                    "units": ERROR_UNITS,
                    "long_name": "estimated pose, global frame; NaN where not detected",
                },
            ),
            "error": (
                full + ("axis",),
                error,
                {
                    "units": ERROR_UNITS,
                    "long_name": "signed error: estimated - expected; rotvec(R_est R_exp^T)",
                },
            ),
            "visible": (
                vdims,
                np.asarray(visible, bool),
                {"long_name": "tag expected to be detectable (1 yes, 0 no)"},
            ),
            "detected": (
                full,
                np.asarray(results["detected"], bool),
                {"long_name": "detector returned this tag id (1 yes, 0 no)"},
            ),
            "reproj_px": (
                full,
                np.asarray(results["reproj_px"], float),
                {
                    "units": PIXEL_UNITS,
                    "long_name": "RMS reprojection error of the PnP solution (px)",
                },
            ),
            "corners": (
                full + ("corner", "uv"),
                np.asarray(results["corners"], float),
                {
                    "units": PIXEL_UNITS,
                    "long_name": "detected corners TL, TR, BR, BL (px, OpenCV pixel convention)",
                },
            ),
        },
        coords={name: (name, values, COORD_ATTRS[name]) for name, values in coords.items()},
        attrs=dict(attrs or {}),
    )
    if "image_stats" in results:
        ds["image_stats"] = (
            full + ("stat",),
            np.asarray(results["image_stats"], float),
            {
                "long_name": "image evidence around each tag, a dimensionless number per stat "
                "in the scale stat_units names (DN: 8-bit level, px: pixels, 1: ratio, count)",
                "units": "1",
            },
        )
        stats = {
            name: ("stat", np.asarray([s[i] for s in STATS], dtype=str), COORD_ATTRS[name])
            for i, name in enumerate(("stat", "stat_units", "stat_long_name"))
        }
        ds = ds.assign_coords(stats)
    return ds


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` as CF-1.10 netCDF4 atomically (temporary file + rename); return the path.

    The file holds :func:`simgap.results.cf.encode_cf` of ``ds`` (docs/conventions.md §3, "On
    disk"); :func:`read_netcdf` gives back ``ds``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cf = encode_cf(ds)
    return atomic_write(path, lambda tmp: cf.to_netcdf(tmp, engine="netcdf4", format="NETCDF4"))


def read_netcdf(path: str | Path) -> xr.Dataset:
    """Read a result dataset fully into memory (the file is closed afterwards).

    The file's CF form is turned back into the contract's (:func:`simgap.results.cf.decode_cf`).
    ``visible`` and ``detected`` are converted to booleans when they are stored as numbers; the
    rest of the contract is checked by :func:`check_dataset`.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    DatasetError
        If it cannot be read as netCDF.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: result dataset not found")
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            out = decode_cf(ds.load())
    except (OSError, ValueError, RuntimeError, KeyError) as exc:
        raise DatasetError(
            f"{path}: cannot read result dataset (expected a netCDF4 file written by simgap): "
            f"{type(exc).__name__}: {exc}"
        ) from exc
    for name in ("visible", "detected"):
        if name in out and _kind_problem(out[name], "boolean") is None:
            out[name] = out[name].fillna(0).astype(bool)
    return out
