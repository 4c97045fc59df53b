"""simgap: simulate the PASS fixture study, compare rendering options, diagnose the sim-to-real gap.

Commands: run, report, compare, study, ingest, calibrate, camera-response, export-bag,
errormodel, diagnose, report-diagnosis, validate, report-validation, effects, assets.

Every error exits with code 2 and one line naming the file, key and expectation (``--debug``
shows the traceback instead).

Modules: :mod:`.app` (the Typer app, its error path and plain help), :mod:`.options` (the options
several commands share, each defined once), :mod:`.progress` (the diagnosis's step bars), then
the commands by job, registered in the order ``--help`` lists them: :mod:`.simulate`,
:mod:`.real`, :mod:`.diagnose`, :mod:`.catalogue`.
"""

from __future__ import annotations

from simgap.cli.app import app

# Command modules register their commands on import, in the order ``--help`` lists them.
# isort: split
from simgap.cli import simulate  # noqa: F401

# isort: split
from simgap.cli import real  # noqa: F401

# isort: split
from simgap.cli import diagnose  # noqa: F401

# isort: split
from simgap.cli import catalogue  # noqa: F401

__all__ = ["app"]
