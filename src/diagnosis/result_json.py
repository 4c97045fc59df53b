"""``result.json`` and ``validation.json``: typed results to plain JSON and back, atomically.

:func:`jsonable` turns dataclasses (their fields, and the read-only keys a class names in
``json_derived``), numpy scalars and arrays and tuples into plain JSON values;
:func:`from_jsonable` builds a dataclass back from them, by its type hints (nested dataclasses,
``list``, ``dict``, ``tuple``, ``X | None``, numbers, strings), and names the key of anything
that does not fit.
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from simgap.core.atomic import atomic_write

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

T = TypeVar("T", bound="DataclassInstance")


def jsonable(obj: Any) -> Any:
    """``obj`` as plain JSON values (dataclasses as mappings of their fields)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {f.name: jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
        out |= {name: jsonable(getattr(obj, name)) for name in getattr(obj, "json_derived", ())}
        return out
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    return obj


def from_jsonable(cls: type[T], data: Any, where: str) -> T:
    """The dataclass ``cls`` built from its :func:`jsonable` form.

    Keys with a default may be missing; the read-only keys ``cls.json_derived`` are ignored.

    Raises
    ------
    ValueError
        Naming the key (``where`` and the path below it) that is missing, unexpected, or not
        of the type the field declares.
    """
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a mapping, got {type(data).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(fields) - set(getattr(cls, "json_derived", ())))
    if unknown:
        raise ValueError(f"{where}: unexpected key(s) {', '.join(unknown)}")
    hints = typing.get_type_hints(cls)
    values = {}
    for name, f in fields.items():
        if name in data:
            values[name] = _value(hints[name], data[name], f"{where}.{name}")
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ValueError(f"{where}: missing key {name!r}")
    return cls(**values)


def _value(tp: Any, value: Any, where: str) -> Any:
    """``value`` read as the type ``tp`` (see :func:`from_jsonable`)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        (inner,) = (a for a in args if a is not type(None))
        return _value(inner, value, where)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return from_jsonable(tp, value, where)
    if origin in (list, tuple):
        if not isinstance(value, list):
            raise ValueError(f"{where}: expected a list, got {type(value).__name__}")
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            if len(value) != len(args):
                raise ValueError(f"{where}: expected {len(args)} values, got {len(value)}")
            pairs = enumerate(zip(args, value, strict=True))
            return tuple(_value(a, v, f"{where}[{i}]") for i, (a, v) in pairs)
        items = [_value(args[0], v, f"{where}[{i}]") for i, v in enumerate(value)]
        return items if origin is list else tuple(items)
    if origin is dict:
        if not isinstance(value, dict):
            raise ValueError(f"{where}: expected a mapping, got {type(value).__name__}")
        return {k: _value(args[1], v, f"{where}.{k}") for k, v in value.items()}
    expected = {float: (int, float), int: (int,), bool: (bool,), str: (str,)}[tp]
    if isinstance(value, bool) is not (tp is bool) or not isinstance(value, expected):
        raise ValueError(f"{where}: expected {tp.__name__}, got {value!r}")
    return tp(value)


def write_json(result: Any, path: Path) -> Path:
    """Write ``result`` (e.g. ``result.json``, ``validation.json``) atomically; return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, json.dumps(jsonable(result), indent=2))
