"""Experiment files on disk: the ``inherit:`` chain, its merge, and errors blamed on the right file.

An experiment file may inherit another (``inherit: smoke.yaml``, relative to it); the chain is read
root first, merged with the child winning (names and descriptions are not inherited; an effect
set to ``null`` by a child is removed: ``effects: {earthshine: null}``), and a validation error
about a key that an inherited file set is reported against that file. A file's
``rig.camera.calibration: FILE`` (relative to it) is read as the camera: a calibration file in any
format of :mod:`simgap.pipeline.capture.calibration` and any of OpenCV's models; keys beside it
override the file's.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from simgap.core.config import ConfigError, deep_merge, read_yaml, to_mapping


def read_chain(path: Path, seen: tuple[Path, ...] = ()) -> list[tuple[Path, dict[str, Any]]]:
    """An experiment file and the files it inherits from: ``(path, data)``, root ancestor first."""
    data = read_yaml(path)
    if not data:
        raise ConfigError(
            f"{path}: empty experiment file; expected a mapping of settings (at least "
            "`name: ...`; an experiment with only a name runs the full study)"
        )
    if "source" in data:
        raise ConfigError(f"{path}: source: unknown key (reserved)")
    parent = data.get("inherit")
    if parent is None:
        return [(path, data)]
    if not isinstance(parent, str):
        raise ConfigError(f"{path}: inherit: expected a file path, got {parent!r}")
    parent_path = (path.parent / parent).resolve()
    if parent_path in seen or parent_path == path.resolve():
        raise ConfigError(f"{path}: inherit: circular inheritance through {parent_path}")
    if not parent_path.is_file():
        raise ConfigError(f"{path}: inherit: {parent_path} not found")
    chain = read_chain(parent_path, seen + (path.resolve(),))
    return chain + [(path, data)]


def with_calibration_file(path: Path, data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with its ``rig.camera.calibration`` file (relative to ``path``) read as the camera.

    The whole camera comes from the file (intrinsics, model, coefficients); other keys of
    ``rig.camera`` override it. Raises ConfigError naming ``path`` and the key, or the
    calibration file and its key.
    """
    camera = _camera_section(data)
    if camera is None or "calibration" not in camera:
        return data
    from simgap.pipeline.capture import read_calibration  # the formats register on import
    from simgap.pipeline.capture.calibration import calibration_source

    name = camera["calibration"]
    if not isinstance(name, str):
        raise ConfigError(f"{path}: rig.camera.calibration: expected a file path, got {name!r}")
    file = (path.parent / name).resolve()
    if not calibration_source(file)[0].is_file():
        raise ConfigError(f"{path}: rig.camera.calibration: {file} not found")
    others = {k: v for k, v in camera.items() if k != "calibration"}
    resolved = {**camera_mapping(read_calibration(file)), **others}
    return {**data, "rig": {**data["rig"], "camera": resolved}}


def _camera_section(data: dict[str, Any]) -> dict[str, Any] | None:
    """An experiment file's ``rig.camera`` mapping, or None where it has none."""
    rig = data.get("rig")
    camera = rig.get("camera") if isinstance(rig, dict) else None
    return camera if isinstance(camera, dict) else None


def camera_mapping(camera: Any) -> dict[str, Any]:
    """Every field of a :class:`~simgap.core.rig.CameraModel`, the distortion model included."""
    out = to_mapping(camera)
    out["distortion_model"] = camera.distortion_model
    return out


def merge_chain(chain: list[tuple[Path, dict[str, Any]]]) -> dict[str, Any]:
    """The files of :func:`read_chain` merged (the last file wins; names are not inherited).

    Each file's ``rig.camera.calibration`` is read first (:func:`with_calibration_file`).
    """
    resolved = [with_calibration_file(path, data) for path, data in chain]
    merged: dict[str, Any] = {}
    for data in resolved[:-1]:
        merged = deep_merge(merged, data)
    merged.pop("name", None)
    merged.pop("description", None)
    out = deep_merge(merged, resolved[-1])
    if len(chain) > 1 and isinstance(out.get("effects"), dict):
        removed = {k for k, v in (resolved[-1].get("effects") or {}).items() if v is None}
        out["effects"] = {k: v for k, v in out["effects"].items() if k not in removed}
    return out


def calibration_files(chain: list[tuple[Path, dict[str, Any]]]) -> list[Path]:
    """The calibration files the chain's ``rig.camera.calibration`` keys name (resolved).

    A ``FILE:camN`` (one camera of a Kalibr camchain) is its ``FILE``.
    """
    from simgap.pipeline.capture.calibration import calibration_source

    out = []
    for path, data in chain:
        camera = _camera_section(data)
        if camera is not None and isinstance(camera.get("calibration"), str):
            out.append(calibration_source((path.parent / camera["calibration"]).resolve())[0])
    return out


def origins(chain: list[tuple[Path, dict[str, Any]]]) -> dict[tuple[str, ...], Path]:
    """Which file set each key path last (mappings merge, other values replace)."""
    out: dict[tuple[str, ...], Path] = {}

    def walk(data: Any, prefix: tuple[str, ...], path: Path) -> None:
        for key, value in data.items():
            out[prefix + (str(key),)] = path
            if isinstance(value, dict):
                walk(value, prefix + (str(key),), path)

    for path, data in chain:
        walk(data, (), path)
    return out


def blame_parent(
    exc: ConfigError, path: Path, origins: dict[tuple[str, ...], Path]
) -> ConfigError:
    """``exc`` reported against the inherited file that set the offending key, if not ``path``."""
    message, prefix = str(exc), f"{path}: "
    if not message.startswith(prefix):
        return exc
    rest = message[len(prefix) :]
    keys = tuple(re.findall(r"[^.\[\]]+", rest.split(": ", 1)[0]))
    for n in range(len(keys), 0, -1):
        origin = origins.get(keys[:n])
        if origin is not None:
            if origin == path:
                return exc
            blamed = ConfigError(f"{origin}: {rest} (inherited by {path})")
            blamed.__cause__ = exc.__cause__
            return blamed
    return exc
