"""Commands that explain the gap: error model, diagnosis, blind validation."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from simgap.cli.app import app, fail, read_experiment, read_result_dataset, read_simulation
from simgap.cli.options import (
    CacheOption,
    CalibrationOption,
    OverwriteOption,
    ProgressOption,
    SchedulerOption,
    VariantOption,
    one_experiment,
    output_option,
)
from simgap.cli.outputs import (
    DIAGNOSIS_FOLDER,
    DIAGNOSIS_JSON,
    ERROR_MODEL,
    OUTPUT,
    VALIDATION_FOLDER,
    check_outputs,
    experiment_inputs,
    simulation_inputs,
)

if TYPE_CHECKING:
    from simgap.diagnosis.validation_summary import ValidationSummary


@app.command("errormodel")
def errormodel(
    result: Annotated[Path, typer.Argument(help="Result dataset (netCDF): simulated or ingested.")],
    output: Annotated[Path, output_option("Model to write (.nc; and .json).")],
    variant: VariantOption = None,
    pool: bool = typer.Option(
        False,
        "--pool-variants",
        help="Model every variant's repeats as draws of one: a Monte Carlo over what the "
        "variants vary (the sun's direction of experiments/orbital_lighting.yaml); the check "
        "then fits on every other variant and tests on the rest.",
    ),
    check: bool = typer.Option(
        True, "--check/--no-check", help="Also fit on half the configurations, test on the rest."
    ),
    overwrite: OverwriteOption = False,
) -> None:
    """Fit a pose-error and detection model a controller can load (netCDF and JSON)."""
    from simgap.analysis.errormodel import check_error_model, fit_error_model, model_paths

    # the model is written as netCDF and JSON: OUTPUT and its other file
    outputs = [(OUTPUT, output, ERROR_MODEL)]
    other = next(p for p in model_paths(output) if p != output)
    outputs.append((f"{OUTPUT} (its {other.suffix})", other, ERROR_MODEL))
    check_outputs(outputs, [("RESULT", result)], overwrite)
    ds = read_result_dataset(result)
    if pool and variant is not None:
        fail("--pool-variants models every variant at once: expected no --variant with it")
    pooled_check = None
    if pool:
        from simgap.analysis.errormodel import check_pooled_model
        from simgap.results.dataset import pooled_variants

        if check and ds.sizes["variant"] > 1:
            pooled_check = check_pooled_model(ds)
        ds = pooled_variants(ds)
    from simgap.analysis.errormodel import FIT_METHODS, FitSettings

    model = fit_error_model(ds, variant=variant, source=str(result))
    summary, skipped = None, ""
    if pooled_check is not None:
        summary = pooled_check
    elif check and not pool:
        try:
            summary = check_error_model(ds, variant=variant)
        except ValueError as exc:  # half of a small dataset: too few detections to fit
            skipped = str(exc)
    for path in model.save(output):
        typer.echo(str(path))
    described = {
        "local": "local fit",
        "pooled": "pooled: constant bias and spread over its span, wide t(n-1) 90 % "
        "intervals, no correlation (fewer detections than the local fit's "
        f"{FitSettings().min_detections})",
        "none": "not fitted (too few detections)",
    }
    for tag, n, how in zip(
        model.tags, model.ds.detections.values, model.ds.fit.values, strict=True
    ):
        typer.echo(f"tag {tag}: {int(n)} detections, {described[FIT_METHODS[int(how)]]}")
    if skipped:
        typer.echo(f"check skipped: on half the configurations {skipped}")
    if summary is not None and summary["n_errors"] == 0:
        typer.echo(
            f"check half: none of its errors lies inside the range the fit "
            f"half spans ({summary['n_outside']} outside it): nothing to check"
        )
    elif summary is not None:
        cover = ", ".join(f"{a} {v:.0%}" for a, v in summary["coverage"].items())
        det = summary["detection"]
        half = "check half (variants)" if pool else "check half"
        typer.echo(
            f"{half}: 90 % interval coverage {cover} ({summary['n_errors']} errors, "
            f"{summary['n_outside']} outside the range); detection predicted "
            f"{det['predicted_rate']:.1%} vs observed {det['observed_rate']:.1%}"
        )


@app.command()
def diagnose(
    real: Annotated[Path, typer.Argument(help="Real dataset (netCDF) from simgap ingest.")],
    output: Annotated[Path, output_option("Report folder to write.")],
    experiment: Annotated[
        Path | None,
        typer.Argument(help="The simulation: experiment YAML or result .nc (also --sim)."),
    ] = None,
    sim: Annotated[Path | None, typer.Option("--sim", hidden=True)] = None,
    calibration: CalibrationOption = None,
    json_path: Path | None = typer.Option(
        None, "--json", help="Also copy the report folder's result.json here."
    ),
    cache: CacheOption = None,
    seed: int = typer.Option(
        0, "--seed", help="Seed of the fit / choose / measure split (>= 0).", min=0
    ),
    converged_simulation: bool = typer.Option(
        True,
        "--converged-simulation/--path-simulation",
        help="Simulate a converged experiment converged (the default), or path traced at 16 spp.",
    ),
    progress: ProgressOption = True,
    scheduler: SchedulerOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Diagnose the sim-to-real gap: where, which effect, how far it shrinks.

    Writes result.json and evidence.nc into OUTPUT, then the report (diagnosis.md and figures)
    from those two files alone, as report-diagnosis writes it again.
    """
    from simgap.cli.progress import StepBars
    from simgap.core.atomic import atomic_copy
    from simgap.core.outputs import claimed_folder
    from simgap.core.paths import default_cache_dir
    from simgap.diagnosis.diagnose import diagnose as run_diagnosis
    from simgap.diagnosis.diagnosis_files import (
        RESULT_FILE,
        read_diagnosis_files,
        write_diagnosis_files,
    )
    from simgap.diagnosis.diagnosis_report import selected_names, write_diagnosis_report
    from simgap.diagnosis.settings import DiagnoseSettings
    from simgap.pipeline.simulator import Simulator
    from simgap.results.dataset import read_netcdf

    sim = one_experiment(experiment, sim, "--sim")
    if sim is None:
        fail("EXPERIMENT: the simulation to compare with is needed (an experiment YAML or .nc)")
    if calibration is not None and sim.suffix not in (".yaml", ".yml"):
        fail(f"--calibration: only with an experiment YAML ({sim} is a result dataset)")
    outputs = [(OUTPUT, output, DIAGNOSIS_FOLDER), ("--json", json_path, DIAGNOSIS_JSON)]
    inputs = [("REAL", real), ("--calibration", calibration)]
    check_outputs(outputs, inputs + simulation_inputs(sim, "EXPERIMENT"), overwrite)
    data = read_netcdf(real)
    exp = read_simulation(sim) if calibration is None else read_experiment(sim, calibration)
    settings = DiagnoseSettings(seed=seed, converged_simulation=converged_simulation)
    simulator = Simulator(cache or default_cache_dir(), scheduler, show_progress=progress)
    with StepBars(progress) as bars:
        result, state = run_diagnosis(data, exp, simulator, settings, progress=bars)
    with claimed_folder(output):
        paths = write_diagnosis_files(result, state.evidence(), output)
        paths += write_diagnosis_report(*read_diagnosis_files(output), output)
    for p in paths:
        typer.echo(str(p))
    if json_path:  # the bytes of OUTPUT's result.json, serialised once
        typer.echo(str(atomic_copy(output / RESULT_FILE, json_path)))
    if not result.where.significant and not result.selection:
        verdict = "no significant gap"
    else:  # a calibration effect the corners single out is a finding without a significant gap
        verdict = "selected: " + selected_names(result)
        if result.unexplained:
            names = "; ".join(map(evidence_name, result.unexplained_evidence))
            verdict += f"; unexplained: {names}"
    typer.echo(f"diagnosis: {verdict}")


