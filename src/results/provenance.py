"""Which netCDF files on disk simgap wrote: their header's provenance attrs, read without the data.

A command may replace its own earlier output but not a file simgap did not write
(:mod:`simgap.core.outputs`); these readers tell the two apart from the file's header.
"""

from __future__ import annotations

from pathlib import Path

from simgap.results.cf import logical_names
from simgap.results.contract import REQUIRED

#: First bytes of a netCDF-4 (HDF5) file and of the classic netCDF formats (CDF-1, -2, -5).
NETCDF_SIGNATURES = (b"\x89HDF\r\n\x1a\n", b"CDF\x01", b"CDF\x02", b"CDF\x05")
#: The attr every file simgap writes as netCDF carries (result datasets, error models).
PROVENANCE_ATTR = "simgap_version"


def netcdf_header(path: Path) -> tuple[dict[str, object], set[str]] | None:
    """The global attrs and variable names of a netCDF file, or None when it is not one.

    Only the header is read (the netCDF library reads no variable's data to list them).
    """
    import netCDF4

    try:
        with open(path, "rb") as handle:
            if not handle.read(8).startswith(NETCDF_SIGNATURES):
                return None
        with netCDF4.Dataset(path, "r") as nc:
            return {k: nc.getncattr(k) for k in nc.ncattrs()}, set(nc.variables)
    except OSError:
        return None


def result_dataset_attrs(path: Path) -> dict[str, object] | None:
    """The global attrs of a result dataset simgap wrote, or None for any other file.

    simgap's: the provenance attr and every required variable (only the header is read).
    """
    header = netcdf_header(path)
    if header is None:
        return None
    attrs, variables = header
    ours = PROVENANCE_ATTR in attrs and set(REQUIRED) <= logical_names(variables)
    return attrs if ours else None


def is_result_dataset_file(path: Path) -> bool:
    """Whether ``path`` is a result dataset simgap wrote (provenance attr, required variables)."""
    return result_dataset_attrs(path) is not None
