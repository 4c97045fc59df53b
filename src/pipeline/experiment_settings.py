"""The settings records of an experiment: configurations, render and image settings, variants.

They are read from an experiment file's blocks (:mod:`simgap.pipeline.experiment`) and validate
their own values on construction.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Final, Literal

from simgap.core.config import require


@dataclass(frozen=True)
class Configurations:
    """Subset of the rig's grid: pin holes, turntable angles (deg) and tag ids; empty = all."""

    p: tuple[int, ...] = ()
    theta_deg: tuple[float, ...] = ()
    tags: tuple[int, ...] = ()


#: Samples per pixel where an experiment names none, per render mode: converged, 4 (two render
#: seeds of the baseline differ by 0.09 mm in ty, docs/results/converged_render_step8.md#step-4);
#: path traced, 16 (the study's setting before converged rendering).
DEFAULT_SPP: Final[dict[str, int]] = {"converged": 4, "path": 16}


@dataclass(frozen=True)
class RenderSettings:
    """How the renderer samples each configuration (the experiment's ``render:`` block)."""

    #: Samples per pixel; none named (or ``null``): :data:`DEFAULT_SPP` of the :attr:`mode` (4
    #: converged, 16 path traced), resolved when the settings are made (a later
    #: ``with_render(mode=...)`` keeps the resolved count unless it names ``spp`` too).
    spp: int | None = None
    #: Mitsuba sampler.
    sampler: Literal["multijitter", "ldsampler", "stratified", "independent", "orthogonal"] = (
        "multijitter"
    )
    #: Base seed; each configuration's render seed is derived from it and (p, theta).
    seed: int = 0
    #: Pixels within this distance of a facing sticker's outline are rendered, the rest of the
    #: frame is a flat surround (px; :mod:`simgap.pipeline.region`); at least the camera
    #: pipeline's reach (a wide blur widens it). Measured on 59 baseline configurations: the
    #: detector finds the same corners (0 px change) from 4 px up, on the same render; 24 px
    #: keeps the diagnosis of the 9-configuration public samples as it was (at 8 px, sample-focal
    #: read as camera_mount at two render seeds, where 24 px gave focal_length at both; since the
    #: diagnosis measures each item's own noise, 8 px gives focal_length too).
    margin_px: int = 24
    #: Maximum path length of the path tracer.
    max_depth: int = 3
    #: Render each repeat with its own seed (Monte Carlo over render noise too; costs a render
    #: per repeat). Otherwise repeats differ only in image-stage noise.
    reseed_repeats: bool = False
    #: ``converged`` (the default): each diffuse sticker demodulated by its
    #: print albedo, with more samples where a shadow or highlight edge crosses it
    #: (:mod:`simgap.render.converged`; needs spp >= 2); ``path``: every pixel the mean of its
    #: path-traced samples (the study's earlier mode, for comparison studies).
    mode: Literal["path", "converged"] = "converged"

    def __post_init__(self) -> None:
        modes = sorted(DEFAULT_SPP)
        require(self.mode in DEFAULT_SPP, f"mode: expected one of {modes}, got {self.mode}")
        if self.spp is None:  # ``spp: null`` too: the mode's own
            object.__setattr__(self, "spp", DEFAULT_SPP[self.mode])
        require(self.spp >= 1, f"spp: expected an integer >= 1, got {self.spp}")
        require(self.max_depth >= 2 or self.max_depth == -1, "max_depth: expected >= 2 or -1")
        require(self.margin_px >= 4, "margin_px: expected an integer >= 4 (px)")
        require(
            self.mode == "path" or self.spp >= 2,
            f"spp: converged mode needs at least 2 samples per pixel, got {self.spp}",
        )

    def render_repeat(self, repeat: int) -> int:
        """The render a repeat's frame is made from: its own with ``reseed_repeats``, else 0."""
        return int(repeat) if self.reseed_repeats else 0


@dataclass(frozen=True)
class ImageSettings:
    """Camera pipeline applied to the linear render.

    Attributes
    ----------
    exposure : float
        Linear gain applied before encoding (dimensionless).
    encoding : {"srgb", "linear"}
        Transfer function of the 8-bit frame.
    """

    exposure: float = 1.0
    encoding: Literal["srgb", "linear"] = "srgb"

    def __post_init__(self) -> None:
        require(self.exposure > 0, f"exposure: expected a positive gain, got {self.exposure}")


@dataclass(frozen=True)
class VariantSpec:
    """A named set of effects (effect name -> parameters) applied on top of the experiment's."""

    name: str
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        require(bool(self.name.strip()), "name: expected a non-empty variant name")
