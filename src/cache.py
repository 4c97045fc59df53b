"""Content-addressed cache of renders, frames and per-configuration results.

Keys are SHA-256 hashes of everything that affects a product (settings, rig, scene, assets, code
version), so rerunning an experiment reuses finished work and an interrupted sweep resumes. Every
file is written atomically (temporary file + rename).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from simgap.atomic import atomic_write
from simgap.config import to_mapping

#: Bump when a change to the code changes renders or results for the same settings.
PIPELINE_VERSION = "1"


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

    def load_arrays(self, kind: str, key: str) -> dict[str, np.ndarray] | None:
        """Load a cached ``.npz`` product, or None when absent or unreadable."""
        path = self.path(kind, key, ".npz")
        if not path.is_file():
            return None
        try:
            with np.load(path) as data:
                return {k: data[k] for k in data.files}
        except (OSError, ValueError):
            return None

    def save_arrays(self, kind: str, key: str, arrays: dict[str, np.ndarray]) -> None:
        """Store arrays as ``.npz``, atomically."""

        def write(tmp: Path) -> None:
            with open(tmp, "xb") as handle:  # a handle: np.savez would append .npz to a name
                np.savez(handle, **arrays)

        atomic_write(self.path(kind, key, ".npz"), write)


def write_text(path: Path, text: str) -> None:
    """Write a text file atomically."""
    atomic_write(Path(path), text)
