"""Where the project's data folders live (repository checkout or ``SIMGAP_ROOT``)."""

from __future__ import annotations

import os
from pathlib import Path

#: A capture folder's layout (docs/conventions.md §3): its calibration, its manifest and the
#: folder of its frames.
CALIBRATION_FILE = "camera.yaml"
MANIFEST_FILE = "manifest.csv"
IMAGES_DIR = "images"


def resolved(path: Path) -> Path:
    """``path`` with its symbolic links resolved; a link loop raises OSError.

    ``Path.resolve`` raises RuntimeError for a loop before Python 3.13 (OSError after): callers
    catch one error type.
    """
    try:
        return Path(path).resolve()
    except RuntimeError as exc:
        raise OSError(f"symbolic link loop ({exc})") from None


def project_root() -> Path:
    """Return the folder holding ``assets/``, ``mitsuba_scenes/`` and ``experiments/``.

    ``SIMGAP_ROOT`` wins; otherwise the repository checkout this package was installed from
    (editable install, as the README's set-up does).
    """
    env = os.environ.get("SIMGAP_ROOT")
    return Path(env) if env else Path(__file__).resolve().parents[2]


def assets_dir() -> Path:
    """Folder of fixture meshes and tag textures."""
    return project_root() / "assets"


def scenes_dir() -> Path:
    """Folder of scene templates."""
    return project_root() / "mitsuba_scenes"


def default_cache_dir() -> Path:
    """Cache of renders and results: ``SIMGAP_CACHE`` or ``~/.cache/simgap``."""
    env = os.environ.get("SIMGAP_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "simgap"
