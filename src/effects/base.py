"""Effect base class, declarative parameter checks and the name-keyed registry.

An effect is a small class whose header names and registers it, ``class Blur(ImageEffect,
name="blur", order=10)``. Its ``Params`` subclass :class:`EffectParams`, which makes them frozen
dataclasses, and each field states its default and valid range once, as data, with :func:`param`:
``sigma_px: float = param(0.7, "0 < sigma < 10 px", lambda v: 0 < v < 10)``; the one generic
``EffectParams.__post_init__`` checks them all and names the key in its message.

(This module imports nothing else of :mod:`simgap.effects`.)
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from simgap.core.config import ConfigError, from_mapping, require, to_mapping

if TYPE_CHECKING:  # annotation only: state imports no module of simgap.effects at import time
    from simgap.effects.state import VariantState

try:  # Python >= 3.11: type checkers then see Params classes as frozen dataclasses
    from typing import dataclass_transform
except ImportError:  # pragma: no cover (Python 3.10)

    def dataclass_transform(**_: Any) -> Callable[[type], type]:
        """Stand-in for :func:`typing.dataclass_transform` (a no-op at run time anyway)."""
        return lambda cls: cls


Stage = Literal["scene", "geometry", "image", "estimation"]


@dataclasses.dataclass(frozen=True)
class Check:
    """A condition parameters must meet, and the error it raises otherwise.

    Attributes
    ----------
    key : str
        What the message names: a field (``"alpha"``) or several (``"ink/paper"``).
    expected : str
        What was expected; the message is ``"<key>: expected <expected>"``.
    ok : callable
        The condition: on the field's value for a :func:`param` check, on the whole ``Params``
        for one in :attr:`EffectParams.checks`.
    """

    key: str
    expected: str
    ok: Callable[[Any], bool]


def param(
    default: Any = dataclasses.MISSING,
    expected: str = "",
    ok: Callable[[Any], bool] | None = None,
    *,
    key: str = "",
    factory: Callable[[], Any] | Any = dataclasses.MISSING,
) -> Any:
    """A ``Params`` field: its default and the condition its value must meet.

    Parameters
    ----------
    default
        The default value.
    expected : str
        What the error message says was expected (e.g. ``"0 < sigma < 10 px"``).
    ok : callable, optional
        The condition on the value; None for no check.
    key : str, optional
        What the error message names, when one condition spans several fields (``"k1/k2/k3"``):
        fields sharing a key are checked together, where the first of them stands. Default: the
        field's name.
    factory : callable, optional
        Makes the default (instead of ``default``), as ``dataclasses.field(default_factory=...)``.
    """
    metadata = {} if ok is None else {"check": (key, expected, ok)}
    return dataclasses.field(default=default, default_factory=factory, metadata=metadata)


def within(bound: float) -> Callable[[Sequence[float]], bool]:
    """Condition for a vector parameter: every component ``|v| < bound``."""
    return lambda vec: all(abs(v) < bound for v in vec)


@dataclass_transform(frozen_default=True, field_specifiers=(param, dataclasses.field))
class EffectParams:
    """Base of effect parameters: each subclass is a frozen dataclass, checked when created.

    Conditions on single fields are declared with :func:`param`; those relating fields go in
    :attr:`checks`. A failed condition raises ``ValueError("<key>: expected <expected>")``, which
    :func:`simgap.core.config.from_mapping` prefixes with the file and key path.
    """

    #: Conditions on several fields at once (checked after those of the fields).
    checks: ClassVar[tuple[Check, ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        dataclasses.dataclass(frozen=True)(cls)

    def __post_init__(self) -> None:
        """Check every declared condition, in field order (fields sharing a key together)."""
        groups: dict[str, tuple[str, list[bool]]] = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            if "check" in f.metadata:
                key, expected, ok = f.metadata["check"]
                _, results = groups.setdefault(key or f.name, (expected, []))
                results.append(bool(ok(getattr(self, f.name))))
        for key, (expected, results) in groups.items():
            require(all(results), f"{key}: expected {expected}")
        for check in self.checks:
            require(bool(check.ok(self)), f"{check.key}: expected {check.expected}")


class RelativeScale(EffectParams):
    """A relative scale error (dimensionless; 0.02 = +2 %)."""

    scale: float = param(0.0, "-0.3 < scale < 0.3", lambda v: -0.3 < v < 0.3)


EFFECTS: dict[str, type[Effect]] = {}


class Effect(abc.ABC):
    """Base class: subclasses set ``name``, ``stage``, a ``Params`` dataclass and ``apply``.

    ``name`` and ``stage`` may be given in the class header, ``class X(Effect, name="x",
    stage="scene")``; a class given a ``name`` is registered (:func:`register`).
    """

    name: ClassVar[str]
    stage: ClassVar[Stage]
    Params: ClassVar[type]
    #: Whether the effect draws random numbers (sensor noise): repeats then differ, and one
    #: realisation is no prediction of the expected corners or pose.
    stochastic: ClassVar[bool] = False

    def __init_subclass__(
        cls, *, name: str | None = None, stage: Stage | None = None, **kwargs: Any
    ) -> None:
        super().__init_subclass__(**kwargs)
        if stage is not None:
            cls.stage = stage
        if name is not None:
            cls.name = name
            register(cls)

    def __init__(self, params: Any) -> None:
        self.params = params

    @abc.abstractmethod
    def apply(self, state: VariantState) -> VariantState:
        """Return ``state`` with this effect applied (its own stage only)."""

    def describe(self) -> dict[str, Any]:
        """The effect's parameters as plain data."""
        return to_mapping(self.params)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.describe()})"


def register(cls: type[Effect]) -> type[Effect]:
    """Add an effect to :data:`EFFECTS` under ``cls.name`` (also usable as a class decorator)."""
    if cls.name in EFFECTS:
        raise ValueError(f"effect name {cls.name!r} registered twice")
    EFFECTS[cls.name] = cls
    return cls


def make_effect(name: str, params: Mapping[str, Any] | None, where: str = "") -> Effect:
    """Build a registered effect from a mapping of its parameters.

    Raises
    ------
    simgap.core.config.ConfigError
        If ``name`` is unknown (the message lists the known names) or the parameters are invalid.
    """
    if name not in EFFECTS:
        raise ConfigError(
            f"{where}{name}: unknown effect; expected one of {', '.join(sorted(EFFECTS))}"
        )
    cls = EFFECTS[name]
    if params is not None and not isinstance(params, Mapping):
        raise ConfigError(f"{where}{name}: expected a mapping of parameters, got {params!r}")
    return cls(from_mapping(cls.Params, params or {}, where=f"{where}{name}"))
