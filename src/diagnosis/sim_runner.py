"""Simulated results of diagnosis items under any variant state, through a :class:`Simulator`."""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from simgap.analysis.gap import Items
from simgap.effects.state import VariantState
from simgap.pipeline.experiment import Experiment
from simgap.pipeline.simulator import Simulator
from simgap.pose.image_stats import STAT_NAMES
from simgap.scene.lights import LightSpec, lights_irradiance

#: Trailing shape of each per-item result field.
_FIELD_SHAPES = {"error": (6,), "corners": (4, 2), "image_stats": (len(STAT_NAMES),)}


class SimRunner:
    """Runs variant states through the simulator for a set of items (in process, memoised).

    The :class:`simgap.analysis.candidates.Runner` of :class:`simgap.analysis.search.ModelSearch`
    and of the simulation-fitted candidates: :meth:`errors`, :meth:`corners`, :meth:`stats`,
    :meth:`detected`, :meth:`depths`, :meth:`eye_from_tag`, :meth:`rail_from_tag` and
    :meth:`irradiance` give the simulated evidence and the nominal rig's geometry and light.

    Parameters
    ----------
    exp : Experiment
        The simulation experiment (rig, tags, repeats, render settings).
    simulator : Simulator
        Runs one state at one configuration (cached).
    """

    def __init__(self, exp: Experiment, simulator: Simulator) -> None:
        self.exp, self.simulator = exp, simulator
        self.rig = exp.rig_model
        #: focal length of the simulated camera (px): the capture's calibration
        self.focal_px = float(self.rig.camera.fx)
        self.tags = simulator.tags(exp)
        self._memo: dict[tuple, dict[str, np.ndarray]] = {}
        self._lights: tuple[LightSpec, ...] | None = None  # the baseline's, read when first asked

    def _results(
        self,
        state: VariantState,
        items: Items,
        field: str,
        advance: Callable[[], None] | None = None,
    ) -> np.ndarray:
        reps = self.exp.repeats if state.image.stochastic else 1
        key0 = self.simulator.state_key(self.exp, state)
        out = np.full((len(items),) + _FIELD_SHAPES.get(field, ()), np.nan)
        for i in range(len(items)):
            p, theta = int(items.p[i]), float(items.theta[i])
            key = (key0, p, theta)
            if key not in self._memo:
                runs = [self.simulator.run(self.exp, state, p, theta, r) for r in range(reps)]
                with warnings.catch_warnings():  # a tag never detected is all-NaN
                    warnings.simplefilter("ignore", RuntimeWarning)
                    self._memo[key] = {
                        f: np.nanmean(np.stack([getattr(x, f) for x in runs]), axis=0)
                        for f in ("error", "corners")
                    } | {
                        "image_stats": np.nanmedian(
                            np.stack([x.image_stats for x in runs]), axis=0
                        ),
                        "detected": np.mean(np.stack([x.detected for x in runs]), axis=0),
                    }
            out[i] = self._memo[key][field][self.tags.index(int(items.tag[i]))]
            if advance is not None:
                advance()
        return out

    def errors(
        self, state: VariantState, items: Items, advance: Callable[[], None] | None = None
    ) -> np.ndarray:
        """Repeat-mean simulated errors (N, 6) of ``items`` under ``state`` (m, rad).

        ``advance`` is called after each item (a progress count), if given.
        """
        return self._results(state, items, "error", advance)

    def corners(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-mean detected corners (N, 4, 2) of ``items`` under ``state`` (px)."""
        return self._results(state, items, "corners")

    def stats(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-median image statistics (N, S) of ``items`` under ``state``."""
        return self._results(state, items, "image_stats")

    def detected(self, state: VariantState, items: Items) -> np.ndarray:
        """Detection rate over repeats (N,) of ``items`` under ``state``."""
        return self._results(state, items, "detected")

    def depths(self, items: Items) -> np.ndarray:
        """Depth of each item's tag along the optical axis, nominal rig (N,) (m)."""
        return self.eye_from_tag(items)[:, 1, 3]

    def eye_from_tag(self, items: Items) -> np.ndarray:
        """Pose of each item's tag in the eyepoint frame, nominal rig (N, 4, 4) (m)."""
        return self.rig.eyepoints_from_tags(items.tag, items.p, items.theta)

    def rail_from_tag(self, items: Items) -> np.ndarray:
        """Pose of each item's tag in the rail frame, nominal rig (N, 4, 4) (m)."""
        tags_thetas = zip(items.tag, items.theta, strict=True)
        poses = [self.rig.rail_from_tag(int(t), float(th)) for t, th in tags_thetas]
        return np.stack(poses) if poses else np.empty((0, 4, 4))

    def irradiance(self, items: Items) -> np.ndarray:
        """Direct irradiance of the simulation's own lights at each item's tag centre (N,) (W m^-2).

        The lights of the experiment's first variant (its baseline), through
        :func:`simgap.scene.lights.lights_irradiance` on the tag's face (nominal rig): shadows and
        inter-reflections left out.
        """
        if not len(items):
            return np.zeros(0)
        if self._lights is None:
            self._lights = tuple(self.exp.variant_states()[0][1].scene.spec.lights.values())
        rail_from_tag = self.rail_from_tag(items)
        return lights_irradiance(
            self._lights,
            rail_from_tag[:, :3, 3],
            rail_from_tag[:, :3, 2],
            np.stack([self.rig.rail_from_eyepoint(float(p)) for p in items.p]),
        )
