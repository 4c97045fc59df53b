"""Atomic file writes: a temporary file beside the target, then :func:`os.replace`.

Every file simgap writes (cache entries, datasets, reports, capture folders, assets) goes through
:func:`atomic_write`, so a reader sees either the old file or the complete new one, never a partial
file, and two processes writing the same target at once cannot collide: each writer has its own
temporary name (host, process id and a random suffix) in the target's folder (the same file
system, so the rename is atomic). On failure the temporary file is removed and the target left
untouched. A writer killed outright (kill -9) cannot remove its temporary file; the next write
into that folder by any simgap process does (:func:`remove_stale_temporaries`: only files of a
writer on this host whose process is gone, so a writer still at work, here or on another host
sharing the folder, keeps its file).

Examples
--------
>>> atomic_write(Path("out/table.md"), "# Table 2")                        # doctest: +SKIP
>>> atomic_write(Path("x.exr"), lambda tmp: exr_file.write(str(tmp)))       # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import os
import re
import secrets
import shutil
import socket
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = [
    "atomic_copy",
    "atomic_write",
    "remove_dead_writers",
    "remove_stale_temporaries",
    "staged_path",
    "temporary_name",
    "writer_alive",
    "writer_tag",
]

#: This host, as 6 hex digits of its name's SHA-256 (writers on hosts sharing a folder differ).
HOST_TAG = hashlib.sha256(socket.gethostname().encode()).hexdigest()[:6]
#: A temporary name of :func:`temporary_name`: host tag (absent in names written before it was
#: added), process id.
_TEMPORARY = re.compile(r"^\..+\.(?:(?P<host>[0-9a-f]{6})-)?(?P<pid>\d+)-[0-9a-f]{12}\.tmp$")
#: Folders this process has already cleaned of stale temporaries.
_CLEANED: set[Path] = set()


def writer_tag() -> str:
    """``<host tag>-<pid>``: which writer on which host a temporary file or folder belongs to."""
    return f"{HOST_TAG}-{os.getpid()}"


def writer_alive(host: str | None, pid: int) -> bool:
    """Whether a writer may still be at work: on another host (unknown), or its process lives."""
    if host is not None and host != HOST_TAG:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def temporary_name(path: Path) -> Path:
    """A temporary path beside ``path``, unique to this writer.

    The name is ``.<name>.<host tag>-<pid>-<12 random hex digits>.tmp``: hidden, in the same
    folder (so the final rename stays on one file system), and ending in ``.tmp`` so that
    leftovers of a killed writer are easy to recognise (:func:`remove_stale_temporaries`).
    Writers must therefore not choose the format by the extension.
    """
    path = Path(path)
    return path.with_name(f".{path.name}.{writer_tag()}-{secrets.token_hex(6)}.tmp")


def remove_stale_temporaries(folder: Path) -> int:
    """Remove the temporary files and staging folders of dead writers in ``folder``; the count.

    A writer's leftovers are stale when it ran on this host and its process is gone
    (:func:`writer_alive`); files it cannot remove are left.
    """
    return remove_dead_writers(folder, _TEMPORARY)


def remove_dead_writers(folder: Path, names: re.Pattern[str]) -> int:
    """Remove the entries of ``folder`` that ``names`` matches and whose writer is dead.

    ``names`` matches an entry's name from its start and captures the writer's ``host`` tag
    (optional) and ``pid`` (:func:`writer_tag`); an entry is removed when :func:`writer_alive`
    says no. A file or folder that cannot be removed is left. Returns the count removed.
    """
    removed = 0
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    for entry in entries:
        match = names.match(entry.name)
        if match is None or writer_alive(match["host"], int(match["pid"])):
            continue
        try:
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path)
            else:
                os.unlink(entry.path)
            removed += 1
        except OSError:
            pass
    return removed


def _clean_once(folder: Path) -> None:
    """:func:`remove_stale_temporaries` on ``folder`` the first time this process writes there."""
    if folder not in _CLEANED:
        _CLEANED.add(folder)
        remove_stale_temporaries(folder)


def atomic_write(
    path: str | Path,
    content: bytes | str | Callable[[Path], object],
    *,
    fsync: bool = False,
    exclusive: bool = False,
) -> Path:
    """Write ``path`` atomically and return it.

    Parameters
    ----------
    path : str or Path
        The target file. Its folder must exist.
    content : bytes, str or callable
        The file's bytes, its text (written as UTF-8), or a function that writes the file at the
        temporary path it is given (for writers that need a file name: OpenEXR, netCDF, ...).
    fsync : bool
        Flush the temporary file to disk before the rename (durability across power loss; costs
        a disk sync, so caches leave it off).
    exclusive : bool
        Publish only if ``path`` does not exist yet (first writer wins: a hard link, which is
        atomic and fails on an existing target), instead of replacing it.

    Raises
    ------
    FileExistsError
        With ``exclusive``, when another writer published ``path`` first (nothing is changed).
    OSError
        If the file cannot be written; the target is then unchanged and no temporary file is
        left behind.
    """
    path = Path(path)
    _clean_once(path.parent)
    tmp = temporary_name(path)
    try:
        if callable(content):
            content(tmp)
            if not tmp.is_file():
                raise OSError(f"{path}: the writer did not create the file")
        else:
            data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
            with open(tmp, "xb") as handle:
                handle.write(data)
        if fsync:
            with open(tmp, "rb+") as handle:
                os.fsync(handle.fileno())
        if exclusive:
            _link_or_replace(tmp, path)
        else:
            os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def atomic_copy(source: str | Path, target: str | Path) -> Path:
    """Copy the bytes of the file ``source`` to ``target`` atomically; return ``target``.

    ``target``'s folder is created where missing; ``source`` is read once, as it is.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(target, Path(source).read_bytes())


def _link_or_replace(tmp: Path, path: Path) -> None:
    """Hard-link ``tmp`` to ``path`` (FileExistsError if it exists); rename where links fail."""
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise
    except OSError:  # a file system without hard links: last writer wins instead
        os.replace(tmp, path)


@contextmanager
def staged_path(path: Path) -> Iterator[Path]:
    """Yield a path that does not exist yet, in a temporary sibling folder; on success install it.

    For writers that create a folder themselves (a ROS 2 bag) or insist on a fresh path. On normal
    exit the staged file or folder replaces ``path`` (an existing folder is first moved aside and
    then deleted); on an exception nothing is installed and the temporary folder is removed.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _clean_once(path.parent)
    stage = temporary_name(path)
    stage.mkdir()
    try:
        staged = stage / path.name
        yield staged
        if path.is_dir() and not path.is_symlink():
            os.replace(path, stage / "replaced")
        os.replace(staged, path)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
