"""``result.json``, ``validation.json`` and trial files: typed results to plain JSON and back.

:func:`jsonable` turns dataclasses (their fields, and the read-only keys a class names in
``json_derived``), numpy scalars and arrays and tuples into plain JSON values;
:func:`from_jsonable` builds a dataclass back from them, by its type hints (nested dataclasses,
``list``, ``dict``, ``tuple``, ``X | None``, numbers, strings), and names the key of anything
that does not fit; a :class:`VersionedRecord` does so for a file with a ``schema_version``,
lifting older schemas to the current one first. :func:`write_json` writes atomically.
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar, cast

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

    Keys with a default may be missing; the read-only keys ``cls.json_derived`` are ignored. A
    nested :class:`VersionedRecord` (a record with schema versions of its own, such as
    :class:`~simgap.diagnosis.result.DiagnosisResult`) is read by its ``from_json``.

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


#: Lifts a record's JSON data of an older schema to the current one.
Upgrade = Callable[[dict[str, Any]], dict[str, Any]]
R = TypeVar("R", bound="VersionedRecord")


class VersionedRecord:
    """A typed record kept as a JSON file with a ``schema_version`` (a base of dataclasses).

    A subclass is a dataclass whose ``schema_version`` field defaults to :attr:`json_schema`,
    the version it writes; :attr:`json_upgrades` maps each older version still read (a file
    without the key is version 1) to the function that lifts its data to a later version's
    layout (its ``schema_version`` says which), applied in turn until the data is current;
    :attr:`json_source` names the file in errors where the reader names none.
    """

    json_schema: ClassVar[int]
    json_upgrades: ClassVar[Mapping[int, Upgrade]] = {}
    json_source: ClassVar[str] = "JSON data"

    def to_json(self) -> dict[str, Any]:
        """The plain-JSON form (:func:`jsonable`)."""
        return jsonable(self)

    @classmethod
    def from_json(cls: type[R], data: Any, source: str | None = None) -> R:
        """Read data of schema :attr:`json_schema`, or of an older one :attr:`json_upgrades` lifts.

        Raises
        ------
        ValueError
            Naming ``source`` (default :attr:`json_source`) and the key that does not fit: a
            schema version neither current nor lifted, or a key :func:`from_jsonable` refuses.
        """
        source = source or cls.json_source
        if not isinstance(data, dict):
            raise ValueError(f"{source}: expected a mapping, got {type(data).__name__}")
        data = lift_schema(
            data,
            data.get("schema_version", 1),
            cls.json_upgrades,
            cls.json_schema,
            lambda d: d["schema_version"],
            source,
        )
        return from_jsonable(cast(Any, cls), data, source)


D = TypeVar("D")


def lift_schema(
    data: D,
    version: Any,
    upgrades: Mapping[int, Callable[[D], D]],
    current: int,
    version_of: Callable[[D], Any],
    source: str,
) -> D:
    """``data`` of schema ``version`` lifted to ``current`` by ``upgrades``, applied in turn.

    Each upgrade returns data of a later version, which ``version_of`` reads from it.

    Raises
    ------
    ValueError
        Naming ``source`` where the version is neither current nor lifted to it.
    """
    while version in upgrades:
        data = upgrades[version](data)
        version = version_of(data)
    if version != current:
        readable = versions_read(upgrades, current)
        raise ValueError(f"{source}: schema_version: expected {readable}, got {version!r}")
    return data


def versions_read(upgrades: Mapping[int, Any], current: int) -> str:
    """The schema versions a reader takes, in words: ``"1, 2 or 3"``."""
    versions = [str(v) for v in sorted({*upgrades, current})]
    return " or ".join([", ".join(versions[:-1]), versions[-1]] if len(versions) > 1 else versions)


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
        if issubclass(tp, VersionedRecord):  # a record with schema versions of its own
            return tp.from_json(value, where)
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
