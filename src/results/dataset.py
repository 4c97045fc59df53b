"""The result dataset: names, dims and units are a contract other tools read.

The contract is docs/conventions.md §3.

Build it with :func:`build_dataset`, write it with :func:`write_netcdf` (atomic) and read it with
:func:`read_netcdf`; the contract's names and its check (``check_dataset``, for a dataset from
elsewhere before working on it) are in :mod:`simgap.results.contract`.
"""

from __future__ import annotations

import json
import platform
from collections.abc import Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np
import xarray as xr

import simgap
from simgap.core.atomic import atomic_write
from simgap.core.axes import AXES
from simgap.core.rig import Rig
from simgap.pose.image_stats import STATS
from simgap.pose.tags import empty_tag_arrays
from simgap.results.cf import ERROR_UNITS, decode_cf, encode_cf
from simgap.results.contract import (
    COORD_ATTRS,
    PIXEL_UNITS,
    DatasetError,
    kind_problem,
)


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
    chosen = np.asarray(results.get("auto_exposure_ev", np.nan), float)
    if np.isfinite(chosen).any():  # the same for every tag of a frame: kept once per frame
        ds["auto_exposure_ev"] = (
            ("variant", "repeat", "p", "theta"),
            _frame_values(chosen),
            {
                "units": "1",
                "long_name": "exposure the camera's auto exposure chose for the frame, in stops "
                "(EV) from the experiment's base exposure; NaN where nothing was imaged",
            },
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


def _frame_values(per_tag: np.ndarray) -> np.ndarray:
    """A per-frame value kept per tag (V, R, T, P, Θ) as one per frame (V, R, P, Θ).

    NaN where no tag of the frame holds one.
    """
    finite = np.isfinite(per_tag)
    first = np.argmax(finite, axis=2)[:, :, None]
    return np.take_along_axis(per_tag, first, axis=2)[:, :, 0]


#: Name of the one variant of :func:`pooled_variants`.
POOLED = "pooled"


def pooled_variants(ds: xr.Dataset, name: str = POOLED) -> xr.Dataset:
    """Every variant's repeats as the repeats of one variant ``name``.

    The draws of a Monte Carlo over what the variants vary (the sun's direction of an orbital
    sweep): each variable along both ``variant`` and ``repeat`` gets ``V x R`` repeats (variant
    by variant); one along ``variant`` only (``visible`` where effects moved the tags) is true
    where any variant's is. The attribute ``pooled_variants`` lists the variants pooled.
    """
    names = [str(v) for v in ds.variant.values]
    both = [k for k, v in ds.data_vars.items() if {"variant", "repeat"} <= set(v.dims)]
    draws = xr.concat([ds[both].isel(variant=i, drop=True) for i in range(len(names))], "repeat")
    draws = draws.assign_coords(repeat=np.arange(draws.sizes["repeat"]))
    out = ds.drop_vars(both).drop_dims("repeat", errors="ignore")
    for key in [k for k, v in out.data_vars.items() if "variant" in v.dims]:
        out[key] = out[key].any("variant") if out[key].dtype == bool else out[key].max("variant")
    out = out.drop_dims("variant", errors="ignore").drop_vars("variant", errors="ignore")
    out = xr.merge([out, draws.expand_dims(variant=np.array([name]))], combine_attrs="override")
    for key in both:
        out[key] = out[key].transpose(*ds[key].dims)
    out.attrs = {**ds.attrs, "pooled_variants": json.dumps(names)}
    return out


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
        if name in out and kind_problem(out[name], "boolean") is None:
            out[name] = out[name].fillna(0).astype(bool)
    return out
