"""Run an experiment: for every (p, theta), every variant and repeat, render -> frame -> pose.

Stages and their caches (:mod:`simgap.pipeline.cache`), each keyed by a content hash of its inputs
only, so a variant reuses everything upstream of the first stage it changes
(docs/conventions.md §2):

=========  ===============================================  ====================================
product    key depends on                                    stored as
=========  ===============================================  ====================================
render     scene state (lights, materials, optics, true      linear HDR crop, half-float EXR
           camera, true geometry, quality, seed), p,
           theta, margin
frame      render key, image state, noise seed (repeat)      8-bit sRGB crop PNG + offset JSON
result     frame key, estimation state, tags                 ``.npz`` of corners, poses, errors
=========  ===============================================  ====================================

Only the pixels near the stickers facing the camera are rendered (:mod:`simgap.pipeline.region`),
in their bounding crop; the detector reads the window of the full-size frame around that crop,
with its size-relative thresholds set for the real image size (docs/conventions.md §4), which
finds what the whole frame would (:attr:`simgap.pose.detect.Detector.window_pad_px`).
Work is spread over a Dask scheduler: a ``LocalCluster`` by default (two worker processes from
:data:`PROCESS_SWEEP_MIN_PAIRS` configuration-variant pairs on, else one in-process worker
thread), or any cluster by address; one task is one (p, theta) for all variants and repeats, so
renders are shared in a task.
"""

from __future__ import annotations

import json
import logging
import os
import platform
from pathlib import Path

import cv2
import numpy as np
import xarray as xr
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

import simgap
from simgap.pipeline.cache import Cache, content_hash
from simgap.pipeline.experiment import Experiment
from simgap.pipeline.variant import VariantPipeline, assets_hash
from simgap.pose.tags import RESULT_FIELDS
from simgap.results.contract import CONVENTIONS
from simgap.results.dataset import build_dataset, empty_results

_PIPELINES: dict[str, list[VariantPipeline]] = {}


def experiment_pipelines(exp: Experiment, cache_dir: Path) -> list[VariantPipeline]:
    """One pipeline per variant (cached per process: Dask workers keep them between tasks)."""
    key = content_hash("pipelines", exp.to_yaml(), str(cache_dir))
    if key not in _PIPELINES:
        _, _, tags = exp.configuration_axes()
        assets = assets_hash()
        cache = Cache(cache_dir)
        rig = exp.rig_model
        margin = exp.render.margin_px
        states = [state for _, state in exp.variant_states()]
        _PIPELINES[key] = [
            VariantPipeline(rig, state, tags, margin, cache, assets, scenes_alive=len(states))
            for state in states
        ]
    return _PIPELINES[key]


def run_task(exp: Experiment, cache_dir: str, p: int, theta: float) -> dict[str, np.ndarray]:
    """All variants and repeats of one (p, theta): arrays shaped (V, R, T, ...)."""
    pipes = experiment_pipelines(exp, Path(cache_dir))
    reps = exp.repeats
    out: dict[str, list] = {k: [] for k in RESULT_FIELDS}
    for pipe in pipes:
        rows = []
        for r in range(reps):
            render_repeat = exp.render.render_repeat(r)
            if r > 0 and not pipe.state.image.stochastic and not exp.render.reseed_repeats:
                rows.append(rows[0])  # deterministic pipeline: every repeat is the same frame
                continue
            rows.append(pipe.run(p, theta, r, render_repeat))
        for k in RESULT_FIELDS:
            out[k].append(np.stack([getattr(row, k) for row in rows]))
    return {k: np.stack(v) for k, v in out.items()}


def preflight(exp: Experiment) -> None:
    """Build every distinct variant scene once (tiny film) so bad scene settings fail up front.

    Raises
    ------
    simgap.core.config.ConfigError
        Naming the variant whose scene Mitsuba cannot build.
    """
    from simgap.core.config import ConfigError
    from simgap.render.scene import FixtureScene

    seen = set()
    for name, state in exp.variant_states():
        key = content_hash(state.scene.spec)
        if key in seen:
            continue
        seen.add(key)
        try:
            FixtureScene(exp.rig_model, state.scene.spec, (8, 8), 1)
        except ConfigError as exc:
            raise ConfigError(f"variant {name!r}: {exc}") from exc


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeRemainingColumn(),
    )


#: Sweeps of at least this many configuration-variant pairs (each a render and its frames) run
#: on two local worker processes; smaller ones on one in-process worker thread (starting the
#: processes costs about 6 s; docs/results/sweep_breakdown.md). A task is one configuration with
#: all its variants, so a sweep of few configurations and many variants is large too (the
#: orbital study: 12 configurations x 73 sun directions).
PROCESS_SWEEP_MIN_PAIRS = 100


