"""Experiment files: what to render, how to image it and how to estimate pose.

An experiment YAML holds (all optional but ``name``)::

    name: smoke
    description: ...
    inherit: smoke.yaml     # another experiment file (relative to this one); this file wins
    rig: {...}              # overrides of the packaged rig.yaml
    scene: {...}            # overrides of mitsuba_scenes/pass_fixture.yaml
    configurations: {p: [0, 7, 14], theta_deg: [0, 30, 180], tags: [0, 1]}
    render: {mode: converged, spp: 4, sampler: multijitter, seed: 0, margin_px: 24}
    image: {exposure: 1.0, encoding: srgb}
    detector: {corner_refinement: SUBPIX, ...}
    pnp: {method: IPPE_SQUARE}
    effects: {lighting: {cct_k: 4000}}         # applied to every variant
    variants:                                  # one at a time; `baseline` is added if absent
      - {name: distortion, effects: {lens_distortion: {k1: 0.1}}}
    grid:                                      # full factorial over effect parameters
      exposure.ev: [-1, 0, 1]
      blur.sigma_px: [0.5, 1.0]
    repeats: 3                                 # Monte Carlo repeats (image-stage noise)

Unknown keys, wrong types and out-of-range values raise :class:`~simgap.core.config.ConfigError`
naming
the file and key path; a value set in an inherited file is reported against that (parent) file. An
empty or comment-only file is an error (it does not mean "the full study": write ``name: ...``).
Configurations must be distinct (``theta_deg: [0, 360]`` names one stop twice), and an experiment
whose result arrays would not fit in memory is refused before any work starts.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from simgap.core.config import (
    ConfigError,
    from_mapping,
    parse_yaml,
    require,
    to_mapping,
)
from simgap.core.rig import Rig, load_rig
from simgap.effects import make_effect
from simgap.effects.state import (
    ImageState,
    RenderQuality,
    SceneState,
    VariantState,
)
from simgap.pipeline.experiment_files import (
    blame_parent,
    camera_mapping,
    merge_chain,
    origins,
    read_chain,
)
from simgap.pipeline.experiment_settings import (
    Configurations,
    ImageSettings,
    RenderSettings,
    VariantSpec,
)
from simgap.pose.detect import DetectorSettings
from simgap.pose.estimate import PnPSettings
from simgap.pose.tags import Estimation
from simgap.results.dataset import result_nbytes
from simgap.scene.spec import SceneSpec, load_scene_spec

#: Share of the machine's physical memory one run may plan to use for its result arrays.
MEMORY_SHARE = 0.5
#: Scheduler overhead per (p, theta) task: future, key and task graph entry (bytes, measured
#: order of magnitude with dask.distributed).
TASK_OVERHEAD_BYTES = 16 * 1024
#: The result arrays are held twice at the end of a run (arrays, then the dataset being written).
RESULT_COPIES = 2


def physical_memory_bytes() -> int:
    """Physical memory of this machine (bytes)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not POSIX: assume 16 GiB
        return 16 * 2**30


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
    inherit: str | None = None
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)
    variants: tuple[VariantSpec, ...] = ()
    grid: dict[str, tuple[Any, ...]] = field(default_factory=dict)
    repeats: int = 1
    source: str = "<memory>"

    def __post_init__(self) -> None:
        require(self.repeats >= 1, f"repeats: expected an integer >= 1, got {self.repeats}")
        names = [v.name for v in self.variants]
        dup = sorted({n for n in names if names.count(n) > 1})
        require(not dup, f"variants: duplicate variant name {dup[0] if dup else ''!r}")
        for key, values in self.grid.items():
            require(key.count(".") == 1, f"grid.{key}: expected a key of the form effect.parameter")
            require(len(values) >= 1, f"grid.{key}: expected a non-empty list of values")
            seen = [repr(v) for v in values]
            again = next((v for v in seen if seen.count(v) > 1), None)
            require(again is None, f"grid.{key}: expected distinct values, {again} is repeated")
        for key in ("p", "tags"):
            values = getattr(self.configurations, key)
            again = next((v for v in values if values.count(v) > 1), None)
            require(
                again is None,
                f"configurations.{key}: expected distinct values, {again} is repeated",
            )

    def with_render(self, **changes: Any) -> Experiment:
        """The experiment with the :class:`RenderSettings` fields in ``changes`` replaced."""
        return replace(self, render=replace(self.render, **changes))

    def memory_estimate(self) -> tuple[int, str, str]:
        """Planned memory of the run's result arrays, computed from counts (nothing allocated).

        Returns
        -------
        tuple
            ``(bytes, key, shape)``: the estimate (bytes), the key path of the largest factor
            (what to reduce) and the shape in words.
        """
        rig, c = self.rig_model, self.configurations
        n_variants = len(self.variants) + ("baseline" not in [v.name for v in self.variants])
        n_variants += math.prod(len(v) for v in self.grid.values()) if self.grid else 0
        factors = {
            "variants": n_variants,
            "repeats": self.repeats,
            "configurations.tags": len(c.tags or rig.tags.ids),
            "configurations.p" if c.p else "rig.grid.p": len(c.p or rig.grid.p),
            "configurations.theta_deg" if c.theta_deg else "rig.grid.theta_count": (
                len(c.theta_deg) or rig.grid.theta_count
            ),
        }
        n = math.prod(factors.values())
        tasks = factors["configurations.p" if c.p else "rig.grid.p"] * (
            len(c.theta_deg) or rig.grid.theta_count
        )
        total = RESULT_COPIES * result_nbytes(n) + tasks * TASK_OVERHEAD_BYTES
        key = max(factors, key=lambda k: factors[k])
        shape = " x ".join(f"{v} {k.split('.')[-1]}" for k, v in factors.items())
        return total, key, shape

    def check_memory(self) -> None:
        """Refuse an experiment whose result arrays this machine cannot hold.

        Raises
        ------
        simgap.core.config.ConfigError
            Naming the largest factor's key path, the estimate and the machine's memory.
        """
        need, key, shape = self.memory_estimate()
        have = physical_memory_bytes()
        if need > MEMORY_SHARE * have:
            raise ConfigError(
                f"{self.source}: {key}: the run would need about {need / 2**30:.3g} GiB for its "
                f"results ({shape}); expected at most {MEMORY_SHARE:.0%} of this machine's "
                f"{have / 2**30:.3g} GiB"
            )

    def variant_specs(self) -> list[VariantSpec]:
        """All variants: ``baseline`` first, then the listed ones, then the grid's combinations."""
        specs = list(self.variants)
        if "baseline" not in [v.name for v in specs]:
            specs.insert(0, VariantSpec("baseline"))
        keys = list(self.grid)
        combos = itertools.product(*(self.grid[k] for k in keys)) if keys else ()
        for combo in combos:
            effects: dict[str, dict[str, Any]] = {}
            for key, value in zip(keys, combo, strict=True):
                effect, param = key.split(".")
                effects.setdefault(effect, {})[param] = value
            name = ",".join(f"{k}={v}" for k, v in zip(keys, combo, strict=True))
            specs.append(VariantSpec(name, effects))
        return specs

    def base_state(self) -> VariantState:
        """The state every variant starts from: this experiment's settings, before effects."""
        rig = self.rig_model
        r = self.render
        return VariantState(
            scene=SceneState(
                spec=self.scene_spec,
                camera=rig.camera,
                quality=RenderQuality(r.spp, r.sampler, r.max_depth, r.mode),
                render_seed=r.seed,
            ),
            image=ImageState(encoding=self.image.encoding, exposure=self.image.exposure),
            estimation=Estimation(calibration=rig.camera, detector=self.detector, pnp=self.pnp),
        )

    def variant_states(self) -> list[tuple[str, VariantState]]:
        """``(name, state)`` of every variant, with the experiment's and the variant's effects.

        Raises
        ------
        simgap.core.config.ConfigError
            Naming the file and key path of an unknown effect or a bad parameter.
        """
        base = self.base_state()
        for name, params in self.effects.items():
            base = _apply_effect(name, params, base, f"{self.source}: effects.")
        out = []
        listed = {v.name: i for i, v in enumerate(self.variants)}
        for spec in self.variant_specs():
            where = (
                f"{self.source}: variants[{listed[spec.name]}].effects."
                if spec.name in listed
                else f"{self.source}: grid: "
            )
            state = base
            for name, params in spec.effects.items():
                state = _apply_effect(name, params, state, where)
            out.append((spec.name, state))
        return out

    @cached_property
    def rig_model(self) -> Rig:
        """The rig with this experiment's overrides."""
        return load_rig(overrides=self.rig, where=f"{self.source}: rig")

    @cached_property
    def scene_spec(self) -> SceneSpec:
        """The scene template with this experiment's overrides."""
        try:
            return load_scene_spec(self.scene)
        except ConfigError as exc:
            raise ConfigError(f"{self.source}: scene: {exc}") from exc

    def configuration_axes(self) -> tuple[tuple[int, ...], np.ndarray, tuple[int, ...]]:
        """Return pin holes, turntable angles (rad) and tag ids of this experiment."""
        rig = self.rig_model
        c = self.configurations
        ps = c.p or rig.grid.p
        self._check_known("p", ps, rig.grid.p, "{} is not a pin hole")
        if c.theta_deg:
            stops = rig.grid.theta_step_deg * np.arange(rig.grid.theta_count)
            first: dict[int, float] = {}
            for t in c.theta_deg:
                close = np.flatnonzero(np.isclose(stops, t % 360.0))
                if not len(close):
                    raise ConfigError(
                        f"{self.source}: configurations.theta_deg: {t} is not a turntable stop "
                        f"(multiples of {rig.grid.theta_step_deg} deg)"
                    )
                if int(close[0]) in first:
                    raise ConfigError(
                        f"{self.source}: configurations.theta_deg: {t} and {first[int(close[0])]} "
                        f"are the same turntable stop ({stops[close[0]]:g} deg); expected "
                        "distinct stops"
                    )
                first[int(close[0])] = t
            thetas = np.deg2rad(np.asarray(c.theta_deg, float) % 360.0)
        else:
            thetas = rig.grid.theta
        tags = c.tags or rig.tags.ids
        self._check_known("tags", tags, rig.tags.ids, "tag {} is not on the rig")
        return tuple(ps), thetas, tuple(tags)

    def _check_known(self, key: str, values, known, what: str) -> None:
        """Refuse ``configurations.<key>`` values not in ``known`` (``what`` formats the first)."""
        bad = sorted(set(values) - set(known))
        if bad:
            raise ConfigError(
                f"{self.source}: configurations.{key}: {what.format(bad[0])}; "
                f"expected one of {list(known)}"
            )

    def to_yaml(self) -> str:
        """The resolved experiment as YAML text (stored in dataset attrs)."""
        data = to_mapping(self)
        data.pop("source")
        return yaml.safe_dump(data, sort_keys=False)


