"""Atomic file and folder writes: a uniquely named temporary sibling, then a rename.

A reader never sees a half-written file or folder: it sees the old one or the new one.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path


def write_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (parent folders are created); return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


@contextmanager
def staged_path(path: Path) -> Iterator[Path]:
    """Yield a path that does not exist yet, in a temporary sibling folder; on success install it.

    The body writes a file or a folder at the yielded path (e.g. a ROS 2 bag writer, which
    insists on creating its folder itself). On normal exit it replaces ``path`` (a file, or a
    folder which is first moved aside and then deleted); on an exception nothing is installed
    and the temporary folder is removed.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp"))
    try:
        staged = stage / path.name
        yield staged
        if path.is_dir() and not path.is_symlink():
            old = stage / "replaced"
            os.replace(path, old)
        os.replace(staged, path)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def write_with(path: Path, write: Callable[[Path], None]) -> Path:
    """Let ``write(tmp)`` write a file at a temporary path, then rename it to ``path``."""
    with staged_path(path) as tmp:
        write(tmp)
    return Path(path)