@app.command("report-diagnosis")
def report_diagnosis(
    diagnosis: Annotated[
        Path,
        typer.Argument(
            help="Diagnosis folder from simgap diagnose: its result.json and evidence.nc."
        ),
    ],
    output: Annotated[
        Path | None,
        output_option(
            "Folder to write the report to (default: DIAGNOSIS itself); another folder also gets "
            "copies of result.json and evidence.nc."
        ),
    ] = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Write a diagnosis's report (diagnosis.md and its figures) again from its folder's files.

    The report is a function of result.json and evidence.nc alone: written again, from the same
    two files, it is the same byte for byte.
    """
    from simgap.core.atomic import atomic_copy
    from simgap.core.outputs import claimed_folder
    from simgap.diagnosis.diagnosis_files import EVIDENCE_FILE, RESULT_FILE, read_diagnosis_files
    from simgap.diagnosis.diagnosis_report import write_diagnosis_report

    output = diagnosis if output is None else output
    files = (RESULT_FILE, EVIDENCE_FILE)
    inputs = [(f"DIAGNOSIS ({name})", diagnosis / name) for name in files]
    check_outputs([(OUTPUT, output, DIAGNOSIS_FOLDER)], inputs, overwrite)
    result, evidence = read_diagnosis_files(diagnosis)
    with claimed_folder(output):
        copies = output.resolve() != diagnosis.resolve()
        paths = [atomic_copy(diagnosis / name, output / name) for name in files if copies]
        paths += write_diagnosis_report(result, evidence, output)
    for p in paths:
        typer.echo(str(p))


def evidence_name(name: str) -> str:
    """A piece of evidence as a reader names it.

    An image statistic by its readable name and unit (``paper level, linear [fraction of full
    scale]``), other evidence (``pose``, ``detection``) as it is.
    """
    from simgap.pose.stat_labels import STAT_LABELS

    return STAT_LABELS[name].text if name in STAT_LABELS else name


#: The simulation ``validate`` diagnoses its pseudo-real captures against by default.
DEFAULT_VALIDATION_EXPERIMENT = Path("experiments/baseline.yaml")


@app.command()
def validate(
    trials: int = typer.Option(30, "--trials", help="Number of blind trials."),
    seed: int = typer.Option(0, "--seed", help="Seed of the hidden draws (>= 0).", min=0),
    output: Path = typer.Option(Path("validation"), "-o", "--output", help="Report folder."),
    experiment: Annotated[
        Path | None,
        typer.Argument(help="Simulation experiment (default experiments/baseline.yaml)."),
    ] = None,
    experiment_alias: Annotated[Path | None, typer.Option("--experiment", hidden=True)] = None,
    cache: CacheOption = None,
    progress: ProgressOption = True,
    scheduler: SchedulerOption = None,
    shard: str = typer.Option(
        "0/1", "--shard", help="K/N: run only trials K, K+N, ... (several processes, one folder)."
    ),
    effects: str = typer.Option(
        "",
        "--effects",
        help="Comma-separated hidden effects to draw from, e.g. sensor_noise (default: all); "
        "then every trial hides one of them (two when several are given, as often as usual).",
    ),
    converged_simulation: bool = typer.Option(
        True,
        "--converged-simulation/--path-simulation",
        help="Diagnose with a converged simulation (the default), or path traced at 16 spp.",
    ),
    camera_pipeline: bool = typer.Option(
        True,
        "--camera-pipeline/--no-camera-pipeline",
        help="Give each other camera its own image pipeline (demosaicing, sharpening, "
        "denoising, black level, tone curve, lateral colour, gain changes) and some captures "
        "mostly frontal poses (the default); --no-camera-pipeline draws cameras without them.",
    ),
    print_reflectance: bool = typer.Option(
        True,
        "--drawn-print/--nominal-print",
        help="Give each other camera its own tag print: ink 0.5-8 % and paper 65-90 % "
        "reflectance (the default); --nominal-print keeps the simulation's print.",
    ),
    measured_response: bool = typer.Option(
        False,
        "--measured-response/--no-measured-response",
        help="Ingest each capture with the response a lab measures of its camera from an "
        "exposure bracket (as ingest --response); default: read with sRGB, as a capture "
        "without one.",
    ),
    stages: str = typer.Option(
        "",
        "--stages",
        help="Comma-separated camera-pipeline stages every other camera has, e.g. black_level "
        "(default: each drawn in some cameras): a validation targeted on a stage.",
    ),
    overwrite: OverwriteOption = False,
) -> None:
    """Blind validation: hidden effects -> pseudo-real captures -> diagnosis -> scores.

    Finished trials are kept in OUTPUT/trials/: a stopped run resumes, and processes with
    disjoint shards share one output folder; a last run without --shard writes the summary of all.
    With --effects the trials are targeted: no trial without a hidden effect or with one
    outside the catalogue.
    """
    from simgap.core.outputs import claimed_folder
    from simgap.core.paths import default_cache_dir
    from simgap.diagnosis.validate import ValidateSettings, run_validation
    from simgap.pipeline.simulator import Simulator

    experiment = one_experiment(experiment, experiment_alias, "--experiment")
    experiment = experiment if experiment is not None else DEFAULT_VALIDATION_EXPERIMENT
    inputs = experiment_inputs(experiment, "EXPERIMENT")
    check_outputs([(OUTPUT, output, VALIDATION_FOLDER)], inputs, overwrite)
    exp = read_experiment(experiment)
    k, _, n = shard.partition("/")
    if not (k.isdigit() and n.isdigit()):
        raise ValueError(f"--shard: expected K/N (two whole numbers, e.g. 0/4), got {shard!r}")
    try:
        settings = ValidateSettings(
            trials=trials,
            seed=seed,
            shard=(int(k), int(n)),
            converged_simulation=converged_simulation,
            camera_pipeline=camera_pipeline,
            print_reflectance=print_reflectance,
            measured_response=measured_response,
            stages=tuple(s.strip() for s in stages.split(",") if s.strip()),
        )
    except ValueError as exc:  # "stages: expected ...": name the option
        raise ValueError(f"--{exc}") from exc
    if effects:
        names = tuple(e.strip() for e in effects.split(",") if e.strip())
        pair = settings.p_pair if len(names) > 1 else 0.0
        try:
            settings = dataclasses.replace(
                settings, effects=names, p_none=0.0, p_outside=0.0, p_pair=pair
            )
        except ValueError as exc:  # "effects: expected ...": name the option
            raise ValueError(f"--{exc}") from exc
    with claimed_folder(output):  # before the first trial: shards and resumes find it marked
        cache_dir = cache or default_cache_dir()
        simulator = Simulator(cache_dir, scheduler, show_progress=progress)
        summary = run_validation(exp, output, cache_dir, settings, typer.echo, simulator)
    _echo_validation(output, summary)


@app.command("report-validation")
def report_validation(
    runs: Annotated[
        list[Path],
        typer.Argument(help="Output folders of simgap validate (their trials/ files), pooled."),
    ],
    output: Annotated[Path, output_option("Folder to write the pooled report to.")] = Path(
        "validation-pooled"
    ),
    overwrite: OverwriteOption = False,
) -> None:
    """Pool finished validation runs (other seeds) into one report, with narrower intervals.

    Reads every RUN/trials/trial_NNN.json and writes OUTPUT/validation.md and validation.json
    of them all. Pool runs of one simgap version, made alike (the same simulation, with or
    without measured responses), on different seeds.
    """
    from simgap.core.outputs import claimed_folder
    from simgap.diagnosis.validation_pool import write_pooled_report

    inputs = [(f"RUN ({run})", run) for run in runs]
    check_outputs([(OUTPUT, output, VALIDATION_FOLDER)], inputs, overwrite)
    with claimed_folder(output):
        summary = write_pooled_report(runs, output)
    _echo_validation(output, summary)


def _echo_validation(output: Path, summary: ValidationSummary) -> None:
    """Print a validation's report, then its headline counts with their intervals."""
    from simgap.diagnosis.validation_report import proportion_text

    typer.echo((output / "validation.md").read_text())
    typer.echo(
        f"top-1 accuracy {proportion_text(summary.top1_accuracy)}, "
        f"no-effect correct {proportion_text(summary.no_effect_correct)}"
    )
