"""The effects catalogue, the assets, and the one-shot study (run + report)."""

from __future__ import annotations

import re
from pathlib import Path

import typer

from simgap.cli.app import app, read_experiment
from simgap.cli.options import (
    CacheOption,
    CalibrationOption,
    OverwriteOption,
    ProgressOption,
    SchedulerOption,
)
from simgap.cli.outputs import (
    OUTPUT,
    REPORT_FOLDER,
    RESULT_DATASET,
    STUDY_FOLDER,
    check_experiment_output,
    check_outputs,
)
from simgap.cli.simulate import report, run


@app.command()
def effects(
    as_json: bool = typer.Option(
        False, "--json", help="Print the catalogue as JSON (name, stage, doc, parameter defaults)."
    ),
) -> None:
    """List the effects catalogue: name, stage, what it models, parameters and defaults."""
    import dataclasses
    import json

    from simgap.effects import EFFECTS

    entries = []
    for name in sorted(EFFECTS, key=lambda n: (EFFECTS[n].stage, n)):
        cls = EFFECTS[name]
        doc = plain_text(" ".join((cls.__doc__ or "").split("\n\n")[0].split()))
        defaults = cls.Params()
        params = {f.name: getattr(defaults, f.name) for f in dataclasses.fields(cls.Params)}
        entries.append({"name": name, "stage": cls.stage, "doc": doc, "params": params})
    if as_json:
        typer.echo(json.dumps(entries, indent=1, default=repr))
        return
    for e in entries:
        params = ", ".join(f"{k}={shown_default(v)}" for k, v in e["params"].items())
        typer.echo(f"{e['name']:20s} [{e['stage']}] {e['doc']}\n{'':21s} {params}")


#: Longest sequence default listed value by value (a response curve's 256 are summarised).
MAX_LISTED_VALUES = 8


def shown_default(value: object) -> str:
    """A parameter default as the listing shows it: its repr, a long sequence summarised."""
    if isinstance(value, tuple) and len(value) > MAX_LISTED_VALUES:
        return f"({len(value)} values, {value[0]!r} ... {value[-1]!r})"
    return repr(value)


#: A Sphinx cross-reference in a docstring (``:class:`~pkg.Name```): shown as its target's name.
SPHINX_ROLE = re.compile(r":\w+:`~?([^`]+)`")


def plain_text(doc: str) -> str:
    """Docstring text for a terminal: Sphinx roles as their names, double backquotes dropped."""
    return SPHINX_ROLE.sub(lambda m: m.group(1), doc).replace("``", "")


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
    cache: CacheOption = None,
    progress: ProgressOption = True,
    scheduler: SchedulerOption = None,
    calibration: CalibrationOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Run an experiment and write its report: OUTPUT/NAME.nc and OUTPUT/NAME-report/."""
    inputs = check_experiment_output(experiment, output, STUDY_FOLDER, overwrite, calibration)
    name = read_experiment(experiment, calibration).name
    nc, folder = output / f"{name}.nc", output / f"{name}-report"
    outputs = [(OUTPUT, nc, RESULT_DATASET), (OUTPUT, folder, REPORT_FOLDER)]
    check_outputs(outputs, inputs, overwrite)
    run(experiment, nc, cache, progress, scheduler, calibration, overwrite)
    report(nc, folder, None, overwrite)