def _client(scheduler: str | None, configurations: int, variants: int):
    """A Dask client, its local cluster (None for an address) and what the scheduler is.

    Every render already uses all cores (Dr.Jit's thread pool), but a third of a
    configuration's time is single-threaded Python (detection, image statistics, IO): two
    worker processes overlap one's Python with the other's kernels (measured on 2 cores:
    1.2x faster over 180 configurations once started). A small sweep does not pay back their
    start-up and runs on one in-process worker thread.
    """
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None, scheduler
    processes = (
        configurations >= 2
        and configurations * variants >= PROCESS_SWEEP_MIN_PAIRS
        and (os.cpu_count() or 1) >= 2
    )
    # a worker whose heartbeat races the scheduler's shutdown on a busy machine logs a
    # traceback at ERROR after the sweep is done and written (seen on 2 cores under load); the
    # sweep's own failures reach the caller through its futures, so the cluster's logs are
    # silenced below CRITICAL
    cluster = LocalCluster(
        n_workers=2 if processes else 1,
        threads_per_worker=1,
        processes=processes,
        dashboard_address=":0",
        silence_logs=logging.CRITICAL,
    )
    where = "LocalCluster, 2 worker processes" if processes else "in-process LocalCluster"
    return Client(cluster), cluster, where


def run_experiment(
    exp: Experiment,
    cache_dir: Path,
    show_progress: bool = True,
    scheduler: str | None = None,
) -> xr.Dataset:
    """Run every configuration, variant and repeat of ``exp``; return the result dataset.

    Parameters
    ----------
    exp : Experiment
        The experiment.
    cache_dir : Path
        Cache folder (must be reachable by the workers under the same path).
    show_progress : bool
        Show a progress bar with counts and rate.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://HOST:PORT``); default: a LocalCluster on
        this machine (:data:`simgap.pipeline.sweep.PROCESS_SWEEP_MIN_PAIRS`).
    """
    from distributed import as_completed

    ps, thetas, tags = exp.configuration_axes()
    names = [name for name, _ in exp.variant_states()]
    shape = (len(names), exp.repeats, len(tags), len(ps), len(thetas))
    res = empty_results(shape)
    configs = [(i, j) for i in range(len(ps)) for j in range(len(thetas))]
    preflight(exp)
    client, cluster, where = _client(scheduler, len(configs), len(names))
    try:
        futures = {
            client.submit(run_task, exp, str(cache_dir), ps[i], float(thetas[j]), pure=False): (
                i,
                j,
            )
            for i, j in configs
        }
        with _progress() as bar:
            task = bar.add_task(exp.name, total=len(configs), rate="", visible=show_progress)
            for n, fut in enumerate(as_completed(futures), 1):
                i, j = futures[fut]
                for k, v in fut.result().items():
                    res[k][:, :, :, i, j] = v
                elapsed = bar.tasks[0].elapsed or 1e-9
                bar.update(task, advance=1, rate=f"{n / elapsed:.1f} cfg/s")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    rig = exp.rig_model
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in thetas] for p in ps] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in thetas] for p in ps] for t in tags])
    return build_dataset(
        tags,
        ps,
        thetas,
        expected,
        visible,
        res,
        variants=tuple(names),
        repeats=tuple(range(exp.repeats)),
        attrs=dataset_attrs(exp, where),
    )


def dataset_attrs(exp: Experiment, scheduler: str) -> dict[str, str]:
    """Provenance attributes: resolved config, seeds, versions, renderer, detector and PnP.

    ``scheduler`` says where the sweep ran (an address, or which local cluster).
    """
    import distributed
    import drjit
    import mitsuba

    from simgap.render.backend import choose_variant

    states = exp.variant_states()
    return {
        "title": f"simgap result: {exp.name}",
        "experiment": exp.name,
        "experiment_yaml": exp.to_yaml(),
        "seed": str(exp.render.seed),
        "repeats": str(exp.repeats),
        "variant_effects": json.dumps({spec.name: spec.effects for spec in exp.variant_specs()}),
        "simgap_version": simgap.__version__,
        "mitsuba_version": mitsuba.__version__,
        "drjit_version": drjit.__version__,
        "opencv_version": cv2.__version__,
        "numpy_version": np.__version__,
        "xarray_version": xr.__version__,
        "dask_distributed_version": distributed.__version__,
        "python_version": platform.python_version(),
        "renderer_variant": choose_variant(),
        "scheduler": scheduler,
        "render_region": f"pixels within {exp.render.margin_px} px of a facing sticker",
        "detector": json.dumps({n: f"{s.estimation.detector}" for n, s in states}),
        "pnp": json.dumps({n: f"{s.estimation.pnp}" for n, s in states}),
        "conventions": CONVENTIONS,
    }
