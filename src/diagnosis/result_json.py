"""``result.json``: plain-JSON conversion and the atomic write."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from simgap.core.atomic import atomic_write


def jsonable(obj: Any) -> Any:
    """``obj`` with numpy scalars and arrays (and tuples) turned into plain Python for JSON."""
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    return obj


def write_json(result: dict[str, Any], path: Path) -> Path:
    """Write ``result`` (e.g. ``result.json``, ``validation.json``) atomically; return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, json.dumps(jsonable(result), indent=2))
