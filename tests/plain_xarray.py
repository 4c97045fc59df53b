"""Select every label of a netCDF file by name in a process that imports only xarray.

What a user's notebook cell does without simgap installed (issue 53):
``xr.open_dataset(path).sel(translation_axis="ty")``. :func:`assert_plain_selection` runs such a
cell in a subprocess and checks that simgap was never imported there.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import netCDF4

CELL = """
import json, sys
import xarray as xr
ds = xr.open_dataset(sys.argv[1])
for dim, labels in json.loads(sys.argv[2]).items():
    for label in labels:
        ds.sel({dim: label})
assert not any(name.startswith("simgap") for name in sys.modules)
print(len(ds.indexes))
"""


def string_labels(path: Path) -> dict[str, list[str]]:
    """Each dimension of ``path`` with a char-array coordinate variable: its labels."""
    with netCDF4.Dataset(path) as nc:
        out = {}
        for name, var in nc.variables.items():
            if name in nc.dimensions and var.dtype == "S1":
                var.set_auto_chartostring(True)
                out[name] = [str(v) for v in var[:]]
        return out


def assert_plain_selection(path: Path, expected: set[str]) -> None:
    """Plain xarray selects every label of ``path`` by name; its label dims include ``expected``."""
    labels = string_labels(path)
    assert expected <= set(labels), (sorted(labels), sorted(expected))
    run = subprocess.run(
        [sys.executable, "-c", CELL, str(path), json.dumps(labels)],
        capture_output=True, text=True, check=False, cwd=Path(path).parent,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
