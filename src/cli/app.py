"""The Typer app of the command line: one error path (exit code 2, one line), shared options."""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import click
import typer

from simgap.core.config import ConfigError
from simgap.core.outputs import OutputPathError

#: The app's ``--help`` text (the command line's description, unchanged from the one-module CLI).
HELP = (
    "simgap: simulate the PASS fixture study, compare rendering options, diagnose the "
    "sim-to-real gap."
    """

Commands: run, report, compare, study, ingest, export-bag, errormodel, diagnose, validate, effects,
assets.

Every error exits with code 2 and one line naming the file, key and expectation (``--debug``
shows the traceback instead). No command writes over one of its inputs or a device, and a file
simgap did not write is replaced only with ``--overwrite``.
"""
)
_STATE = {"debug": False}


def _error_line(exc: BaseException, paths: list[Path]) -> str:
    """One line for ``exc``, prefixed with the command's input file unless it names a file.

    A refused output path is never prefixed: its message starts with the option and the path.
    """
    if isinstance(exc, OSError) and exc.filename and exc.strerror:
        message = f"{exc.filename}: {exc.strerror}"
    elif isinstance(exc, (ConfigError, ValueError, OSError)):
        message = str(exc)
    elif isinstance(exc, MemoryError):
        message = "out of memory (reduce the experiment's size)"
    else:
        message = f"{type(exc).__name__}: {exc} (unexpected; rerun with --debug for the traceback)"
    named = isinstance(exc, OutputPathError) or any(str(p) in message for p in paths)
    if paths and not named:
        message = f"{paths[0]}: {message}"
    return " ".join(message.split())


def _handle_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Run a command; any error exits with code 2 and one line (the traceback with --debug)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except Exception as exc:
            if _STATE["debug"]:
                raise
            bound = inspect.signature(func).bind_partial(*args, **kwargs).arguments
            paths = [v for v in bound.values() if isinstance(v, Path)]
            fail(_error_line(exc, paths))

    return wrapper


class _App(typer.Typer):
    """A Typer app whose commands all go through :func:`_handle_errors` (one place)."""

    def command(self, *args: Any, **kwargs: Any) -> Callable[[Callable], Callable]:
        """Register a command, wrapped by :func:`_handle_errors`."""
        register = super().command(*args, **kwargs)
        return lambda func: register(_handle_errors(func))


app = _App(add_completion=False, no_args_is_help=True, help=HELP)


@app.callback()
def main(
    debug: bool = typer.Option(
        False, "--debug", help="Show the full traceback of an error instead of one line."
    ),
) -> None:
    """Simulate the PASS fixture study, compare rendering options, diagnose the sim-to-real gap."""
    _STATE["debug"] = debug


CACHE_HELP = "Cache folder for renders and results (default: $SIMGAP_CACHE or ~/.cache/simgap)."
SCHEDULER_HELP = (
    "Dask scheduler address (tcp://HOST:PORT); default: a LocalCluster on this machine. "
    "Workers must see the cache folder under the same path."
)

# Parameters several commands share, declared once (typer's ``Annotated`` form; defaults stay in
# the signatures).
#: ``--cache FOLDER`` (default ``None``: $SIMGAP_CACHE or ~/.cache/simgap).
CacheOption = Annotated[Path | None, typer.Option("--cache", help=CACHE_HELP)]
#: ``--scheduler ADDRESS`` (default ``None``: an in-process cluster).
SchedulerOption = Annotated[str | None, typer.Option("--scheduler", help=SCHEDULER_HELP)]
#: ``--progress/--no-progress`` (default ``True``).
ProgressOption = Annotated[
    bool, typer.Option("--progress/--no-progress", help="Show a progress bar.")
]
#: ``--variant NAME`` of a result dataset (default ``None``: the first).
VariantOption = Annotated[
    str | None, typer.Option("--variant", help="Variant of the dataset (default: the first).")
]


def output_option(help_text: str) -> Any:
    """The ``-o/--output PATH`` option, with what the command writes there as its help."""
    return typer.Option("-o", "--output", help=help_text)


def read_result_dataset(path: Path):
    """A result dataset (netCDF), checked against the contract (errors name the file)."""
    from simgap.results.dataset import check_dataset, read_netcdf

    return check_dataset(read_netcdf(path), path)


def fail(message: str) -> None:
    """Print ``error: message`` to stderr and exit with code 2 (the command line's one error)."""
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code=2)


def read_experiment(path: Path):
    """Load an experiment file (errors name the file and key)."""
    from simgap.pipeline.experiment import load_experiment

    return load_experiment(path)


def read_simulation(sim: Path):
    """An experiment from YAML, or the experiment a result dataset was made with."""
    from simgap.pipeline.experiment import experiment_from_yaml

    if sim.suffix in (".yaml", ".yml"):
        return read_experiment(sim)
    from simgap.results.dataset import read_netcdf

    ds = read_netcdf(sim)
    if "experiment_yaml" not in ds.attrs:
        raise ConfigError(f"{sim}: not a simgap result dataset (no experiment_yaml attribute)")
    return experiment_from_yaml(ds.attrs["experiment_yaml"], source=str(sim))
