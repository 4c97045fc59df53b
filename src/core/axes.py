"""Pose axes of every error array and their units: the one definition the whole package reads.

Translation errors are stored in metres and rotation errors (rotation-vector components) in
radians (docs/conventions.md §1); reports show them in millimetres and milliradians.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Final

AXES: Final[tuple[str, ...]] = ("tx", "ty", "tz", "rx", "ry", "rz")
"""Pose axes of the result dataset's ``axis`` coordinate, in contract order."""

TRANSLATION_AXES: Final[tuple[str, ...]] = AXES[:3]
"""Translation axes (errors in metres)."""

ROTATION_AXES: Final[tuple[str, ...]] = AXES[3:]
"""Rotation axes (rotation-vector components, errors in radians)."""

AXIS_UNITS: Final = MappingProxyType(
    {**dict.fromkeys(TRANSLATION_AXES, "m"), **dict.fromkeys(ROTATION_AXES, "rad")}
)
"""SI unit of each axis' error: ``"m"`` for translation, ``"rad"`` for rotation."""

DISPLAY_UNITS: Final = MappingProxyType({"m": ("mm", 1e3), "rad": ("mrad", 1e3)})
"""Display unit and the factor from the SI unit to it, per SI unit."""


def axis_unit(axis: str) -> str:
    """SI unit of an axis' error.

    Parameters
    ----------
    axis : str
        One of :data:`AXES`.

    Returns
    -------
    str
        ``"m"`` for translation axes, ``"rad"`` for rotation axes.
    """
    try:
        return AXIS_UNITS[axis]
    except KeyError:
        raise ValueError(f"unknown pose axis {axis!r}; expected one of {AXES}") from None


def display_unit(axis: str) -> tuple[str, float]:
    """Display unit of an axis' error (one of :data:`AXES`) and the factor from its SI unit.

    ``("mm", 1e3)`` for translation axes, ``("mrad", 1e3)`` for rotation axes.
    """
    return DISPLAY_UNITS[axis_unit(axis)]
