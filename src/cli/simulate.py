"""Commands on simulated results: run an experiment, report it, compare its variants."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from simgap.cli.app import app, fail, read_experiment, read_result_dataset
from simgap.cli.options import (
    CacheOption,
    CalibrationOption,
    OverwriteOption,
    ProgressOption,
    SchedulerOption,
    output_option,
)
from simgap.cli.outputs import (
    COMPARISON_FOLDER,
    OUTPUT,
    REPORT_FOLDER,
    RESULT_DATASET,
    check_experiment_output,
    check_outputs,
)


@app.command()
def run(
    experiment: Annotated[
        Path, typer.Argument(help="Experiment YAML (e.g. experiments/smoke.yaml).")
    ],
    output: Annotated[Path, output_option("Result dataset to write (netCDF).")],
    cache: CacheOption = None,
    progress: ProgressOption = True,
    scheduler: SchedulerOption = None,
    calibration: CalibrationOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Run an experiment and write its result dataset."""
    from simgap.core.paths import default_cache_dir
    from simgap.pipeline.sweep import run_experiment
    from simgap.results.dataset import write_netcdf

    check_experiment_output(experiment, output, RESULT_DATASET, overwrite, calibration)
    exp = read_experiment(experiment, calibration)
    ds = run_experiment(exp, cache or default_cache_dir(), progress, scheduler)
    write_netcdf(ds, output)
    vis = ds.visible.values
    det = ds.detected.values[0, 0]
    typer.echo(
        f"wrote {output}: {ds.sizes['variant']} variant(s) x {ds.sizes['repeat']} repeat(s); "
        f"baseline: {vis.sum()} visible items (tag x configuration), {(det & vis).sum()} detected"
    )


MODEL_HELP = "Error model (.nc or .json): draw its bands over the data."


@app.command()
def report(
    result: Annotated[Path, typer.Argument(help="Result dataset (netCDF) from simgap run.")],
    output: Annotated[Path, output_option("Report folder to write.")],
    model: Annotated[Path | None, typer.Option("--model", help=MODEL_HELP)] = None,
    cache: CacheOption = None,
    progress: ProgressOption = True,
    overwrite: OverwriteOption = False,
) -> None:
    """Write figures and the paper-style Table 2 (and, for several variants, the comparison).

    A sweep over the sun's direction (experiments/orbital_lighting.yaml) gets the sun's section
    instead of the comparison: polar maps of detection and error, the configurations outside
    the envelope and the worst directions' frames (read from the cache, or rendered).

    A board's photo set (`simgap ingest --board`, with or without --simulate) gets its own
    report: errors near / mid / far, and with its simulation the camera fitted and the gap
    before -> after per third of distance, view angle and image radius.
    """
    from simgap.analysis.report import (
        is_photo_dataset,
        write_photo_report,
        write_report,
        write_sun_report,
    )
    from simgap.cli.progress import StepBars
    from simgap.core.config import ConfigError
    from simgap.core.outputs import claimed_folder
    from simgap.results.contract import check_dataset
    from simgap.results.dataset import read_netcdf

    inputs = [("RESULT", result), ("--model", model)]
    check_outputs([(OUTPUT, output, REPORT_FOLDER)], inputs, overwrite)
    data = read_netcdf(result)
    if is_photo_dataset(data):
        if model is not None:
            fail(f"--model: {result} is a board's photo set; an error model is drawn over a PASS "
                 "result dataset")  # fmt: skip
        with claimed_folder(output):
            try:
                paths = write_photo_report(data, output)
            except ConfigError as exc:
                fail(f"{result}: {exc}")
        for p in paths:
            typer.echo(str(p))
        return
    ds = check_dataset(data, result)
    with claimed_folder(output), StepBars(progress) as bars:
        paths = write_report(ds, output, progress=bars)
        sun = write_sun_report(ds, output, cache)
        paths += sun
        if ds.sizes.get("variant", 1) > 1 and not sun:  # compare the variants with the reference
            from simgap.analysis.report import write_comparison

            paths += write_comparison(ds, output, progress=bars)
        if model is not None:
            from simgap.analysis.report import write_error_model_bands

            paths.append(write_error_model_bands(model, ds, output))
    for p in paths:
        typer.echo(str(p))


@app.command()
def compare(
    result: Annotated[Path, typer.Argument(help="Result dataset (netCDF) with several variants.")],
    output: Annotated[Path, output_option("Comparison folder to write.")],
    baseline: str | None = typer.Option(
        None, "--baseline", help="Reference variant (default: 'baseline', else the first)."
    ),
    progress: ProgressOption = True,
    overwrite: OverwriteOption = False,
) -> None:
    """Compare each variant of a result dataset with the reference variant."""
    from simgap.analysis.report import write_comparison
    from simgap.cli.progress import StepBars
    from simgap.core.outputs import claimed_folder

    check_outputs([(OUTPUT, output, COMPARISON_FOLDER)], [("RESULT", result)], overwrite)
    ds = read_result_dataset(result)
    with claimed_folder(output), StepBars(progress) as bars:
        paths = write_comparison(ds, output, baseline, progress=bars)
    for p in paths:
        typer.echo(str(p))
