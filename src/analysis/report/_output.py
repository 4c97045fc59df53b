"""Writing report files: PNG figures and text, each replaced atomically."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import IO, Final

from matplotlib.figure import Figure

from simgap.core.atomic import atomic_write

FIGURE_DPI: Final[int] = 110
"""Resolution of the written PNG figures, in dots per inch."""


def _write_binary(path: Path, write: Callable[[IO[bytes]], object]) -> Path:
    """Write a file through :func:`~simgap.core.atomic.atomic_write` (binary handle)."""

    def to_file(tmp: Path) -> None:
        with open(tmp, "xb") as handle:
            write(handle)

    return atomic_write(path, to_file)


def save_figure(fig: Figure, path: Path) -> Path:
    """Write ``fig`` as a PNG at :data:`FIGURE_DPI` to ``path`` atomically; return the path."""
    return _write_binary(path, lambda handle: fig.savefig(handle, format="png", dpi=FIGURE_DPI))


def save_text(text: str, path: Path) -> Path:
    """Write ``text`` as UTF-8 to ``path`` atomically; return the path."""
    return _write_binary(path, lambda handle: handle.write(text.encode("utf-8")))
