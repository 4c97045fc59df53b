"""simgap: simulate the PASS fixture study, compare rendering options, diagnose the sim-to-real gap.

Commands: run, report, compare, study, ingest, export-bag, errormodel, diagnose, validate, effects,
assets.

Every error exits with code 2 and one line naming the file, key and expectation (``--debug``
shows the traceback instead).
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import typer

from simgap.core.config import ConfigError

_STATE = {"debug": False}


def _error_line(exc: BaseException, paths: list[Path]) -> str:
    """One line for ``exc``, prefixed with the command's input file unless it names a file."""
    if isinstance(exc, OSError) and exc.filename and exc.strerror:
        message = f"{exc.filename}: {exc.strerror}"
    elif isinstance(exc, (ConfigError, ValueError, OSError)):
        message = str(exc)
    elif isinstance(exc, MemoryError):
        message = "out of memory (reduce the experiment's size)"
    else:
        message = f"{type(exc).__name__}: {exc} (unexpected; rerun with --debug for the traceback)"
    if paths and not any(str(p) in message for p in paths):
        message = f"{paths[0]}: {message}"
    return " ".join(message.split())


def _handle_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Run a command; any error exits with code 2 and one line (the traceback with --debug)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except Exception as exc:
            if _STATE["debug"]:
                raise
            bound = inspect.signature(func).bind_partial(*args, **kwargs).arguments
            paths = [v for v in bound.values() if isinstance(v, Path)]
            _fail(_error_line(exc, paths))

    return wrapper


class _App(typer.Typer):
    """A Typer app whose commands all go through :func:`_handle_errors` (one place)."""

    def command(self, *args: Any, **kwargs: Any) -> Callable[[Callable], Callable]:
        """Register a command, wrapped by :func:`_handle_errors`."""
        register = super().command(*args, **kwargs)
        return lambda func: register(_handle_errors(func))


app = _App(add_completion=False, no_args_is_help=True, help=__doc__)


@app.callback()
def main(
    debug: bool = typer.Option(
        False, "--debug", help="Show the full traceback of an error instead of one line."
    ),
) -> None:
    """Simulate the PASS fixture study, compare rendering options, diagnose the sim-to-real gap."""
    _STATE["debug"] = debug


CACHE_HELP = "Cache folder for renders and results (default: $SIMGAP_CACHE or ~/.cache/simgap)."
SCHEDULER_HELP = (
    "Dask scheduler address (tcp://HOST:PORT); default: an in-process LocalCluster. "
    "Workers must see the cache folder under the same path."
)


def _fail(message: str) -> None:
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code=2)


def _experiment(path: Path):
    """Load an experiment file (errors name the file and key)."""
    from simgap.pipeline.experiment import load_experiment

    return load_experiment(path)


@app.command()
def run(
    experiment: Path = typer.Argument(..., help="Experiment YAML (e.g. experiments/smoke.yaml)."),
    output: Path = typer.Option(..., "-o", "--output", help="Result dataset to write (netCDF)."),
    cache: Path | None = typer.Option(None, "--cache", help=CACHE_HELP),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar."),
    scheduler: str | None = typer.Option(None, "--scheduler", help=SCHEDULER_HELP),
) -> None:
    """Run an experiment and write its result dataset."""
    from simgap.core.paths import default_cache_dir
    from simgap.pipeline.sweep import run_experiment
    from simgap.results.dataset import write_netcdf

    exp = _experiment(experiment)
    ds = run_experiment(exp, cache or default_cache_dir(), progress, scheduler)
    write_netcdf(ds, output)
    vis = ds.visible.values
    det = ds.detected.values[0, 0]
    typer.echo(
        f"wrote {output}: {ds.sizes['variant']} variant(s) x {ds.sizes['repeat']} repeat(s); "
        f"baseline: {vis.sum()} visible tag configurations, {(det & vis).sum()} detected"
    )


