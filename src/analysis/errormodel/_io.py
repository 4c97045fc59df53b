"""Error-model files: the netCDF dataset and its JSON form (readable without simgap).

The JSON schema is in docs/errormodel.md: grid coordinates, units, ``min_support``, provenance
attrs and per tag the nested lists of every tabulated variable, NaN as null.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from simgap.core.atomic import atomic_write
from simgap.core.axes import AXES
from simgap.results.cf import ERROR_UNITS, decode_cf
from simgap.results.contract import COORD_ATTRS
from simgap.results.dataset import write_netcdf

SCHEMA = "simgap-errormodel/1"
"""Schema name of error-model files (netCDF attr ``schema``, JSON key ``schema``)."""

#: How each tag's errors were fitted: the netCDF ``fit`` variable (CF flag values 0, 1, 2) and
#: the JSON per-tag ``fit`` string. ``none``: too few detections, NaN; ``pooled``: one constant per
#: axis with t intervals; ``local``: the local-linear fit (files without ``fit`` are ``local``).
FIT_METHODS = ("none", "pooled", "local")

#: Per-tag variables of the JSON form.
JSON_VARIABLES = (
    "bias", "spread", "bias_se", "correlation", "p_detect", "p_detect_lo", "p_detect_hi",
    "support_error", "support_detection",
)  # fmt: skip
#: ``units`` and ``long_name`` attrs of the model's variables and coordinates (a variable along
#: ``axis`` in :data:`ERROR_UNITS` is stored as translation and rotation parts, see
#: :mod:`simgap.results.cf`); no quantity here has a CF standard name.
ATTRS: dict[str, dict[str, Any]] = {
    "bias": {"units": ERROR_UNITS, "long_name": "location of the signed error"},
    "spread": {"units": ERROR_UNITS, "long_name": "std of the error"},
    "bias_se": {"units": ERROR_UNITS, "long_name": "std error of bias"},
    "correlation": {"units": "1", "long_name": "rank correlation of two axes' errors"},
    "calibration": {"units": "1", "long_name": "factor calibrating the spread to 90 % coverage"},
    "p_detect": {"units": "1", "long_name": "detection probability"},
    "p_detect_lo": {"units": "1", "long_name": "detection probability, 5 % bound"},
    "p_detect_hi": {"units": "1", "long_name": "detection probability, 95 % bound"},
    "support_error": {"units": "1", "long_name": "kernel mass of the detected configurations"},
    "support_detection": {"units": "1", "long_name": "kernel mass of the facing configurations"},
    "detections": {"units": "count", "long_name": "detections the model was fitted to"},
    "fit": {
        "long_name": "how the tag's errors were fitted",
        "flag_values": np.arange(len(FIT_METHODS), dtype=np.int8),
        "flag_meanings": " ".join(FIT_METHODS),
    },
    "tag": COORD_ATTRS["tag"],
    "distance": {"units": "m", "long_name": "eyepoint-tag distance"},
    "obliquity": {"units": "rad", "long_name": "signed angle between tag normal and line of sight"},
    "axis": COORD_ATTRS["axis"],
    "axis_b": {"long_name": "second pose axis of a correlation"},
}


def with_attrs(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` with the :data:`ATTRS` of each of its variables and coordinates (in place)."""
    for name, attrs in ATTRS.items():
        if name in ds.variables:
            ds[name].attrs.update(attrs)
    return ds


def read_model_dataset(path: str | Path) -> xr.Dataset:
    """The model dataset from its netCDF (``.nc``) or JSON (``.json``) file.

    Raises
    ------
    FileNotFoundError
        If ``path`` is not a file.
    ValueError
        If the file is not a simgap error model (schema).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: error model not found")
    if path.suffix == ".json":
        return dataset_from_json(json.loads(path.read_text()))
    with xr.open_dataset(path, engine="netcdf4") as ds:
        ds = decode_cf(ds.load())
    if ds.attrs.get("schema") != SCHEMA:
        raise ValueError(f"{path}: not a simgap error model (schema {SCHEMA!r})")
    return ds


def model_paths(path: str | Path) -> tuple[Path, Path]:
    """The netCDF and JSON files of a model written to ``path``.

    ``path`` and the same name with ``.json``; a ``path`` that ends in ``.json`` is the JSON,
    beside the same name with ``.nc``.
    """
    path = Path(path)
    if path.suffix == ".json":
        return path.with_suffix(".nc"), path
    return path, path.with_suffix(".json")


def write_model_dataset(ds: xr.Dataset, path: str | Path) -> tuple[Path, Path]:
    """Write the model's netCDF and JSON files (:func:`model_paths`), atomically; return both."""
    nc_path, json_path = model_paths(path)
    nc = write_netcdf(ds, nc_path)
    js = atomic_write(json_path, json.dumps(dataset_to_json(ds)))
    return nc, js


def dataset_to_json(ds: xr.Dataset) -> dict:
    """The JSON form of a model dataset (schema: docs/errormodel.md): nested lists, NaN as null."""

    def lists(a: np.ndarray):
        a = np.asarray(a)
        return np.where(np.isfinite(a), np.round(a, 9), np.nan).astype(object).tolist()

    def clean(v):
        if isinstance(v, list):
            return [clean(x) for x in v]
        return None if isinstance(v, float) and math.isnan(v) else v

    tags = {}
    for t in (int(t) for t in ds.tag.values):
        s = ds.sel(tag=t)
        tags[str(t)] = {k: clean(lists(s[k].values)) for k in JSON_VARIABLES}
        tags[str(t)]["fit"] = FIT_METHODS[int(s["fit"])] if "fit" in s else "local"
    return {
        "schema": SCHEMA,
        "axes": list(AXES),
        "units": {"distance": "m", "obliquity": "rad", "errors": ERROR_UNITS},
        "min_support": float(ds.attrs["min_support"]),
        "distance": ds.distance.values.tolist(),
        "obliquity": ds.obliquity.values.tolist(),
        "attrs": {k: str(v) for k, v in ds.attrs.items()},
        "tags": tags,
    }


def dataset_from_json(data: dict) -> xr.Dataset:
    """The model dataset from its JSON form."""
    if data.get("schema") != SCHEMA:
        raise ValueError(f"not a simgap error model (schema {SCHEMA!r})")
    tags = sorted(int(t) for t in data["tags"])

    def arr(key: str) -> np.ndarray:
        values = [data["tags"][str(t)][key] for t in tags]
        return np.array(values, dtype=object).astype(float)  # null -> NaN

    cube, plane = ("tag", "distance", "obliquity", "axis"), ("tag", "distance", "obliquity")
    ds = xr.Dataset(
        {
            "bias": (cube, arr("bias")),
            "spread": (cube, arr("spread")),
            "bias_se": (cube, arr("bias_se")),
            "correlation": (("tag", "axis", "axis_b"), arr("correlation")),
            "p_detect": (plane, arr("p_detect")),
            "p_detect_lo": (plane, arr("p_detect_lo")),
            "p_detect_hi": (plane, arr("p_detect_hi")),
            "support_error": (plane, arr("support_error")),
            "support_detection": (plane, arr("support_detection")),
            "fit": (
                ("tag",),
                np.array(
                    [FIT_METHODS.index(data["tags"][str(t)].get("fit", "local")) for t in tags],
                    np.int8,
                ),
            ),
        },
        coords={
            "tag": tags,
            "distance": data["distance"],
            "obliquity": data["obliquity"],
            "axis": list(data["axes"]),
            "axis_b": list(data["axes"]),
        },
        attrs={**data.get("attrs", {}), "min_support": float(data["min_support"])},
    )
    return with_attrs(ds)
