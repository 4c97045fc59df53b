"""The Typer app of the command line: one error path (exit code 2, one line), plain help.

Help is plain text: no markup, no type shown against a flag, arguments in capitals in the usage
line (:class:`_PlainHelp`); ``-h`` is ``--help`` everywhere; ``--version`` and shell completion
(``--install-completion``, ``--show-completion SHELL``) are on the app. The options several
commands share are in :mod:`simgap.cli.options`.
"""

from __future__ import annotations

import functools
import inspect
import os
import re
import sys
import warnings
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

from simgap.core.config import ConfigError
from simgap.core.outputs import OutputPathError

#: The app's ``--help`` text (plain: one paragraph per line, rich wraps them).
HELP = "\n\n".join(
    [
        "simgap: simulate the PASS fixture study, compare rendering options, diagnose the "
        "sim-to-real gap.",
        "Every error exits with code 2 and one line naming the file, key and expectation "
        "(--debug shows the traceback instead). No command writes over one of its inputs or a "
        "device, and a file simgap did not write is replaced only with --overwrite.",
        "Shell completion: simgap --install-completion, then open a new shell (simgap "
        "--show-completion prints the script instead).",
    ]
)
#: ``-h`` and ``--help`` on the app and every command.
CONTEXT_SETTINGS = {"help_option_names": ["-h", "--help"]}
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
        except (typer.Exit, typer.Abort, typer.TyperException):
            raise
        except BrokenPipeError:  # the reader went away (``simgap effects | head``): stop quietly
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # no second error when Python flushes stdout
            raise typer.Exit(code=0) from None
        except Exception as exc:
            if _STATE["debug"]:
                raise
            bound = inspect.signature(func).bind_partial(*args, **kwargs).arguments
            paths = [v for v in bound.values() if isinstance(v, Path)]
            fail(_error_line(exc, paths))

    return wrapper


#: A numpydoc section heading (``Parameters`` over a dashed line): help ends before it.
_SECTION = re.compile(r"^\s*[A-Z][A-Za-z ]+\n\s*-{3,}\s*$", re.MULTILINE)
#: A Sphinx cross-reference role, e.g. ``:class:`~simgap.x.Y```: its target is kept.
_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")
#: Literal text in double backticks: the text is kept.
_LITERAL = re.compile(r"``([^`]+)``")


def plain_help(text: str | None) -> str | None:
    """A docstring as plain help: its text before any numpydoc section, without markup.

    Sphinx roles and double backticks are dropped (their text is kept), and the lines of each
    paragraph are joined, so that the terminal wraps them.
    """
    if text is None:
        return None
    text = _SECTION.split(inspect.cleandoc(text), maxsplit=1)[0]
    text = _LITERAL.sub(r"\1", _ROLE.sub(r"\1", text))
    return "\n\n".join(" ".join(p.split()) for p in text.split("\n\n") if p.strip())


class _PlainHelp:
    """Help in the usual command-line style (a mixin of typer's command and group classes).

    The help text is :func:`plain_help`; a flag shows no type (typer writes ``<bool>`` against
    it) and the usage line names the arguments in capitals, optional ones in brackets (typer
    writes ``{experiment}``).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.help = plain_help(self.help)
        if self.help and not self.short_help:  # the command list shows it whole, wrapped
            self.short_help = self.help.split("\n\n")[0]

    def get_params(self, ctx: Any) -> list:
        """The parameters, flags without a type label."""
        params = super().get_params(ctx)  # type: ignore[misc]
        for param in params:
            if isinstance(param, TyperOption) and param.is_flag and param.metavar is None:
                param.metavar = ""
        return params

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        """The usage line's pieces, each argument as ``NAME`` (required) or ``[NAME]``."""
        plain = {}
        for param in self.get_params(ctx):
            if isinstance(param, TyperArgument):
                name = (param.metavar or param.name or "").upper()
                name = (name if param.required else f"[{name}]") + ("..." * (param.nargs != 1))
                plain.update((piece, name) for piece in param.get_usage_pieces(ctx))
        pieces = super().collect_usage_pieces(ctx)  # type: ignore[misc]
        return [plain.get(piece, piece) for piece in pieces]


class _Command(_PlainHelp, TyperCommand):
    """A command with plain help (:class:`_PlainHelp`)."""


class _Group(_PlainHelp, TyperGroup):
    """The app's group with plain help (:class:`_PlainHelp`)."""


class _App(typer.Typer):
    """A Typer app whose commands all go through :func:`_handle_errors` and have plain help."""

    def command(self, *args: Any, **kwargs: Any) -> Callable[[Callable], Callable]:
        """Register a command, wrapped by :func:`_handle_errors`."""
        kwargs.setdefault("cls", _Command)
        register = super().command(*args, **kwargs)
        return lambda func: register(_handle_errors(func))


#: Plain help and one-line usage errors (typer's rich mode boxes both and reads markup in them).
app = _App(
    cls=_Group,
    no_args_is_help=True,
    help=HELP,
    context_settings=CONTEXT_SETTINGS,
    rich_markup_mode=None,
)


def package_version() -> str:
    """The installed simgap package's version (its metadata)."""
    try:
        return version("simgap")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown"


def _print_version(value: bool) -> None:
    """``--version``: print ``simgap X.Y.Z`` and exit 0."""
    if value:
        typer.echo(f"simgap {package_version()}")
        raise typer.Exit()


@app.callback()
def main(
    debug: bool = typer.Option(
        False, "--debug", help="Show the full traceback of an error instead of one line."
    ),
    show_version: bool = typer.Option(
        False,
        "--version",
        callback=_print_version,
        is_eager=True,
        help="Print simgap's version and exit.",
    ),
) -> None:
    """Simulate the PASS fixture study, compare rendering options, diagnose the sim-to-real gap."""
    _STATE["debug"] = debug
    if not debug:
        warnings.formatwarning = _warning_line


def _warning_line(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    line: str | None = None,
) -> str:
    """A warning as one line, ``warning: MESSAGE`` (``--debug`` keeps Python's file and line)."""
    return f"warning: {message}\n"


def read_result_dataset(path: Path):
    """A result dataset (netCDF), checked against the contract (errors name the file)."""
    from simgap.results.contract import check_dataset
    from simgap.results.dataset import read_netcdf

    return check_dataset(read_netcdf(path), path)


def fail(message: str) -> None:
    """Print ``error: message`` to stderr and exit with code 2 (the command line's one error)."""
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code=2)


def read_experiment(path: Path, calibration: Path | None = None):
    """Load an experiment file (errors name the file and key), its camera from ``calibration``."""
    from simgap.pipeline.experiment import load_experiment, with_calibration

    exp = load_experiment(path)
    return exp if calibration is None else with_calibration(exp, calibration)


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
