"""Tests of the command line (simgap.cli) that need no rendering: errors exit with code 2 and say
what is wrong and where; ``report`` writes the paper-style tables for a result dataset."""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from simgap.cli import app
from simgap.core.rig import load_rig
from simgap.pose.image_stats import STAT_NAMES
from simgap.results.dataset import build_dataset, write_netcdf

TAGS = (0, 1)
PS = (0, 7, 14)
THETAS = np.deg2rad([0.0, 30.0, 180.0, 330.0])


@pytest.fixture
def runner():
    return CliRunner()


def small_dataset(seed: int = 0, image_stats: bool = False):
    """A result dataset shaped like `simgap run`'s, with mm-sized random errors.

    With ``image_stats``, random image statistics of every visible configuration too.
    """
    rig = load_rig()
    rng = np.random.default_rng(seed)
    shape = (len(TAGS), len(PS), len(THETAS))
    expected = np.empty(shape + (6,))
    visible = np.empty(shape, bool)
    for (i, tag), (j, p), (k, theta) in itertools.product(
        enumerate(TAGS), enumerate(PS), enumerate(THETAS)
    ):
        expected[i, j, k] = rig.expected_pose(tag, p, theta)
        visible[i, j, k] = rig.is_visible(tag, p, theta)
    full = (1, 1) + shape
    detected = visible[None, None].copy()
    detected[0, 0, 0, 2, 1] = False  # one detection failure
    error = np.concatenate(
        [rng.normal(0, 0.002, full + (3,)), rng.normal(0, 0.02, full + (3,))], axis=-1
    )
    error[~detected] = np.nan
    estimated = expected[None, None] + error
    reproj = np.where(detected, rng.uniform(0.01, 0.3, full), np.nan)
    corners = np.where(detected[..., None, None], rng.uniform(0, 1000, full + (4, 2)), np.nan)
    results = {
        "detected": detected,
        "estimated": estimated,
        "error": error,
        "reproj_px": reproj,
        "corners": corners,
    }
    if image_stats:
        stats = rng.uniform(0.0, 1.0, full + (len(STAT_NAMES),))
        results["image_stats"] = np.where(visible[None, None, ..., None], stats, np.nan)
    return build_dataset(
        TAGS, PS, THETAS, expected, visible, results, attrs={"config": "name: cli-test\n"}
    )


def test_run_bad_experiment_exits_2(runner, tmp_path):
    exp = tmp_path / "bad.yaml"
    exp.write_text("name: bad\nrender: {spp: 0}\n")
    out = tmp_path / "out.nc"
    result = runner.invoke(app, ["run", str(exp), "-o", str(out)])
    assert result.exit_code == 2, result.output
    assert str(exp) in result.output
    assert "render.spp" in result.output
    assert "expected an integer >= 1" in result.output
    assert not out.exists()


def test_run_unknown_key_exits_2(runner, tmp_path):
    exp = tmp_path / "typo.yaml"
    exp.write_text("name: typo\ndetector: {corner_refinment: SUBPIX}\n")
    result = runner.invoke(app, ["run", str(exp), "-o", str(tmp_path / "out.nc")])
    assert result.exit_code == 2, result.output
    assert str(exp) in result.output
    assert "detector.corner_refinment" in result.output


def test_run_missing_experiment_exits_2(runner, tmp_path):
    exp = tmp_path / "absent.yaml"
    result = runner.invoke(app, ["run", str(exp), "-o", str(tmp_path / "out.nc")])
    assert result.exit_code == 2, result.output
    assert str(exp) in result.output
    assert "not found" in result.output


def test_report_missing_file_exits_2(runner, tmp_path):
    nc = tmp_path / "missing.nc"
    result = runner.invoke(app, ["report", str(nc), "-o", str(tmp_path / "rep")])
    assert result.exit_code == 2, result.output
    assert str(nc) in result.output
    assert "not found" in result.output
    assert not (tmp_path / "rep").exists()


def test_report_not_netcdf_exits_2(runner, tmp_path):
    nc = tmp_path / "garbage.nc"
    nc.write_bytes(b"this is not a netCDF file\n")
    result = runner.invoke(app, ["report", str(nc), "-o", str(tmp_path / "rep")])
    assert result.exit_code == 2, result.output
    assert str(nc) in result.output


def test_report_incomplete_dataset_exits_2(runner, tmp_path):
    nc = write_netcdf(small_dataset().drop_vars("detected"), tmp_path / "partial.nc")
    result = runner.invoke(app, ["report", str(nc), "-o", str(tmp_path / "rep")])
    assert result.exit_code == 2, result.output
    assert str(nc) in result.output
    assert "detected" in result.output


