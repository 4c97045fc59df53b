"""Commands on simulated results: run an experiment, report it, compare its variants."""

from __future__ import annotations

from pathlib import Path

import typer

from simgap.cli.app import CACHE_HELP, SCHEDULER_HELP, _experiment, app


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
