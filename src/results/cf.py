"""The netCDF form of simgap's datasets: CF-1.10 on disk, the contract's names in memory.

In memory a pose, a pose error and the error model's ``bias``, ``spread`` and ``bias_se`` are one
variable along the ``axis`` dim (tx, ty, tz in metres, rx, ry, rz in radians; ``units`` attr
:data:`ERROR_UNITS`), and labels (``variant``, ``axis``, ``stat``, ...) are string dimension
coordinates. CF allows neither (one udunits string per variable; coordinate variables are numeric),
so :func:`encode_cf` writes, and :func:`decode_cf` reads back (docs/conventions.md §3, "On disk"):

- each such variable ``X`` as ``X_translation`` (dim ``translation_axis``: tx, ty, tz; units
  ``m``) and ``X_rotation`` (dim ``rotation_axis``: rx, ry, rz; units ``rad``);
- each string coordinate as a char array (CF's string type); a string dimension coordinate
  ``D`` stays the coordinate variable of ``D``, so plain ``xarray.open_dataset`` indexes its
  labels and selects by name (``.sel(translation_axis="ty")``). CF's data model wants a
  coordinate variable numeric: ``cfchecks`` warns once per label dimension
  (:data:`LABEL_WARNING`) and finds no error;
- each boolean variable (``visible``, ``detected``) as 0/1 bytes with CF's ``flag_values`` and
  ``flag_meanings`` (``not_visible visible``);
- the global attr ``Conventions = "CF-1.10"``.

Files written before this form (one ``X`` with mixed units, string dimension coordinates) and
files that kept the labels in an auxiliary ``D_label`` variable read unchanged.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from simgap.core.axes import AXES, AXIS_UNITS, ROTATION_AXES, TRANSLATION_AXES

#: ``units`` attr, in memory, of the variables along ``axis`` that hold a pose or a pose error:
#: ``"m (tx, ty, tz); rad (rx, ry, rz)"``. On disk they are split (:func:`encode_cf`).
ERROR_UNITS = "; ".join(
    f"{unit} ({', '.join(a for a in AXES if AXIS_UNITS[a] == unit)})"
    for unit in dict.fromkeys(AXIS_UNITS.values())
)
#: ``long_name`` of the ``axis`` coordinate.
AXIS_LONG_NAME = "pose axis: translation tx, ty, tz (m), rotation vector rx, ry, rz (rad)"
#: Global ``Conventions`` attr of every netCDF file simgap writes.
CF_CONVENTIONS = "CF-1.10"
#: On-disk parts of an ``ERROR_UNITS`` variable: (suffix, axes, udunits string, long_name tail).
PARTS: tuple[tuple[str, tuple[str, ...], str, str], ...] = (
    ("translation", TRANSLATION_AXES, "m", "translation part (tx, ty, tz)"),
    ("rotation", ROTATION_AXES, "rad", "rotation-vector part (rx, ry, rz)"),
)
#: Suffix of the auxiliary label variable that held a string dimension coordinate in files
#: written before the labels were indexed (read back, never written).
LABEL_SUFFIX = "_label"
#: What ``cfchecks`` (cfchecker 4.1) says of a string label dimension's coordinate variable:
#: CF's data model wants coordinate variables numeric, so it is a warning, not an error.
LABEL_WARNING = "WARN: (5): Possible incorrect declaration of a coordinate variable."
_TAIL = "; "


def _is_string(values: np.ndarray) -> bool:
    return values.dtype.kind in "US" or (
        values.dtype.kind == "O" and all(isinstance(v, str) for v in values.ravel().tolist())
    )


def encode_cf(ds: xr.Dataset) -> xr.Dataset:
    """The on-disk (CF-1.10) form of a dataset; ``ds`` itself is not changed.

    Parameters
    ----------
    ds : xarray.Dataset
        A result dataset or an error-model dataset, as simgap holds it in memory.

    Returns
    -------
    xarray.Dataset
        Its CF form (module docstring), for ``to_netcdf``.
    """
    out = ds.copy()
    for variable in out.variables.values():  # xarray writes the coordinates attrs anew
        variable.encoding = {k: v for k, v in variable.encoding.items() if k != "coordinates"}
    for name in list(out.data_vars):
        da = out[name]
        if "axis" not in da.dims or da.attrs.get("units") != ERROR_UNITS:
            continue
        out = out.drop_vars(name)
        for suffix, axes, unit, tail in PARTS:
            keep = [a for a in da["axis"].values.tolist() if a in axes]
            if not keep:
                continue
            dim = f"{suffix}_axis"
            part = da.sel(axis=keep).rename(axis=dim)
            labels = (dim, part[dim].values, {"long_name": f"{suffix} axis"})
            part = part.assign_coords({dim: labels})
            long_name = da.attrs.get("long_name", name) + _TAIL + tail
            part.attrs = {**da.attrs, "units": unit, "long_name": long_name}
            part.encoding = dict(da.encoding)
            out[f"{name}_{suffix}"] = part
    if "axis" in out.coords and not any("axis" in v.dims for v in out.data_vars.values()):
        out = out.drop_vars("axis")  # every variable along it was split
    for name in list(out.coords):
        values = np.asarray(out[name].values)
        if not _is_string(values):
            continue
        coord = out[name].variable.copy()
        coord.encoding = {"dtype": "S1"}  # a char array: CF has no other string type before 1.8
        out = out.assign_coords({name: coord})
    for name in list(out.data_vars):  # 0/1 flags say what they mean (CF flag attributes)
        if out[name].dtype == bool:
            flag = out[name].variable.copy()
            flag.attrs = {
                **flag.attrs,
                "flag_values": np.array([0, 1], np.int8),
                "flag_meanings": f"not_{name} {name}",
            }
            flag.encoding = {**flag.encoding, "dtype": "int8"}
            out[name] = flag
    out.attrs["Conventions"] = CF_CONVENTIONS
    return out


def decode_cf(ds: xr.Dataset) -> xr.Dataset:
    """The in-memory form of a dataset read from a netCDF file (undoes :func:`encode_cf`)."""
    out = ds.copy()
    out.attrs.pop("Conventions", None)
    for name in list(out.data_vars):  # a boolean's flag attributes (read back as booleans)
        if out[name].attrs.get("flag_meanings") == f"not_{name} {name}":
            flags = ("flag_values", "flag_meanings")
            out[name].attrs = {k: v for k, v in out[name].attrs.items() if k not in flags}
    for name in list(out.variables):
        dim = name.removesuffix(LABEL_SUFFIX)
        if name != dim and out[name].dims == (dim,):
            values = np.asarray(out[name].values).astype(str)
            out = out.drop_vars(name).assign_coords({dim: (dim, values, out[name].attrs)})
    for name in list(out.coords):
        values = np.asarray(out[name].values)
        if values.dtype.kind in "OS" and _is_string(values.astype(str)):
            out = out.assign_coords({name: (out[name].dims, values.astype(str), out[name].attrs)})
    stems = {
        n.removesuffix(f"_{s}")
        for n in out.data_vars
        for s, *_ in PARTS
        if n.endswith(f"_{s}") and f"{s}_axis" in out[n].dims
    }
    axis_attrs = dict(out["axis"].attrs) if "axis" in out.coords else {"long_name": AXIS_LONG_NAME}
    for stem in sorted(stems):
        pieces = []
        for suffix, _, _, tail in PARTS:
            name, dim = f"{stem}_{suffix}", f"{suffix}_axis"
            if name in out.data_vars:
                pieces.append(out[name].rename({dim: "axis"}))  # its labels become axis'
                attrs = dict(out[name].attrs)
                attrs["long_name"] = attrs.get("long_name", "").removesuffix(_TAIL + tail)
                out = out.drop_vars(name)
        joined = xr.concat(pieces, dim="axis") if len(pieces) > 1 else pieces[0]
        joined.attrs = {**attrs, "units": ERROR_UNITS}
        out[stem] = joined
    out = out.drop_vars([f"{s}_axis" for s, *_ in PARTS if f"{s}_axis" in out.coords])
    if stems:  # the axis coordinate kept, or rebuilt from the parts' labels
        out["axis"].attrs = axis_attrs
    return out


def logical_names(names: set[str]) -> set[str]:
    """The in-memory names of a file's variables (``error`` for ``error_translation``, ...)."""
    out = set()
    for name in names:
        for suffix, *_ in PARTS:
            name = name.removesuffix(f"_{suffix}")
        out.add(name.removesuffix(LABEL_SUFFIX))
    return out