def test_report_writes_table2(runner, tmp_path, monkeypatch):
    # Drawing the four PNG figures takes ~5 s on 2 busy cores; tests/test_report.py checks them.
    # Here only the command's wiring matters, so figures are built but saved as placeholders.
    import simgap.analysis.report as report

    def placeholder(fig, path):
        path.write_bytes(b"figure placeholder")
        return path

    monkeypatch.setattr(report, "_save_figure", placeholder)
    nc = write_netcdf(small_dataset(), tmp_path / "result.nc")
    out = tmp_path / "report"
    result = runner.invoke(app, ["report", str(nc), "-o", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    table = out / "table2.md"
    assert table.is_file()
    text = table.read_text()
    # The paper's high-precision thresholds appear beside our numbers.
    assert "0.005" in text and "0.0873" in text, text
    # Tag 0 is visible at 9 of these configurations; the one detection failure is counted.
    assert "8/9" in text, text
    # The command prints the files it wrote, one per line, and they all exist.
    printed = [line for line in result.output.splitlines() if line.strip()]
    assert str(table) in printed
    for line in printed:
        assert Path(line).is_file(), line


def test_report_shows_its_progress_off_a_terminal(runner, tmp_path, monkeypatch):
    """Not on a terminal (CliRunner's pipe), the figures step prints plain lines: start, end."""
    import simgap.analysis.report as report

    monkeypatch.setattr(report, "_save_figure", lambda fig, path: path)
    nc = write_netcdf(small_dataset(), tmp_path / "result.nc")
    result = runner.invoke(app, ["report", str(nc), "-o", str(tmp_path / "report")])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if line.startswith("figures:")]
    assert lines[0].startswith("figures: 0/") and re.match(r"figures: (\d+)/\1 after", lines[-1])


# -- command-line conventions (issue 29): --version, -h, completion, plain help, shared options --

#: Markup that must not reach the terminal: reStructuredText literals and roles, typer's type
#: label against a flag (flags are the only options whose value is never typed).
MARKUP = re.compile(r"``|:(class|func|mod|meth|data|attr|exc|obj):|<bool>")
#: Commands that simulate (they take --cache, --scheduler and --progress/--no-progress).
LONG_COMMANDS = ("run", "study", "diagnose", "validate")


def command_paths() -> list[list[str]]:
    """The app and every command under it, as argument prefixes (``[]`` is the app)."""
    import typer

    paths, todo = [], [([], typer.main.get_command(app))]
    while todo:
        path, command = todo.pop()
        paths.append(path)
        for name, sub in getattr(command, "commands", {}).items():
            todo.append((path + [name], sub))
    return paths


def test_version_prints_the_package_version(runner):
    from importlib.metadata import version

    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0, result.output
    assert result.output == f"simgap {version('simgap')}\n"
    assert re.fullmatch(r"simgap \d+\.\d+\.\d+\n", result.output)


def test_every_command_has_plain_help_under_h_and_help(runner):
    paths = command_paths()
    assert len(paths) == 16  # the app and its 15 commands (see simgap.cli)
    for path in paths:
        short = runner.invoke(app, path + ["-h"], prog_name="simgap")
        assert short.exit_code == 0, (path, short.output)
        assert runner.invoke(app, path + ["--help"], prog_name="simgap").output == short.output
        text = short.output
        usage = next(line for line in text.splitlines() if "Usage:" in line)
        assert usage.split()[: 2 + len(path)] == ["Usage:", "simgap", *path], usage
        assert "{" not in usage and "}" not in usage, usage
        assert not MARKUP.search(text), (path, MARKUP.search(text)[0], text)
    # the arguments in capitals, optional ones in brackets
    usage = runner.invoke(app, ["study", "-h"], prog_name="simgap").output
    assert "Usage: simgap study [OPTIONS] [EXPERIMENT]" in usage
    usage = runner.invoke(app, ["run", "-h"], prog_name="simgap").output
    assert "Usage: simgap run [OPTIONS] EXPERIMENT" in usage


def test_plain_help_drops_sections_and_markup():
    from simgap.cli.app import plain_help

    doc = """Fit a model (:class:`~simgap.x.Model`), written as ``model.nc``.

        A second paragraph
        over two lines.

        Parameters
        ----------
        x : int
            Not help.
        """
    expected = (
        "Fit a model (simgap.x.Model), written as model.nc.\n\nA second paragraph over two lines."
    )
    assert plain_help(doc) == expected


def test_show_completion_prints_the_bash_script(runner, monkeypatch):
    # typer reads the shell from the option instead of detecting the login shell (which a test
    # runner may not have); the command is built per invocation, after this is set
    monkeypatch.setenv("_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION", "1")
    result = runner.invoke(app, ["--show-completion", "bash"], prog_name="simgap")
    assert result.exit_code == 0, result.output
    assert "complete -o default -F _simgap_completion simgap" in result.output
    assert "_SIMGAP_COMPLETE=complete_bash" in result.output


def test_completion_completes_commands_and_choices(runner):
    def complete(words: str) -> list[str]:
        env = {
            "_SIMGAP_COMPLETE": "complete_bash",
            "COMP_WORDS": words,
            "COMP_CWORD": str(len(words.split()) - (not words.endswith(" "))),
        }
        result = runner.invoke(app, [], env=env, prog_name="simgap")
        assert result.exit_code == 0, result.output
        return result.output.split()

    assert complete("simgap dia") == ["diagnose"]
    assert complete("simgap export-bag --format ") == ["ros1", "ros2"]


def test_long_commands_share_one_definition_of_cache_scheduler_progress():
    import typer

    from simgap.cli.options import CACHE_HELP, PROGRESS_HELP, SCHEDULER_HELP

    commands = typer.main.get_command(app).commands
    for name in LONG_COMMANDS:
        options = {tuple(p.opts + p.secondary_opts): p.help for p in commands[name].params}
        assert options[("--cache",)] == CACHE_HELP, name
        assert options[("--scheduler",)] == SCHEDULER_HELP, name
        assert options[("--progress", "--no-progress")] == PROGRESS_HELP, name


def test_bad_bag_format_names_the_allowed_values(runner, tmp_path):
    from simgap.cli.options import BagFormat, BagStorage
    from simgap.pipeline.bag.formats import BAG_FORMATS, BAG_STORAGES

    assert tuple(f.value for f in BagFormat) == BAG_FORMATS  # the choice is the writer's
    assert tuple(s.value for s in BagStorage) == BAG_STORAGES
    out = tmp_path / "x.bag"
    args = ["export-bag", str(tmp_path), "-o", str(out), "--format", "ros3"]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    (error,) = [line for line in result.output.splitlines() if line.startswith("Error:")]
    assert "'--format'" in error and "'ros3' is not one of 'ros1', 'ros2'" in error, error
    assert "Traceback" not in result.output and not out.exists()


def test_step_bars_draw_each_step_as_bars_or_plain_lines():
    import io

    from rich.console import Console

    from simgap.cli.progress import StepBars

    def draw(show: bool, terminal: bool) -> str:
        file = io.StringIO()
        console = Console(file=file, force_terminal=terminal, width=100, color_system=None)
        with StepBars(show, console) as bars:
            bars("fitting candidates", 0, 3)
            bars("fitting candidates", 3, 3)
            bars("model search", 0, None)
            bars("model search", 7, None)
        return file.getvalue()

    shown = draw(True, terminal=True)
    assert "fitting candidates" in shown and "3/3" in shown
    # a search of unknown length is marked done with its count when the display stops
    assert "model search" in shown and "7/7" in shown
    assert draw(False, terminal=True) == draw(False, terminal=False) == ""  # --no-progress
    # a pipe, a log file, a notebook cell: plain lines at each step's start and end (and every
    # PLAIN_INTERVAL_S between; issue 53: the fitting had printed nothing off a terminal)
    assert draw(True, terminal=False).splitlines() == [
        "fitting candidates: 0/3 after 0 s",
        "fitting candidates: 3/3 after 0 s",
        "model search: 0 after 0 s",
        "model search: 7 after 0 s",
    ]


class Stop(ValueError):
    """Raised by a stand-in for the work of a command once its arguments are recorded."""


def test_long_commands_pass_progress_and_scheduler_down(runner, tmp_path, monkeypatch):
    """--no-progress and --scheduler reach the simulation of study, diagnose and validate, and
    diagnose's step bars (quiet here: --no-progress, and no terminal either way)."""
    import simgap.diagnosis.diagnose as diagnosis
    import simgap.diagnosis.validate as validation
    import simgap.pipeline.sweep as sweep

    seen = {}

    def record(name):
        def stand_in(*args, **kwargs):
            seen[name] = (args, kwargs)
            raise Stop("stopped")

        return stand_in

    monkeypatch.setattr(sweep, "run_experiment", record("study"))
    monkeypatch.setattr(diagnosis, "diagnose", record("diagnose"))
    monkeypatch.setattr(validation, "run_validation", record("validate"))
    real = write_netcdf(small_dataset(), tmp_path / "real.nc")
    address = "tcp://127.0.0.1:8786"
    common = ["--no-progress", "--scheduler", address, "--cache", str(tmp_path / "cache")]
    commands = {
        "study": ["study", "experiments/smoke.yaml", "-o", str(tmp_path / "s")],
        "diagnose": ["diagnose", str(real), "--sim", "experiments/smoke.yaml"]
        + ["-o", str(tmp_path / "d")],
        "validate": [
            "validate",
            "--experiment",
            "experiments/smoke.yaml",
            "-o",
            str(tmp_path / "v"),
        ],
    }
    for name, args in commands.items():
        result = runner.invoke(app, args + common)
        assert result.exit_code == 2, (name, result.output)
        assert result.output.count("error:") == 1 and "stopped" in result.output, result.output
    args, kwargs = seen["study"]
    assert args[2:] == (False, address)  # run_experiment(exp, cache, show_progress, scheduler)
    args, kwargs = seen["diagnose"]
    simulator = args[2]
    assert (simulator.scheduler, simulator.show_progress) == (address, False)
    assert not kwargs["progress"].show
    args, kwargs = seen["validate"]
    simulator = args[5]
    assert (simulator.scheduler, simulator.show_progress) == (address, False)


def test_run_with_a_bad_calibration_file_exits_2(runner, tmp_path):
    """``--calibration`` reads the file as the camera; a wrong one is named with its key."""
    cal = tmp_path / "ost.yaml"
    cal.write_text(
        "image_width: 1920\nimage_height: 1080\ncamera_matrix: {rows: 3, cols: 3, data: "
        "[1386, 0, 959.5, 0, 1386, 539.5, 0, 0, 1]}\ndistortion_model: rational_polynomial\n"
        "distortion_coefficients: {rows: 1, cols: 9, data: [0, 0, 0, 0, 0, 0, 0, 0, 0.1]}\n"
    )
    out = tmp_path / "out.nc"
    result = runner.invoke(
        app, ["run", "experiments/smoke.yaml", "--calibration", str(cal), "-o", str(out)]
    )
    assert result.exit_code == 2, result.output
    assert f"{cal}: distortion_coefficients.data: expected the 8 coefficients" in result.output
    assert not out.exists()


def test_an_output_named_for_another_format_is_refused(runner, tmp_path):
    """``errormodel -o m.txt`` had written netCDF (HDF5) under a .txt name (issue 53)."""
    res = runner.invoke(app, ["errormodel", "absent.nc", "-o", str(tmp_path / "m.txt")])
    assert res.exit_code == 2
    assert "expected a name ending in .nc or .json (the error model (netCDF or JSON)" in res.output
    res = runner.invoke(app, ["run", "experiments/smoke.yaml", "-o", str(tmp_path / "r.h5")])
    assert res.exit_code == 2 and "expected a name ending in .nc" in res.output
    assert not list(tmp_path.iterdir())


def test_effects_are_listed_in_plain_text_and_a_negative_seed_is_refused(runner):
    """No Sphinx roles or double backquotes on the terminal; ``diagnose --seed -1`` fails at
    once, naming the option (issue 53)."""
    out = runner.invoke(app, ["effects"]).output
    assert ":class:" not in out and "``" not in out and ":mod:" not in out
    assert "see simgap.pose.detect.DetectorSettings" in out
    res = runner.invoke(app, ["diagnose", "absent.nc", "--seed", "-1", "-o", "d"])
    assert res.exit_code == 2 and "--seed" in res.output


def test_effects_as_json_for_programs(runner):
    """``simgap effects --json``: every catalogue effect with its stage and parameter defaults."""
    import json

    from simgap.effects import EFFECTS

    res = runner.invoke(app, ["effects", "--json"])
    assert res.exit_code == 0, res.output
    entries = {e["name"]: e for e in json.loads(res.output)}
    assert set(entries) == set(EFFECTS)
    assert entries["blur"]["stage"] == "image" and entries["blur"]["params"] == {"sigma_px": 0.7}
    assert entries["sun"]["params"]["irradiance_w_m2"] == pytest.approx(1361.0)


def test_unexplained_evidence_is_named_for_a_reader():
    """The one-line summary names image statistics by their readable names and units, not their
    code names (issue 53)."""
    from simgap.cli.diagnose import evidence_name

    assert evidence_name("paper_linear") == "paper level, linear [fraction of full scale]"
    assert evidence_name("black_clipped_fraction") == (
        "black-clipped pixels (0 DN) [fraction of sticker pixels]"
    )
    assert evidence_name("pose") == "pose"


def test_plain_progress_lines_come_every_interval_with_an_estimate(monkeypatch):
    import io

    from rich.console import Console

    import simgap.cli.progress as progress

    clock = iter([0.0, 40.0, 50.0, 100.0])  # start, 40 s (a line), 50 s (none), 100 s (done)
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    file = io.StringIO()
    console = Console(file=file, force_terminal=False, width=100, color_system=None)
    with progress.StepBars(True, console) as bars:
        for done in (0, 2, 3, 5):
            bars("fitting candidates", done, 5)
    assert file.getvalue().splitlines() == [
        "fitting candidates: 0/5 after 0 s",
        "fitting candidates: 2/5 after 40 s, about 60 s left",
        "fitting candidates: 5/5 after 100 s",
    ]


#: The option vocabulary (issue 53): one spelling per concept, on every command it applies to.
#: Commands that write: -o/--output and --overwrite. Commands that render, fit or read many
#: frames: --progress/--no-progress. Commands that simulate or ingest: --calibration. Commands
#: that take an experiment: the positional EXPERIMENT (export-bag: SOURCE, which may also be a
#: capture folder), older option spellings kept hidden.
WRITES = {"run", "report", "compare", "study", "ingest", "calibrate", "export-bag", "errormodel",
          "diagnose", "report-diagnosis", "validate", "report-validation"}  # fmt: skip
PROGRESS = {
    "run",
    "report",
    "compare",
    "study",
    "ingest",
    "calibrate",
    "export-bag",
    "diagnose",
    "validate",
}
CALIBRATION = {"run", "study", "ingest", "calibrate", "export-bag", "diagnose"}
EXPERIMENT = {"run", "study", "ingest", "diagnose", "validate"}
#: Spellings that would say the same as the vocabulary's (none may appear, visible or hidden).
FORBIDDEN = {"--out", "--output-dir", "--outdir", "--force", "--clobber", "--calib", "--camera",
             "--quiet", "--verbose-progress", "--no-overwrite"}  # fmt: skip


def _options(command) -> dict[str, object]:
    """Every option spelling of a click command -> its parameter (visible or hidden)."""
    out = {}
    for param in command.params:
        for name in (*param.opts, *getattr(param, "secondary_opts", ())):
            if name.startswith("-"):
                out[name] = param
    return out


def test_option_vocabulary_holds_on_every_command():
    import typer

    commands = typer.main.get_command(app).commands
    for name, command in commands.items():
        opts = _options(command)
        visible = {o for o, p in opts.items() if not getattr(p, "hidden", False)}
        assert not FORBIDDEN & set(opts), (name, FORBIDDEN & set(opts))
        if name in WRITES:
            assert {"-o", "--output", "--overwrite"} <= visible, name
        if name in PROGRESS:
            assert {"--progress", "--no-progress"} <= visible, name
        if name in CALIBRATION:
            assert "--calibration" in visible, name
        if name in EXPERIMENT:
            args = [p.name for p in command.params if p.param_type_name == "argument"]
            assert "experiment" in args, (name, args)
            assert not {"--sim", "--experiment"} & visible, name  # the old spellings: hidden
        if "--seed" in opts:
            assert opts["--seed"].min == 0, name


def test_old_experiment_spellings_still_work_and_agree(runner, tmp_path):
    """``--sim`` and ``--experiment`` are aliases of EXPERIMENT; two different ones are refused."""
    real = write_netcdf(small_dataset(), tmp_path / "real.nc")
    both = ["diagnose", str(real), "experiments/smoke.yaml", "--sim", "experiments/baseline.yaml"]
    res = runner.invoke(app, [*both, "-o", str(tmp_path / "d")])
    assert res.exit_code == 2 and "name two experiments" in res.output, res.output
    res = runner.invoke(app, ["diagnose", str(real), "-o", str(tmp_path / "d")])
    assert res.exit_code == 2 and "EXPERIMENT" in res.output, res.output


def test_diagnose_checks_its_seed_before_any_work(runner, tmp_path):
    """``--seed -1`` is refused by the parser, naming --seed, before the dataset is read."""
    cache = tmp_path / "cache"
    args = ["diagnose", str(tmp_path / "missing.nc"), "experiments/smoke.yaml", "--seed", "-1"]
    res = runner.invoke(app, [*args, "-o", str(tmp_path / "d"), "--cache", str(cache)])
    assert res.exit_code == 2 and "--seed" in res.output, res.output
    assert "missing.nc" not in res.output and not cache.exists()
