"""Strict loading of YAML into frozen dataclasses.

Every error names the file, the key path and what was expected, e.g.::

    experiments/smoke.yaml: render.spp: expected an integer >= 1, got 0

Dataclasses validate their own ranges in ``__post_init__`` by raising :class:`ValueError` with a
message that starts with the field name; :func:`from_mapping` prefixes the file and key path.

YAML is read with :class:`StrictLoader`: a duplicate key is an error (naming its key path and
line) instead of silently keeping the last value, and exponent notation without a dot (``6e3``,
``1e-3``) is a float as in YAML 1.2 (PyYAML's YAML 1.1 resolver reads it as a string). Every number
:func:`from_mapping` reads must be finite: NaN and infinities are refused wherever they appear.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""


class DuplicateKeyError(yaml.YAMLError):
    """A YAML mapping holds the same key twice (raised by :class:`StrictLoader`)."""

    def __init__(self, key_path: str, line: int, first_line: int) -> None:
        super().__init__(f"{key_path}: duplicate key at line {line} (first at line {first_line})")
        self.key_path, self.line, self.first_line = key_path, line, first_line


class StrictLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses duplicate keys and reads ``6e3`` / ``1e-3`` as floats.

    Raises
    ------
    DuplicateKeyError
        For a key that appears twice in one mapping (merge keys ``<<`` may be overridden, as the
        YAML merge-key spec allows), naming the key path and both lines (1-based).
    """

    def construct_document(self, node: yaml.Node) -> Any:
        """Check the document's keys for duplicates, then construct it."""
        self._check_unique_keys(node, "", set())
        return super().construct_document(node)

    def _check_unique_keys(self, node: yaml.Node, where: str, seen: set[int]) -> None:
        if id(node) in seen:  # aliases: each node once (also guards recursive structures)
            return
        seen.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                self._check_unique_keys(item, f"{where}[{i}]", seen)
        elif isinstance(node, yaml.MappingNode):
            first: dict[Any, int] = {}
            for key_node, value_node in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = _scalar_key(self, key_node)
                path = f"{where}.{key}" if where else str(key)
                if key is not None and key in first:
                    raise DuplicateKeyError(path, key_node.start_mark.line + 1, first[key])
                if key is not None:
                    first[key] = key_node.start_mark.line + 1
                self._check_unique_keys(value_node, path, seen)


def _scalar_key(loader: yaml.SafeLoader, node: yaml.Node) -> Any:
    """The value of a scalar mapping key (so ``1`` and ``0x1`` are the same key); None otherwise."""
    if not isinstance(node, yaml.ScalarNode):
        return None
    try:
        key = loader.construct_object(node)
    except (yaml.YAMLError, ValueError):
        return None  # reported by the construction proper
    return key if isinstance(key, (str, int, float, bool)) or key is None else None


# YAML 1.2 floats with an exponent but no dot (6e3, -1E-3, 2.5e4 is already a float in PyYAML).
StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def parse_yaml(text: str, source: str) -> Any:
    """Parse YAML text with :class:`StrictLoader`.

    Parameters
    ----------
    text : str
        The YAML document.
    source : str
        What the text came from (a file name), for error messages.

    Raises
    ------
    ConfigError
        Naming ``source`` (and the key path and line of a duplicate key) when the text is not
        valid YAML.
    """
    try:
        return yaml.load(text, Loader=StrictLoader)  # noqa: S506 (StrictLoader is a SafeLoader)
    except DuplicateKeyError as exc:
        raise ConfigError(f"{source}: {exc}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source}: not valid YAML: {exc}") from exc
    except (ValueError, TypeError, RecursionError) as exc:  # e.g. a timestamp 2024-13-45
        raise ConfigError(f"{source}: not valid YAML: {type(exc).__name__}: {exc}") from exc


def read_text(path: str | Path, what: str = "file") -> str:
    """Read a UTF-8 text file (a BOM is allowed).

    Raises
    ------
    ConfigError
        If the file is missing, unreadable or not UTF-8 (naming the byte offset).
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: {what} not found")
    try:
        return p.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{p}: not UTF-8 text (byte {exc.start}: {exc.object[exc.start : exc.start + 1]!r}); "
            "expected a UTF-8 encoded file"
        ) from exc
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read {what}: {exc.strerror or exc}") from exc


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from ``path`` (with :class:`StrictLoader`).

    An empty (or comment-only) file gives an empty mapping.

    Raises
    ------
    ConfigError
        If the file is missing, not UTF-8, not valid YAML, has a duplicate key or does not hold a
        mapping.
    """
    p = Path(path)
    data = parse_yaml(read_text(p, "file"), str(p))
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: expected a mapping at the top level, got {type(data).__name__}")
    return data


