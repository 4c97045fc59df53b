"""What the layers above the pipeline may ask of it: simulate, re-run one variant, frames.

The diagnosis and the blind validation need three things from the cached pipeline and nothing
else: an experiment simulated as a result dataset; the results of one variant state (any effects
applied to the experiment's baseline) for a chosen set of configurations; and the frames of an
experiment's first variant (to write them as a capture folder). :class:`Simulator` offers exactly
these, so that code above this layer never touches the sweep's stages, caches or process-wide
memo tables.

Examples
--------
>>> sim = Simulator(cache_dir)                         # doctest: +SKIP
>>> ds = sim.dataset(exp)                              # every configuration, variant, repeat
>>> res = sim.run(exp, state, p=3, theta=0.0, repeat=0)  # one ConfigResult (tag order)
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import xarray as xr

from simgap.effects.state import VariantState
from simgap.pipeline.cache import Cache, content_hash
from simgap.pipeline.experiment import Experiment
from simgap.pipeline.sweep import run_experiment
from simgap.pipeline.variant import Frame, VariantPipeline, assets_hash
from simgap.pose.tags import ConfigResult


class Simulator:
    """The cached render -> frame -> pose pipeline, seen from the layers above it.

    One simulator is an explicit context: the variant pipelines it builds are kept on the
    instance (not in a process-wide table), keyed by the content hash of experiment and state.

    Parameters
    ----------
    cache_dir : Path
        Cache folder of renders, frames and results (see :mod:`simgap.pipeline.cache`).
    scheduler : str, optional
        Address of a Dask scheduler for :meth:`dataset`; default: a LocalCluster on
        this machine (:data:`simgap.pipeline.sweep.PROCESS_SWEEP_MIN_PAIRS`).
    show_progress : bool
        Show a progress bar while :meth:`dataset` runs.
    """

    def __init__(
        self, cache_dir: Path, scheduler: str | None = None, show_progress: bool = True
    ) -> None:
        self.cache_dir = Path(cache_dir)
        self.scheduler = scheduler
        self.show_progress = show_progress
        self._cache = Cache(self.cache_dir)
        self._assets = ""  # content hash of the fixture assets, computed on first use
        self._pipes: dict[str, VariantPipeline] = {}

    def dataset(self, exp: Experiment) -> xr.Dataset:
        """Every configuration, variant and repeat of ``exp`` as a result dataset (m, rad, px)."""
        return run_experiment(
            exp, self.cache_dir, show_progress=self.show_progress, scheduler=self.scheduler
        )

    __call__ = dataset

    def tags(self, exp: Experiment) -> tuple[int, ...]:
        """Tag ids of ``exp`` in the order of every :class:`ConfigResult`'s first axis."""
        return tuple(int(t) for t in exp.configuration_axes()[2])

    def state_key(self, exp: Experiment, state: VariantState) -> str:
        """Content hash of everything that decides ``state``'s results under ``exp``.

        Rig, state, tags, crop margin and the fixture assets; equal keys give equal results, so
        callers may memoise on it.
        """
        if not self._assets:
            self._assets = assets_hash()
        return content_hash(
            "simulator", exp.rig_model, state, self.tags(exp), exp.render.margin_px,
            self._assets,
        )

    def _pipeline(self, exp: Experiment, state: VariantState) -> VariantPipeline:
        key = self.state_key(exp, state)
        if key not in self._pipes:
            self._pipes[key] = VariantPipeline(
                exp.rig_model,
                state,
                self.tags(exp),
                exp.render.margin_px,
                self._cache,
                self._assets,
            )
        return self._pipes[key]

    def run(
        self, exp: Experiment, state: VariantState, p: int, theta: float, repeat: int = 0
    ) -> ConfigResult:
        """Detection and pose of every tag at one configuration under ``state`` (cached).

        Parameters
        ----------
        exp : Experiment
            Supplies the rig, tags and render settings.
        state : VariantState
            The variant: any effects applied to one of ``exp``'s variant states.
        p : int
            Pin hole.
        theta : float
            Turntable angle (rad).
        repeat : int
            Repeat index: the noise seed of a stochastic image pipeline (the render is repeat 0).
        """
        return self._pipeline(exp, state).run(int(p), float(theta), int(repeat), 0)

    def frame(
        self, exp: Experiment, state: VariantState, p: int, theta: float, repeat: int = 0
    ) -> Frame | None:
        """The 8-bit frame of one configuration under ``state`` (cached).

        None if no sticker faces the camera. Its ``crop`` holds the stickers, ``record`` the
        camera's choices (``auto_exposure_ev``).
        """
        render_repeat = exp.render.render_repeat(int(repeat))
        return self._pipeline(exp, state).frame(int(p), float(theta), int(repeat), render_repeat)

    def frames(self, exp: Experiment) -> Iterator[tuple[int, float, int, np.ndarray]]:
        """``(p, theta (rad), repeat, RGB uint8 H x W x 3)`` of ``exp``'s first variant.

        Every repeat of ``exp`` (they differ in image-stage noise, and in the render too with
        ``render.reseed_repeats``). Configurations where no sticker faces the camera are
        skipped. Frames already made by :meth:`dataset` come from the cache.
        """
        state = exp.variant_states()[0][1]
        pipe = self._pipeline(exp, state)
        ps, thetas, _ = exp.configuration_axes()
        for p in ps:
            for theta in thetas:
                for repeat in range(exp.repeats):
                    render_repeat = exp.render.render_repeat(repeat)
                    frame = pipe.frame(int(p), float(theta), repeat, render_repeat)
                    if frame is None:
                        break
                    yield int(p), float(theta), repeat, frame.rgb()
