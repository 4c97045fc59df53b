"""Content-addressed cache of renders, frames and per-configuration results.

Keys are SHA-256 hashes of everything that affects a product (settings, rig, scene, assets, code
version), so rerunning an experiment reuses finished work and an interrupted sweep resumes. Every
file is written atomically (:func:`simgap.core.atomic.atomic_write`: a temporary name unique to the
writer, then a rename), so processes sharing a cache never see each other's partial files. An
entry that cannot be read (truncated or corrupt) is moved aside as ``<name>.corrupt``, reported by
a :class:`CacheWarning` and recomputed (:meth:`Cache.read`).
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from simgap.core.atomic import atomic_write
from simgap.core.config import to_mapping

T = TypeVar("T")


class CacheWarning(UserWarning):
    """A cache entry was corrupt (truncated or unreadable); it was moved aside and recomputed."""


#: Bump when a change to the code changes renders or results for the same settings.
PIPELINE_VERSION = "2"  # 2: lights picked by their irradiance (sampling_weight)


def content_hash(*parts: Any) -> str:
    """SHA-256 hex digest of JSON-serialisable parts (dataclasses and numpy values allowed)."""

    def default(o: Any) -> Any:
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.generic):
            return o.item()
        return str(o)

    text = json.dumps([PIPELINE_VERSION, *map(to_mapping, parts)], sort_keys=True, default=default)
    return hashlib.sha256(text.encode()).hexdigest()


def file_hash(paths: list[Path]) -> str:
    """SHA-256 of the contents of files (e.g. assets), in the given order."""
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()


class Cache:
    """A folder of cached products, by kind and key: ``ROOT/<kind>/<key[:2]>/<key><suffix>``."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    def path(self, kind: str, key: str, suffix: str) -> Path:
        """Path of a product (its folder is created)."""
        folder = self.root / kind / key[:2]
        folder.mkdir(parents=True, exist_ok=True)
        return folder / f"{key}{suffix}"

    def read(self, path: Path, reader: Callable[[Path], T]) -> T | None:
        """Read a cached file with ``reader``; None when absent or corrupt.

        Any error of ``reader`` (a truncated ``.npz``, ``.png``, ``.json`` or ``.exr`` raises
        ``BadZipFile``, ``EOFError``, ``ValueError``, ``RuntimeError``, ``JSONDecodeError``...)
        means the entry is corrupt: it is moved aside (:func:`quarantine`) with a
        :class:`CacheWarning` and None is returned, so the caller recomputes and rewrites it.
        """
        if not path.is_file():
            return None
        try:
            return reader(path)
        except FileNotFoundError:
            return None  # moved aside by another process in the meantime
        except Exception as exc:  # any decoder error: the entry is corrupt
            quarantine(path, f"{type(exc).__name__}: {exc}")
            return None

    def load_arrays(self, kind: str, key: str) -> dict[str, np.ndarray] | None:
        """Load a cached ``.npz`` product, or None when absent or corrupt (see :meth:`read`)."""
        return self.read(self.path(kind, key, ".npz"), _load_npz)

    def save_arrays(self, kind: str, key: str, arrays: dict[str, np.ndarray]) -> None:
        """Store arrays as ``.npz``, atomically."""

        def write(tmp: Path) -> None:
            with open(tmp, "xb") as handle:  # a handle: np.savez would append .npz to a name
                np.savez(handle, **arrays)

        atomic_write(self.path(kind, key, ".npz"), write)


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}  # reads (and CRC-checks) every member


def quarantine(path: Path, why: str) -> Path:
    """Move a corrupt cache file aside as ``<name>.corrupt`` and warn; return the new path."""
    aside = path.with_name(path.name + ".corrupt")
    try:
        os.replace(path, aside)
    except FileNotFoundError:
        pass  # another process moved it aside (or replaced it) first
    warnings.warn(
        f"{path}: corrupt cache entry ({why}); moved aside to {aside.name}, recomputing",
        CacheWarning,
        stacklevel=3,
    )
    return aside


def write_text(path: Path, text: str) -> None:
    """Write a text file atomically."""
    atomic_write(Path(path), text)