@app.command()
def report(
    result: Path = typer.Argument(..., help="Result dataset (netCDF) from `simgap run`."),
    output: Path = typer.Option(..., "-o", "--output", help="Report folder to write."),
    model: Path | None = typer.Option(
        None, "--model", help="Error model (.nc or .json): draw its bands over the data."
    ),
) -> None:
    """Write figures and the paper-style Table 2 (and, for several variants, the comparison)."""
    from simgap.analysis.report import write_report
    from simgap.results.dataset import check_dataset, read_netcdf

    ds = check_dataset(read_netcdf(result), result)
    paths = write_report(ds, output)
    if ds.sizes.get("variant", 1) > 1:  # several variants: compare them with the reference
        from simgap.analysis.compare import write_comparison

        paths += write_comparison(ds, output)
    if model is not None:
        from simgap.analysis.errormodel_report import write_error_model_bands

        paths.append(write_error_model_bands(model, ds, output))
    for p in paths:
        typer.echo(str(p))


@app.command()
def compare(
    result: Path = typer.Argument(..., help="Result dataset (netCDF) with several variants."),
    output: Path = typer.Option(..., "-o", "--output", help="Comparison folder to write."),
    baseline: str | None = typer.Option(
        None, "--baseline", help="Reference variant (default: 'baseline', else the first)."
    ),
) -> None:
    """Compare each variant of a result dataset with the reference variant."""
    from simgap.analysis.compare import write_comparison
    from simgap.results.dataset import check_dataset, read_netcdf

    ds = check_dataset(read_netcdf(result), result)
    paths = write_comparison(ds, output, baseline)
    for p in paths:
        typer.echo(str(p))


@app.command()
def ingest(
    capture: Path = typer.Argument(
        ..., help="Capture folder (camera.yaml, manifest.csv, images), ROS 1 .bag or ROS 2 bag."
    ),
    output: Path = typer.Option(..., "-o", "--output", help="Result dataset to write (netCDF)."),
    experiment: Path | None = typer.Option(
        None, "--experiment", help="Take rig, detector and PnP settings from this experiment YAML."
    ),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar."),
    ranges: Path | None = typer.Option(
        None,
        "--ranges",
        help="Bag only: CSV start_ns,end_ns,p,theta_rad giving each frame's p, theta.",
    ),
    image_topic: str | None = typer.Option(None, "--image-topic", help="Bag only: frames topic."),
    camera_info_topic: str | None = typer.Option(
        None, "--camera-info-topic", help="Bag only: CameraInfo topic."
    ),
    fixture_topic: str | None = typer.Option(
        None, "--fixture-topic", help="Bag only: JointState topic (default /simgap/fixture)."
    ),
    keep_capture: Path | None = typer.Option(
        None, "--keep-capture", help="Bag only: keep the intermediate capture folder here."
    ),
) -> None:
    """Detect markers and estimate poses in a real capture or ROS bag; write its result dataset."""
    from simgap.pipeline.capture import ingest as ingest_capture
    from simgap.results.dataset import write_netcdf

    kwargs = {}
    if experiment is not None:
        exp = _experiment(experiment)
        kwargs = {"rig": exp.rig_model, "detector": exp.detector, "pnp": exp.pnp}
    from simgap.pipeline.bag import ingest_bag, is_bag

    if is_bag(capture):
        bag_options = {
            "ranges_csv": ranges,
            "image_topic": image_topic,
            "camera_info_topic": camera_info_topic,
            "fixture_topic": fixture_topic,
            "keep_capture": keep_capture,
        }
        ds = ingest_bag(capture, show_progress=progress, **bag_options, **kwargs)
    else:
        ds = ingest_capture(capture, show_progress=progress, **kwargs)
    write_netcdf(ds, output)
    vis = ds.visible.values
    det = ds.detected.values[0].any(axis=0)
    typer.echo(
        f"wrote {output}: {ds.attrs['frames']} frame(s), {ds.attrs['frames_unreadable']} "
        f"unreadable; {vis.sum()} visible tag configurations, {(det & vis).sum()} detected"
    )


