"""Effect base class and the name-keyed registry (imports nothing else of :mod:`simgap.effects`)."""

from __future__ import annotations

import abc
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from simgap.core.config import ConfigError, from_mapping, require, to_mapping

if TYPE_CHECKING:  # annotation only: the state module reads the registry, not the reverse
    from simgap.effects.state import VariantState

Stage = Literal["scene", "geometry", "image", "estimation"]


@dataclass(frozen=True)
class RelativeScale:
    """A relative scale error (dimensionless; 0.02 = +2 %)."""

    scale: float = 0.0

    def __post_init__(self) -> None:
        require(-0.3 < self.scale < 0.3, "scale: expected -0.3 < scale < 0.3")


EFFECTS: dict[str, type[Effect]] = {}


class Effect(abc.ABC):
    """Base class: subclasses set ``name``, ``stage``, a ``Params`` dataclass and ``apply``."""

    name: ClassVar[str]
    stage: ClassVar[Stage]
    Params: ClassVar[type]
    #: Whether the effect draws random numbers (sensor noise): repeats then differ, and one
    #: realisation is no prediction of the expected corners or pose.
    stochastic: ClassVar[bool] = False

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
    """Class decorator adding an effect to :data:`EFFECTS` under ``cls.name``."""
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