def deep_merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """Return ``base`` updated recursively by ``over`` (mappings merge, others replace)."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if origin in (list, tuple):
        args = typing.get_args(tp)
        return f"a list of {_type_name(args[0])}" if args else "a list"
    if origin in (dict,):
        return f"a mapping of {_type_name(typing.get_args(tp)[1])}"
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    return {int: "an integer", float: "a number", str: "a string", bool: "true or false"}.get(
        tp, getattr(tp, "__name__", str(tp))
    )


def check_finite(value: Any, where: str, _seen: set[int] | None = None) -> None:
    """Refuse NaN and infinities anywhere in (nested) mappings and lists.

    Raises
    ------
    ConfigError
        ``"<where>.<key>[i]: expected a finite number, got nan"``.
    """
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ConfigError(f"{where}: expected a finite number, got {value!r}")
        return
    if not isinstance(value, (Mapping, list, tuple)):
        return
    _seen = set() if _seen is None else _seen
    if id(value) in _seen:  # YAML aliases share objects: check each once
        return
    _seen.add(id(value))
    if isinstance(value, Mapping):
        for k, v in value.items():
            check_finite(v, f"{where}.{k}", _seen)
    else:
        for i, v in enumerate(value):
            check_finite(v, f"{where}[{i}]", _seen)


def _mismatch(tp: Any, value: Any, where: str) -> ConfigError:
    """The error for ``value`` at ``where`` not being of the type ``tp``."""
    return ConfigError(f"{where}: expected {_type_name(tp)}, got {value!r}")


@functools.cache
def _type_hints(cls: type) -> dict[str, Any]:
    """``typing.get_type_hints`` of a dataclass, resolved once per class."""
    return typing.get_type_hints(cls)


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    if tp is Any:
        check_finite(value, where)
        return value
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        if isinstance(value, float) and float in args:
            check_finite(value, where)
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, where)
            except ConfigError:
                continue
        raise _mismatch(tp, value, where)
    if origin is typing.Literal:
        if value in typing.get_args(tp):
            return value
        raise _mismatch(tp, value, where)
    if origin in (list, tuple):
        if not isinstance(value, (list, tuple)):
            raise _mismatch(tp, value, where)
        (arg, *rest) = typing.get_args(tp) or (Any,)
        if origin is tuple and rest and rest[0] is not Ellipsis:
            args = typing.get_args(tp)
            if len(args) != len(value):
                raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}")
            return tuple(
                _convert(a, v, f"{where}[{i}]")
                for i, (a, v) in enumerate(zip(args, value, strict=True))
            )
        return tuple(_convert(arg, v, f"{where}[{i}]") for i, v in enumerate(value))
    if origin is dict:
        if not isinstance(value, Mapping):
            raise _mismatch(tp, value, where)
        _, vt = typing.get_args(tp)
        return {str(k): _convert(vt, v, f"{where}.{k}") for k, v in value.items()}
    if dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        if not isinstance(value, Mapping):
            raise _mismatch(tp, value, where)
        return from_mapping(tp, value, where=where)
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise _mismatch(tp, value, where)
    if tp is int:
        if isinstance(value, float) and value.is_integer():  # 6e3 in YAML is a float
            return int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise _mismatch(tp, value, where)
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _mismatch(tp, value, where)
        try:
            number = float(value)
        except OverflowError:  # an integer beyond float range
            raise ConfigError(f"{where}: expected a finite number, got {value!r}") from None
        check_finite(number, where)
        return number
    if tp is str:
        if not isinstance(value, str):
            raise _mismatch(tp, value, where)
        return value
    raise ConfigError(f"{where}: unsupported type {tp!r}")


def from_mapping(cls: type[T], data: Mapping[str, Any], where: str = "") -> T:
    """Build the dataclass ``cls`` from a mapping, strictly.

    Parameters
    ----------
    cls
        A dataclass type. Its fields' type hints drive conversion and type checks.
    data
        The mapping read from YAML. Missing keys take the field default.
    where
        Prefix for error messages: ``"file.yaml: key.path"``.

    Raises
    ------
    ConfigError
        On unknown keys, wrong types, missing required keys, or a range check failing in the
        dataclass's ``__post_init__``.
    """
    hints = _type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    sep = "" if not where or where.endswith(": ") else "."
    unknown = sorted(set(map(str, data)) - set(fields))
    if unknown:
        raise ConfigError(
            f"{where}{sep}{unknown[0]}: unknown key; expected one of {', '.join(sorted(fields))}"
        )
    kwargs = {}
    for name, field in fields.items():
        key_where = f"{where}{sep}{name}"
        if name in data:
            kwargs[name] = _convert(hints[name], data[name], key_where)
        elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            raise ConfigError(f"{key_where}: required key is missing ({_type_name(hints[name])})")
    try:
        return cls(**kwargs)
    except ConfigError:
        raise
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{where}{sep}{exc}") from exc


#: Field metadata: leave the field out of :func:`to_mapping` while it holds its default, so that a
#: field added later keeps the mappings (and the cache keys hashed from them) of everything that
#: does not use it.
OMIT_DEFAULT = {"omit_default": True}


def to_mapping(obj: Any) -> Any:
    """Convert (nested) dataclasses to plain mappings/lists suitable for YAML.

    Fields marked with :data:`OMIT_DEFAULT` are left out while they hold their default.
    """
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {
            f.name: to_mapping(getattr(obj, f.name))
            for f in dataclasses.fields(obj)
            if not (f.metadata.get("omit_default") and getattr(obj, f.name) == f.default)
        }
    if isinstance(obj, (list, tuple)):
        return [to_mapping(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_mapping(v) for k, v in obj.items()}
    return obj


#: Characters of a user's value echoed in an error message; longer ones are cut (a 5000-digit
#: number or a secret file's first line has no place on the terminal).
MESSAGE_VALUE_CHARS = 60


def shown(value: object, limit: int = MESSAGE_VALUE_CHARS) -> str:
    """``repr(value)`` for a message, cut to ``limit`` characters with the count of the rest."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text) - limit} more characters)"


def require(condition: bool, message: str) -> None:
    """Raise ``ValueError(message)`` unless ``condition`` holds (for ``__post_init__`` checks)."""
    if not condition:
        raise ValueError(message)