@app.command("export-bag")
def export_bag(
    source: Path = typer.Argument(
        ..., help="Experiment YAML, simulated result dataset (.nc) or capture folder."
    ),
    output: Path = typer.Option(..., "-o", "--output", help="Bag to write: .bag file or folder."),
    fmt: str | None = typer.Option(
        None, "--format", help="ros1 or ros2 (default: ros1 for a .bag output, else ros2)."
    ),
    compressed: bool = typer.Option(
        False, "--compressed/--raw", help="CompressedImage (PNG, or the file's bytes) or raw bgr8."
    ),
    variant: str | None = typer.Option(
        None, "--variant", help="Variant to export (default: first)."
    ),
    cache: Path | None = typer.Option(None, "--cache", help=CACHE_HELP),
) -> None:
    """Write frames, CameraInfo, fixture joints and tag poses as a ROS 1 or ROS 2 bag."""
    from simgap.core.paths import default_cache_dir
    from simgap.pipeline.bag import BAG_FORMATS, capture_to_bag, experiment_to_bag

    fmt = fmt or ("ros1" if output.suffix == ".bag" else "ros2")
    if fmt not in BAG_FORMATS:
        _fail(f"--format: expected one of {', '.join(BAG_FORMATS)}, got {fmt!r}")
    if source.is_dir():
        path = capture_to_bag(source, output, fmt, compressed=compressed)
    else:
        dataset = None
        if source.suffix == ".nc":
            from simgap.results.dataset import check_dataset, read_netcdf

            dataset = check_dataset(read_netcdf(source), source)
        exp = _load_sim(source)
        cache_dir = cache or default_cache_dir()
        path = experiment_to_bag(exp, cache_dir, output, fmt, dataset, variant, compressed)
    typer.echo(f"wrote {path} ({fmt})")


@app.command("errormodel")
def errormodel(
    result: Path = typer.Argument(..., help="Result dataset (netCDF): simulated or ingested."),
    output: Path = typer.Option(..., "-o", "--output", help="Model to write (.nc; and .json)."),
    variant: str | None = typer.Option(
        None, "--variant", help="Variant to model (default: first)."
    ),
    check: bool = typer.Option(
        True, "--check/--no-check", help="Also fit on half the configurations, test on the rest."
    ),
) -> None:
    """Fit a pose-error and detection model a controller can load (netCDF and JSON)."""
    from simgap.analysis.errormodel import check_error_model, fit_error_model
    from simgap.results.dataset import check_dataset, read_netcdf

    ds = check_dataset(read_netcdf(result), result)
    model = fit_error_model(ds, variant=variant, source=str(result))
    summary = check_error_model(ds, variant=variant) if check else None
    for path in model.save(output):
        typer.echo(str(path))
    if summary is not None:
        cover = ", ".join(f"{a} {v:.0%}" for a, v in summary["coverage"].items())
        det = summary["detection"]
        typer.echo(
            f"held-out half: 90 % interval coverage {cover} ({summary['n_errors']} errors, "
            f"{summary['n_outside']} outside the range); detection predicted "
            f"{det['predicted_rate']:.1%} vs observed {det['observed_rate']:.1%}"
        )


def _load_sim(sim: Path):
    """An experiment from YAML, or the experiment a result dataset was made with."""
    from simgap.pipeline.experiment import experiment_from_yaml

    if sim.suffix in (".yaml", ".yml"):
        return _experiment(sim)
    from simgap.results.dataset import read_netcdf

    ds = read_netcdf(sim)
    if "experiment_yaml" not in ds.attrs:
        raise ConfigError(f"{sim}: not a simgap result dataset (no experiment_yaml attribute)")
    return experiment_from_yaml(ds.attrs["experiment_yaml"], source=str(sim))


