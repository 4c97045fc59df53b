"""Run the CF conventions checker (``cfchecks`` of the pypi package cfchecker 4.1) offline.

:func:`cf_check` runs it in a subprocess (this file as a script) on one netCDF file and returns
its counts and output. Offline it needs two things it would otherwise look up or download:

- the UDUNITS-2 C library that cfunits loads through ``ctypes.util.find_library``: the copy the
  cf-units wheel bundles (``cf_units.libs/``), with its unit tables (``UDUNITS2_XML_PATH``);
- the CF standard name, area type and region tables: the small ones in ``tests/data/cf/``, which
  hold only what simgap writes (nothing: simgap writes no ``standard_name``, area type or region).

cfchecker 4.1.0 (2021) knows CF versions up to 1.8. simgap's files declare ``CF-1.10`` and use
nothing that CF 1.9 or 1.10 added, so the script adds 1.10 to the versions the checker knows and
checks against it: every rule the checker has (those of CF-1.8) applies, and the checker neither
rejects the ``Conventions`` value nor warns that it differs from the checked version.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

TABLES = Path(__file__).resolve().parent / "data" / "cf"
#: The CF version simgap's files declare (global ``Conventions`` attr) and are checked against.
CF_VERSION = (1, 10)
_COUNT = re.compile(r"^(FATAL ERRORS|ERRORS detected|WARNINGS given|INFORMATION messages): (\d+)$")


@dataclass(frozen=True)
class CFReport:
    """What ``cfchecks`` said about one file: counts per category and its whole output."""

    fatal: int
    errors: int
    warnings: int
    info: int
    output: str

    def summary(self) -> str:
        """One line: the counts."""
        counts = (self.fatal, self.errors, self.warnings, self.info)
        return "{} fatal, {} errors, {} warnings, {} info".format(*counts)


def cf_check(path: Path, timeout_s: float = 120.0) -> CFReport:
    """Run ``cfchecks`` (CF-1.10, the tables in ``tests/data/cf/``) on ``path`` in a subprocess."""
    cmd = [
        sys.executable,
        __file__,
        "-s", str(TABLES / "standard-name-table.xml"),
        "-a", str(TABLES / "area-type-table.xml"),
        "-r", str(TABLES / "standardized-region-list.xml"),
        "-v", ".".join(map(str, CF_VERSION)),
        str(path),
    ]  # fmt: skip
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, check=False)
    output = run.stdout + run.stderr
    counts = {"FATAL ERRORS": 0}
    for line in output.splitlines():
        match = _COUNT.match(line.strip())
        if match:
            counts[match[1]] = int(match[2])
    if "ERRORS detected" not in counts:  # the checker crashed before its summary
        raise RuntimeError(f"cfchecks on {path} gave no summary (exit {run.returncode}):\n{output}")
    return CFReport(
        fatal=counts["FATAL ERRORS"],
        errors=counts["ERRORS detected"],
        warnings=counts["WARNINGS given"],
        info=counts["INFORMATION messages"],
        output=output,
    )


def label_dimensions(path: Path) -> int:
    """How many dimensions of ``path`` have a char-array (string label) coordinate variable."""
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        return sum(
            1 for name, var in nc.variables.items() if name in nc.dimensions and var.dtype == "S1"
        )


def _variables(group, prefix: str = ""):
    """``(name, variable)`` of every variable of a netCDF group and of the groups in it.

    A variable of a group is named by its path, ``group/name``.
    """
    for name, var in group.variables.items():
        yield prefix + name, var
    for name, child in group.groups.items():
        yield from _variables(child, f"{prefix}{name}/")


def missing_metadata(path: Path) -> list[str]:
    """Variables of ``path``, in any group, without a ``long_name``; numeric ones without ``units``.

    Flags (``flag_values``) have no units, as CF's flags; char arrays (labels) hold no quantity.
    ``cfchecks`` asks for neither a long_name nor units on every variable; simgap's files have both.
    """
    import netCDF4

    out = []
    with netCDF4.Dataset(path) as nc:
        for name, var in _variables(nc):
            attrs = set(var.ncattrs())
            if "long_name" not in attrs:
                out.append(f"{name}: no long_name")
            numeric = var.dtype != "S1" and var.dtype.kind in "iuf"
            if numeric and "units" not in attrs and "flag_values" not in attrs:
                out.append(f"{name}: no units")
    return out


def assert_cf_valid(path: Path) -> CFReport:
    """Assert that ``cfchecks`` finds no fatal error, no error and no warning in ``path``...

    ... but one per string label dimension: simgap writes the labels as the dimension's
    coordinate variable (a char array) so that plain xarray indexes them, which CF's data model
    (numeric coordinate variables) warns about (:data:`simgap.results.cf.LABEL_WARNING`).
    """
    from simgap.results.cf import LABEL_WARNING

    report = cf_check(path)
    lines = report.output.splitlines()
    problems = [
        line
        for line in lines
        if line.startswith(("FATAL", "ERROR", "WARN")) and line != LABEL_WARNING
        and not line.startswith(("ERRORS detected", "WARNINGS given", "FATAL ERRORS"))
    ]  # fmt: skip
    assert (report.fatal, report.errors) == (0, 0) and not problems, "\n".join(problems)
    assert lines.count(LABEL_WARNING) == report.warnings == label_dimensions(path)
    assert not missing_metadata(path), missing_metadata(path)
    return report


def _main() -> None:
    """``cfchecks`` with the bundled UDUNITS-2 library and CF-1.10 among the known versions."""
    import ctypes.util
    import importlib.util

    root = Path(importlib.util.find_spec("cf_units").origin).parent
    library = next((root.parent / "cf_units.libs").glob("libudunits2*"))
    os.environ.setdefault("UDUNITS2_XML_PATH", str(root / "etc" / "share" / "udunits2.xml"))
    find_library = ctypes.util.find_library
    ctypes.util.find_library = lambda name: (
        str(library) if name == "udunits2" else find_library(name)
    )
    from cfchecker import cfchecks

    version = cfchecks.CFVersion(CF_VERSION)
    if version not in cfchecks.cfVersions:
        cfchecks.cfVersions.append(version)
    sys.argv = ["cfchecks", *sys.argv[1:]]
    cfchecks.main()


if __name__ == "__main__":
    _main()
