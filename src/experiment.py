"""Experiment files: what to render, how to image it and how to estimate pose.

An experiment YAML holds (all optional but ``name``)::

    name: smoke
    description: ...
    rig: {...}              # overrides of the packaged rig.yaml
    scene: {...}            # overrides of mitsuba_scenes/pass_fixture.yaml
    configurations: {p: [0, 7, 14], theta_deg: [0, 30, 180], tags: [0, 1]}
    render: {spp: 16, sampler: multijitter, seed: 0, crop_margin_px: 24}
    image: {exposure: 1.0, encoding: srgb}
    detector: {corner_refinement: SUBPIX, ...}
    pnp: {method: IPPE_SQUARE}

Unknown keys, wrong types and out-of-range values raise :class:`~simgap.config.ConfigError` naming
the file and key path.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml

from simgap.config import ConfigError, from_mapping, read_yaml, require, to_mapping
from simgap.pose.detect import DetectorSettings
from simgap.pose.estimate import PnPSettings
from simgap.render.scene import SceneSpec, load_scene_spec
from simgap.rig import Rig


@dataclass(frozen=True)
class Configurations:
    """Subset of the rig's grid: pin holes, turntable angles (deg) and tag ids; empty = all."""

    p: tuple[int, ...] = ()
    theta_deg: tuple[float, ...] = ()
    tags: tuple[int, ...] = ()


@dataclass(frozen=True)
class RenderSettings:
    """Renderer settings.

    Attributes
    ----------
    spp : int
        Samples per pixel.
    sampler : str
        Mitsuba sampler (``multijitter``, ``ldsampler``, ``stratified``, ``independent``).
    seed : int
        Base seed; each configuration's render seed is derived from it and (p, theta).
    crop_margin_px : int
        Margin around the largest projected sticker when sizing the render crop (px).
    """

    spp: int = 16
    sampler: Literal["multijitter", "ldsampler", "stratified", "independent", "orthogonal"] = (
        "multijitter"
    )
    seed: int = 0
    crop_margin_px: int = 24

    def __post_init__(self) -> None:
        require(self.spp >= 1, f"spp: expected an integer >= 1, got {self.spp}")
        require(self.crop_margin_px >= 4, "crop_margin_px: expected an integer >= 4 (px)")


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
class Experiment:
    """A resolved experiment (see module docstring)."""

    name: str
    description: str = ""
    rig: dict[str, Any] = field(default_factory=dict)
    scene: dict[str, Any] = field(default_factory=dict)
    configurations: Configurations = field(default_factory=Configurations)
    render: RenderSettings = field(default_factory=RenderSettings)
    image: ImageSettings = field(default_factory=ImageSettings)
    detector: DetectorSettings = field(default_factory=DetectorSettings)
    pnp: PnPSettings = field(default_factory=PnPSettings)
    source: str = "<memory>"

    @cached_property
    def rig_model(self) -> Rig:
        """The rig with this experiment's overrides."""
        from simgap.config import deep_merge
        from simgap.rig import DEFAULT_RIG_FILE

        data = deep_merge(read_yaml(DEFAULT_RIG_FILE), self.rig)
        return from_mapping(Rig, data, where=f"{self.source}: rig")

    @cached_property
    def scene_spec(self) -> SceneSpec:
        """The scene template with this experiment's overrides."""
        try:
            return load_scene_spec(self.scene)
        except ConfigError as exc:
            raise ConfigError(f"{self.source}: scene: {exc}") from exc

    def grid(self) -> tuple[tuple[int, ...], np.ndarray, tuple[int, ...]]:
        """Return pin holes, turntable angles (rad) and tag ids of this experiment."""
        rig = self.rig_model
        c = self.configurations
        ps = c.p or rig.grid.p
        bad = sorted(set(ps) - set(rig.grid.p))
        if bad:
            raise ConfigError(
                f"{self.source}: configurations.p: {bad[0]} is not a pin hole; "
                f"expected one of {list(rig.grid.p)}"
            )
        if c.theta_deg:
            stops = rig.grid.theta_step_deg * np.arange(rig.grid.theta_count)
            for t in c.theta_deg:
                if not np.any(np.isclose(stops, t % 360.0)):
                    raise ConfigError(
                        f"{self.source}: configurations.theta_deg: {t} is not a turntable stop "
                        f"(multiples of {rig.grid.theta_step_deg} deg)"
                    )
            thetas = np.deg2rad(np.asarray(c.theta_deg, float) % 360.0)
        else:
            thetas = rig.grid.theta
        tags = c.tags or rig.tags.ids
        bad_tags = sorted(set(tags) - set(rig.tags.ids))
        if bad_tags:
            raise ConfigError(
                f"{self.source}: configurations.tags: tag {bad_tags[0]} is not on the rig; "
                f"expected one of {list(rig.tags.ids)}"
            )
        return tuple(ps), thetas, tuple(tags)

    def to_yaml(self) -> str:
        """The resolved experiment as YAML text (stored in dataset attrs)."""
        data = to_mapping(self)
        data.pop("source")
        return yaml.safe_dump(data, sort_keys=False)


def load_experiment(path: str | Path) -> Experiment:
    """Load and validate an experiment YAML file.

    Raises
    ------
    simgap.config.ConfigError
        Naming the file and key path of what is wrong.
    """
    path = Path(path)
    data = read_yaml(path)
    data.setdefault("name", path.stem)
    exp = from_mapping(Experiment, {**data, "source": str(path)}, where=f"{path}: ")
    exp.rig_model  # noqa: B018  (validate now, not in the middle of a sweep)
    exp.scene_spec  # noqa: B018
    exp.grid()
    return exp
