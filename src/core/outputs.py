"""Output paths, checked before a command works: what it writes never destroys what it reads.

Every write replaces its target atomically (:mod:`simgap.core.atomic`), which makes partial files
impossible but would also replace whatever sits at the target. So every command checks each path
it will write with :func:`check_output` before any work, and refuses (:class:`OutputPathError`,
naming the option and the path):

- a target that is one of the command's inputs (the same file after resolving symbolic links,
  or a hard link to it), or lies inside an input folder (a capture folder or ROS 2 bag being
  read), or, for an output that replaces a whole folder, holds an input;
- a target that exists and is not what the command writes: a device, FIFO or socket (``-o
  /dev/null`` would otherwise replace the device node with a regular file), a folder where a
  file is expected, a file where a folder is expected, or a path below a file;
- unless ``overwrite`` is given, an existing file simgap did not write (``OutputKind.is_ours``
  recognises the kind the command writes, by its simgap provenance), or a folder of files
  holding files simgap did not write.

Folders of files (report, diagnosis, comparison and validation folders, kept capture folders) are
written file by file, atomically, into a folder that simgap marks as its own with
:data:`OUTPUT_MARKER` (:func:`claim_folder`, :func:`claimed_folder`): a new or empty folder, or
one holding the marker, is simgap's; any other needs ``overwrite``. Files are written one by one
rather than the whole folder staged and renamed because a validation resumes from the trial files
already in its folder and several shards write into one folder at once, and because ``report``,
``compare`` and ``report --model`` add files to the same folder.

Examples
--------
>>> kind = OutputKind("result dataset (netCDF)", is_ours=lambda p: False)
>>> check_output(Path("e.yaml"), "-o/--output", kind, [("EXPERIMENT", Path("e.yaml"))])
Traceback (most recent call last):
OutputPathError: -o/--output e.yaml: is the input EXPERIMENT e.yaml; writing it would destroy it
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from simgap.core.atomic import atomic_write
from simgap.core.config import ConfigError
from simgap.core.paths import resolved

__all__ = [
    "OUTPUT_MARKER",
    "OutputKind",
    "OutputPathError",
    "check_output",
    "claim_folder",
    "claimed_folder",
]

#: The file that marks a folder of files as simgap's output (written by :func:`claim_folder`).
OUTPUT_MARKER = ".simgap-output"
_MARKER_TEXT = (
    "This folder is an output of simgap. simgap replaces the files it writes here (each one\n"
    "atomically) and leaves other files alone; it refuses to write into a folder that holds\n"
    "files without this marker unless given --overwrite.\n"
)
#: What a file of each type is called in a refusal (``stat`` mode tests, in order).
_FILE_TYPES = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISREG, "a file"),
)


class OutputPathError(ConfigError):
    """An output path would destroy an input, a device or a file simgap did not write."""


@dataclass(frozen=True)
class OutputKind:
    """What a command writes at an output path.

    Attributes
    ----------
    what : str
        Its name in messages, e.g. ``"result dataset (netCDF)"``.
    folder : bool
        The output is a folder (else a file).
    is_ours : callable, optional
        Whether an existing output (a regular file, or a folder for ``folder``) is the kind the
        command writes, written by simgap: an earlier output it may replace. ``None`` for a
        folder of files: simgap's when new, empty or marked with :data:`OUTPUT_MARKER`.
    replaced_whole : bool
        Writing replaces the whole folder (a ROS 2 bag): no input may lie inside it, and a
        folder that is not simgap's is refused even with ``--overwrite``.
    names : tuple of str
        The entries the command writes in the folder (a capture's ``camera.yaml``, ...): in a
        folder that is not simgap's, an existing one is refused even with ``--overwrite``, which
        writes beside a user's files and replaces none.
    suffixes : tuple of str
        The file name endings of the format written (``.nc``, ...): another is refused, so a
        file's name says what it holds (none: any name).
    """

    what: str
    folder: bool = False
    is_ours: Callable[[Path], bool] | None = None
    replaced_whole: bool = False
    names: tuple[str, ...] = ()
    suffixes: tuple[str, ...] = ()


def _file_type(mode: int) -> str:
    """``"a FIFO (named pipe)"``, ``"a folder"``, ... for a ``st_mode``."""
    return next((name for test, name in _FILE_TYPES if test(mode)), "not a regular file")


def _same(a: Path, b: Path) -> bool:
    """Whether two existing paths are one file (symbolic or hard links included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _resolve(path: Path, refuse: Callable[[str], None]) -> Path:
    """``path`` with symbolic links resolved (a link loop is refused)."""
    try:
        return resolved(path)
    except OSError as exc:
        refuse(f"cannot resolve the path ({exc})")
        raise  # not reached: refuse raises


def _check_inputs(
    path: Path, refuse: Callable[[str], None], kind: OutputKind, inputs: Iterable
) -> None:
    """Refuse ``path`` when it is, lies inside or (for a replaced folder) holds an input."""
    target = _resolve(path, refuse)
    for label, source in inputs:
        if source is None:
            continue
        source = Path(source)
        try:
            real = resolved(source)
        except OSError:  # a link loop: the command's own reading names it
            continue
        if target == real or (path.exists() and source.exists() and _same(path, source)):
            how = " (through a symbolic link)" if path.is_symlink() else ""
            refuse(f"is the input {label} {source}{how}; writing it would destroy it")
        if source.is_dir() and target.is_relative_to(real):
            refuse(f"lies inside the input {label} {source}, which this command reads")
        if kind.replaced_whole and real.is_relative_to(target):
            refuse(f"holds the input {label} {source}, which replacing the folder would delete")


def _folder_is_ours(folder: Path) -> bool:
    """A folder of files simgap may write into: empty, or marked with :data:`OUTPUT_MARKER`."""
    return (folder / OUTPUT_MARKER).is_file() or next(folder.iterdir(), None) is None


def check_output(
    path: Path,
    option: str,
    kind: OutputKind,
    inputs: Iterable[tuple[str, Path | None]] = (),
    overwrite: bool = False,
) -> Path:
    """Check an output path before any work; return it.

    Parameters
    ----------
    path : Path
        The path the command will write.
    option : str
        The option that names it, for messages (``"-o/--output"``, ``"--json"``).
    kind : OutputKind
        What the command writes there.
    inputs : iterable of (str, Path or None)
        The command's inputs, each with the argument or option that names it (``None`` paths are
        skipped): files the output may not be, folders (captures, bags) it may not lie in.
    overwrite : bool
        Replace an existing file, or write into a folder, that simgap did not write.

    Raises
    ------
    OutputPathError
        One line, ``OPTION PATH: why``: the path is an input, lies inside an input folder, holds
        an input that would be deleted, lies below a file, exists and is not a regular file
        (device, FIFO, socket, folder) where a file is expected or not a folder where one is
        expected, or, without ``overwrite``, exists and was not written by simgap.
    """
    path = Path(path)

    def refuse(why: str) -> None:
        raise OutputPathError(f"{option} {path}: {why}")

    _check_inputs(path, refuse, kind, inputs)
    below = next((p for p in _resolve(path, refuse).parents if p.exists() and not p.is_dir()), None)
    if below is not None:
        refuse(f"{below} is {_file_type(below.stat().st_mode)}, not a folder")
    if path.exists():
        _check_existing(path, kind, overwrite, refuse)
    if kind.suffixes and path.suffix.lower() not in kind.suffixes:
        refuse(
            f"expected a name ending in {' or '.join(kind.suffixes)} (the {kind.what} is written "
            f"in that format), got {path.name!r}"
        )
    return path


def _check_existing(
    path: Path, kind: OutputKind, overwrite: bool, refuse: Callable[[str], None]
) -> None:
    """Refuse an existing output of the wrong type, or one simgap may not replace."""
    mode = path.stat().st_mode
    expected = stat.S_ISDIR(mode) if kind.folder else stat.S_ISREG(mode)
    if not expected:
        refuse(
            f"is {_file_type(mode)}; expected {'a folder' if kind.folder else 'a file'} "
            f"(the {kind.what} to write)"
        )
    if kind.replaced_whole and kind.is_ours is not None and not kind.is_ours(path):
        # writing replaces the whole folder: --overwrite never deletes a user's files
        refuse(
            f"holds files simgap did not write, and a {kind.what} replaces its whole folder; "
            "choose a new or empty folder (--overwrite does not delete a user's files)"
        )
    taken = [n for n in kind.names if (path / n).exists()] if kind.folder else []
    if taken and kind.is_ours is None and not _folder_is_ours(path):
        refuse(
            f"holds {', '.join(taken)} that simgap did not write, which the {kind.what} would "
            "replace; choose a new or empty folder (--overwrite does not replace a user's files)"
        )
    if overwrite:
        return
    if kind.is_ours is None and not _folder_is_ours(path):
        refuse(
            f"holds files simgap did not write (no {OUTPUT_MARKER}); choose a new or empty "
            "folder, or pass --overwrite to write into it"
        )
    if kind.is_ours is not None and not kind.is_ours(path):
        refuse(f"exists and is not a simgap {kind.what}; pass --overwrite to replace it")


def claim_folder(folder: Path) -> Path:
    """Create an output folder (and its parents) and mark it as simgap's; return it.

    Call after :func:`check_output` accepted the folder, just before the first write. Processes
    that claim one folder at once (validation shards) each write the same marker atomically.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    marker = folder / OUTPUT_MARKER
    if not marker.is_file():
        atomic_write(marker, _MARKER_TEXT)
    return folder


@contextmanager
def claimed_folder(folder: Path) -> Iterator[Path]:
    """:func:`claim_folder` for the writes of a ``with`` block.

    When the block fails before writing anything into a folder this call created, the folder is
    removed again: a refused dataset or setting leaves no output behind.
    """
    folder = Path(folder)
    created = not folder.exists()
    claim_folder(folder)
    try:
        yield folder
    except BaseException:
        if created and [p.name for p in folder.iterdir()] == [OUTPUT_MARKER]:
            (folder / OUTPUT_MARKER).unlink()
            folder.rmdir()
        raise
