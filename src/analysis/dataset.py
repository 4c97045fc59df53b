"""The result dataset (DESIGN §3): names, dims and units are a contract other tools read.

Build it with :func:`build_dataset`, write it with :func:`write_netcdf` (atomic) and read it with
:func:`read_netcdf`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import xarray as xr

from simgap.atomic import atomic_write

AXES = ("tx", "ty", "tz", "rx", "ry", "rz")
ERROR_UNITS = "m (tx, ty, tz); rad (rx, ry, rz)"


def empty_results(shape: tuple[int, ...]) -> dict[str, np.ndarray]:
    """Result arrays of ``shape`` (variant, repeat, tag, p, theta): none detected, NaN poses."""
    return {
        "detected": np.zeros(shape, bool),
        "estimated": np.full(shape + (6,), np.nan),
        "error": np.full(shape + (6,), np.nan),
        "reproj_px": np.full(shape, np.nan),
        "corners": np.full(shape + (4, 2), np.nan),
    }


def result_nbytes(n_configurations: int) -> int:
    """Bytes of the :func:`empty_results` arrays for ``n_configurations`` entries.

    An entry is one (variant, repeat, tag, p, theta): 169 B (flag, two poses, reprojection error,
    four corners).
    """
    per = sum(a.nbytes for a in empty_results((1,)).values())
    return int(n_configurations) * per


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
        ``reproj_px`` (V, R, tag, p, theta), ``corners`` (V, R, tag, p, theta, 4, 2).
    variants, repeats
        Variant names and repeat indices.
    attrs
        Dataset attributes (strings).
    """
    estimated = np.asarray(results["estimated"], float)
    error = np.asarray(results["error"], float)
    vdims = ("variant", "tag", "p", "theta") if visible.ndim == 4 else ("tag", "p", "theta")
    full = ("variant", "repeat", "tag", "p", "theta")
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
                {"long_name": "tag expected to be detectable"},
            ),
            "detected": (
                full,
                np.asarray(results["detected"], bool),
                {"long_name": "detector returned this tag id"},
            ),
            "reproj_px": (
                full,
                np.asarray(results["reproj_px"], float),
                {"units": "px", "long_name": "RMS reprojection error of the PnP solution"},
            ),
            "corners": (
                full + ("corner", "uv"),
                np.asarray(results["corners"], float),
                {
                    "units": "px",
                    "long_name": "detected corners TL, TR, BR, BL (OpenCV pixel convention)",
                },
            ),
        },
        coords={
            "variant": ("variant", np.asarray(variants, dtype=str)),
            "repeat": ("repeat", np.asarray(repeats, dtype=int)),
            "tag": ("tag", np.asarray(tags, dtype=int)),
            "p": ("p", np.asarray(ps, dtype=int), {"long_name": "carriage pin hole"}),
            "theta": (
                "theta",
                np.asarray(thetas, dtype=float),
                {"units": "rad", "long_name": "turntable angle"},
            ),
            "axis": ("axis", np.asarray(AXES, dtype=str)),
            "corner": ("corner", np.arange(4)),
            "uv": ("uv", np.array(["u", "v"])),
        },
        attrs=dict(attrs or {}),
    )
    return ds


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` as netCDF4 atomically (temporary file + rename); return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, lambda tmp: ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4"))


def read_netcdf(path: str | Path) -> xr.Dataset:
    """Read a result dataset fully into memory (the file is closed afterwards)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: result dataset not found")
    with xr.open_dataset(path, engine="netcdf4") as ds:
        out = ds.load()
    for name in ("visible", "detected"):
        if name in out:
            out[name] = out[name].astype(bool)
    return out