@app.command()
def diagnose(
    real: Path = typer.Argument(..., help="Real dataset (netCDF) from `simgap ingest`."),
    sim: Path = typer.Option(..., "--sim", help="Simulation: experiment YAML or result .nc."),
    output: Path = typer.Option(..., "-o", "--output", help="Report folder to write."),
    json_path: Path | None = typer.Option(None, "--json", help="Also write result.json here."),
    cache: Path | None = typer.Option(None, "--cache", help=CACHE_HELP),
    seed: int = typer.Option(0, "--seed", help="Seed of the train/held-out split."),
    scheduler: str | None = typer.Option(None, "--scheduler", help=SCHEDULER_HELP),
) -> None:
    """Diagnose the sim-to-real gap: where, which effect, how far it shrinks."""
    from simgap.core.paths import default_cache_dir
    from simgap.diagnosis.diagnose import diagnose as run_diagnosis
    from simgap.diagnosis.diagnosis_report import write_diagnosis_report
    from simgap.diagnosis.result_json import write_json
    from simgap.diagnosis.settings import DiagnoseSettings
    from simgap.pipeline.simulator import Simulator
    from simgap.results.dataset import read_netcdf

    data = read_netcdf(real)
    exp = _load_sim(sim)
    settings = DiagnoseSettings(seed=seed)
    simulator = Simulator(cache or default_cache_dir(), scheduler=scheduler)
    result, state = run_diagnosis(data, exp, settings=settings, simulator=simulator)
    for p in write_diagnosis_report(result, state, output):
        typer.echo(str(p))
    if json_path:
        typer.echo(str(write_json(result, json_path)))
    minor = result.get("minor", [])
    if not result["where"]["significant"]:
        verdict = "no significant gap"
    else:
        named = [f"{e} (minor)" if e in minor else e for e in result["selected"]]
        verdict = "selected: " + (", ".join(named) or "-")
        if result["unexplained"]:
            verdict += f"; unexplained: {', '.join(result['unexplained_evidence'])}"
    typer.echo(f"diagnosis: {verdict}")


@app.command()
def validate(
    trials: int = typer.Option(30, "--trials", help="Number of blind trials."),
    seed: int = typer.Option(0, "--seed", help="Seed of the hidden draws."),
    output: Path = typer.Option(Path("validation"), "-o", "--output", help="Report folder."),
    experiment: Path = typer.Option(
        Path("experiments/baseline.yaml"), "--experiment", help="Simulation experiment."
    ),
    cache: Path | None = typer.Option(None, "--cache", help=CACHE_HELP),
) -> None:
    """Blind validation: hidden effects -> pseudo-real captures -> diagnosis -> scores."""
    from simgap.core.paths import default_cache_dir
    from simgap.diagnosis.validate import ValidateSettings, run_validation

    exp = _experiment(experiment)
    settings = ValidateSettings(trials=trials, seed=seed)
    summary = run_validation(exp, output, cache or default_cache_dir(), settings, log=typer.echo)
    typer.echo((output / "validation.md").read_text())
    typer.echo(
        f"top-1 accuracy {summary['top1_accuracy']}, "
        f"no-effect correct {summary['no_effect_correct']}"
    )


@app.command()
def effects() -> None:
    """List the effects catalogue: name, stage, what it models, parameters and defaults."""
    import dataclasses

    from simgap.effects import EFFECTS

    for name in sorted(EFFECTS, key=lambda n: (EFFECTS[n].stage, n)):
        cls = EFFECTS[name]
        doc = " ".join((cls.__doc__ or "").split("\n\n")[0].split())
        defaults = cls.Params()
        params = ", ".join(
            f"{f.name}={getattr(defaults, f.name)!r}" for f in dataclasses.fields(cls.Params)
        )
        typer.echo(f"{name:20s} [{cls.stage}] {doc}\n{'':21s} {params}")


@app.command()
def assets() -> None:
    """Regenerate fixture meshes and tag textures in assets/."""
    from simgap.render.assets import write_assets

    for p in write_assets():
        typer.echo(str(p))


@app.command()
def study(
    experiment: Path = typer.Argument(Path("experiments/baseline.yaml"), help="Experiment YAML."),
    output: Path = typer.Option(Path("results"), "-o", "--output", help="Output folder."),
    cache: Path | None = typer.Option(None, "--cache", help=CACHE_HELP),
    scheduler: str | None = typer.Option(None, "--scheduler", help=SCHEDULER_HELP),
) -> None:
    """Run an experiment and write its report: OUTPUT/<name>.nc and OUTPUT/<name>-report/."""
    name = _experiment(experiment).name
    nc = output / f"{name}.nc"
    run(experiment, nc, cache, True, scheduler)
    report(nc, output / f"{name}-report", None)


if __name__ == "__main__":
    app()
