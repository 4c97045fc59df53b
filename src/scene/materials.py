"""Surface materials of the scene description, renderer-agnostic (the Kubric idea).

Each material is a frozen dataclass with validated, unit-named parameters. Reflectances are linear
albedos (dimensionless, 0..1); ``alpha`` is the microfacet roughness (dimensionless; None is a
smooth surface); ``int_ior`` the refractive index of a dielectric coating. The YAML templates in
``mitsuba_scenes/`` name materials by the Mitsuba BSDF they map to (:data:`MATERIAL_TYPES`), so the
files read the same; only :mod:`simgap.render.mitsuba_scene` turns a material back into a plugin.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from simgap.core.config import ConfigError, from_mapping, require

#: Roughness of a ``rough*`` template entry that gives none: Mitsuba's own default ``alpha``.
DEFAULT_ALPHA = 0.1
#: Refractive index of a plastic coating when none is given: polypropylene, Mitsuba's default.
DEFAULT_INT_IOR = 1.49


def _check_alpha(alpha: float | None) -> None:
    require(alpha is None or 0 < alpha <= 1, "alpha: expected 0 < alpha <= 1 (or none: smooth)")


def _check_albedo(name: str, value: float) -> None:
    require(0 <= value <= 1, f"{name}: expected an albedo in 0..1, got {value}")


@dataclass(frozen=True)
class Diffuse:
    """Lambertian surface of albedo ``reflectance`` (dimensionless, linear)."""

    reflectance: float = 0.5

    def __post_init__(self) -> None:
        _check_albedo("reflectance", self.reflectance)


@dataclass(frozen=True)
class Plastic:
    """Diffuse base under a dielectric coating: painted, anodised or laminated surfaces.

    Attributes
    ----------
    diffuse_reflectance : float
        Albedo of the base (dimensionless, linear).
    alpha : float or None
        Roughness of the coating (dimensionless); None is a smooth coating.
    int_ior : float
        Refractive index of the coating (dimensionless).
    """

    diffuse_reflectance: float = 0.5
    alpha: float | None = None
    int_ior: float = DEFAULT_INT_IOR

    def __post_init__(self) -> None:
        _check_albedo("diffuse_reflectance", self.diffuse_reflectance)
        _check_alpha(self.alpha)
        require(1 < self.int_ior < 3, "int_ior: expected 1 < int_ior < 3")


@dataclass(frozen=True)
class Conductor:
    """Metal: ``material`` names its complex refractive index (e.g. ``Al``); rough when ``alpha``.

    ``material`` is a name of Mitsuba's conductor table (``none`` is a perfect mirror).
    """

    material: str = "none"
    alpha: float | None = None

    def __post_init__(self) -> None:
        _check_alpha(self.alpha)
        require(bool(self.material.strip()), "material: expected a conductor name, e.g. Al")


@dataclass(frozen=True)
class Coating:
    """Dielectric laminate over a print: roughness ``alpha`` (None = smooth) and ``int_ior``."""

    alpha: float | None = None
    int_ior: float = DEFAULT_INT_IOR

    def __post_init__(self) -> None:
        _check_alpha(self.alpha)
        require(1 < self.int_ior < 3, "int_ior: expected 1 < int_ior < 3")


@dataclass(frozen=True)
class TagPrint:
    """The printed tag sticker: marker texture as ink/paper albedo, optionally laminated.

    Attributes
    ----------
    ink, paper : float
        Albedo of the black cells and of the white paper (dimensionless, linear).
    texture_filter : {"nearest", "bilinear"}
        ``nearest`` keeps cell edges exactly sharp; ``bilinear`` is a print with slightly soft
        cell edges (the renderer upsamples the one-texel-per-cell texture first).
    coating : Coating or None
        A dielectric laminate over the print; None is a matte print.
    """

    ink: float = 0.03
    paper: float = 0.80
    texture_filter: Literal["nearest", "bilinear"] = "nearest"
    coating: Coating | None = None

    def __post_init__(self) -> None:
        _check_albedo("ink", self.ink)
        _check_albedo("paper", self.paper)


Material = Diffuse | Plastic | Conductor

#: Template ``type`` -> (material class, keys the entry may set, whether it is rough).
MATERIAL_TYPES: dict[str, tuple[type, tuple[str, ...], bool]] = {
    "diffuse": (Diffuse, ("reflectance",), False),
    "plastic": (Plastic, ("diffuse_reflectance", "int_ior"), False),
    "roughplastic": (Plastic, ("diffuse_reflectance", "int_ior", "alpha"), True),
    "conductor": (Conductor, ("material",), False),
    "roughconductor": (Conductor, ("material", "alpha"), True),
}
#: Template ``type`` of the tag material -> whether its coating is rough (None: no coating).
TAG_TYPES: dict[str, bool | None] = {"diffuse": None, "plastic": False, "roughplastic": True}
_TAG_KEYS = ("ink", "paper", "texture_filter")


def _entry(
    data: Any, types: Mapping[str, Any], where: str, default: str | None
) -> tuple[str, dict]:
    """The ``type`` and other keys of a template entry, checked against ``types``."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping with a type, got {data!r}")
    rest = {str(k): v for k, v in data.items()}
    kind = rest.pop("type", default)
    if kind not in types:
        raise ConfigError(f"{where}.type: expected one of {', '.join(types)}, got {kind!r}")
    return kind, rest


def _unknown(rest: Mapping[str, Any], allowed: tuple[str, ...], kind: str, where: str) -> None:
    unknown = sorted(set(rest) - set(allowed))
    if unknown:
        raise ConfigError(
            f"{where}.{unknown[0]}: unknown key for type {kind}; expected one of "
            f"{', '.join(('type',) + allowed)}"
        )


def material_from_mapping(data: Any, where: str) -> Material:
    """A material from a template entry, e.g. ``{type: roughconductor, material: Al, alpha: 0.25}``.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming ``where`` and the key for an unknown type or key, a wrong type or a bad value.
    """
    kind, rest = _entry(data, MATERIAL_TYPES, where, None)
    cls, allowed, rough = MATERIAL_TYPES[kind]
    _unknown(rest, allowed, kind, where)
    if rough:
        rest.setdefault("alpha", DEFAULT_ALPHA)
    return from_mapping(cls, rest, where=where)


def tag_print_from_mapping(data: Any, where: str) -> TagPrint:
    """The tag print from the template's ``materials.tag`` entry (``type`` default ``diffuse``).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming ``where`` and the key for an unknown type or key, a wrong type or a bad value.
    """
    kind, rest = _entry(data, TAG_TYPES, where, "diffuse")
    rough = TAG_TYPES[kind]
    coating_keys = () if rough is None else ("int_ior", "alpha") if rough else ("int_ior",)
    _unknown(rest, _TAG_KEYS + coating_keys, kind, where)
    coating = {k: rest.pop(k) for k in coating_keys if k in rest}
    if rough is not None:
        if rough:
            coating.setdefault("alpha", DEFAULT_ALPHA)
        rest["coating"] = coating
    return from_mapping(TagPrint, rest, where=where)