def _apply_effect(name: str, params: Any, state: VariantState, where: str) -> VariantState:
    """Apply one effect; a state it makes invalid (e.g. an implausible camera) is a ConfigError."""
    effect = make_effect(name, params, where=where)
    try:
        return effect.apply(state)
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(f"{where}{name}: {exc}") from exc


def experiment_from_yaml(text: str, source: str = "<dataset>") -> Experiment:
    """Rebuild an experiment from its resolved YAML (as stored in a dataset's attrs).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming ``source`` when the text is not a valid experiment.
    """
    data = parse_yaml(text, f"{source}: experiment_yaml")
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: experiment_yaml: expected a mapping, got {data!r:.60}")
    data.pop("inherit", None)
    return from_mapping(Experiment, {**data, "source": source}, where=f"{source}: ")


def with_calibration(exp: Experiment, path: str | Path) -> Experiment:
    """``exp`` whose camera is the calibration file at ``path`` (any format and OpenCV model).

    The file gives the whole camera (intrinsics, distortion model and coefficients), as
    ``rig.camera.calibration`` does in an experiment file
    (:func:`simgap.pipeline.experiment_files.with_calibration_file`).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the calibration file and its key, or the experiment's when the camera does not
        fit it (an image too small for its configurations, say).
    """
    from simgap.pipeline.capture import read_calibration  # the formats register on import

    camera = camera_mapping(read_calibration(Path(path)))
    out = replace(exp, rig={**exp.rig, "camera": camera})
    out.rig_model  # noqa: B018  (validate now)
    return out


def load_experiment(path: str | Path) -> Experiment:
    """Load and validate an experiment YAML file (and the files it inherits from).

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the file and key path of what is wrong.
    """
    path = Path(path)
    chain = read_chain(path)
    data = merge_chain(chain)
    data.setdefault("name", path.stem)
    try:
        exp = from_mapping(Experiment, {**data, "source": str(path)}, where=f"{path}: ")
        exp.rig_model  # noqa: B018  (validate now, not in the middle of a sweep)
        exp.scene_spec  # noqa: B018
        exp.check_memory()
        exp.configuration_axes()
        exp.variant_states()
    except ConfigError as exc:
        raise blame_parent(exc, path, origins(chain)) from exc.__cause__
    return exp
