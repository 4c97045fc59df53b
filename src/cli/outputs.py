"""What each command writes, checked before it works (:mod:`simgap.core.outputs`).

Every command that writes calls :func:`check_outputs` first with its output paths, what it
writes at each (an :class:`~simgap.core.outputs.OutputKind` of this module) and its inputs.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from simgap.cli.options import FOLDER_SPELLED
from simgap.core.config import ConfigError
from simgap.core.outputs import OutputKind, OutputPathError, check_output
from simgap.core.paths import CALIBRATION_FILE, IMAGES_DIR, MANIFEST_FILE

#: The ``-o/--output`` option in messages.
OUTPUT = "-o/--output"
#: A command's input: the argument or option that names it, and its path (None: not given).
Input = tuple[str, Path | None]
#: The largest JSON file read to recognise an earlier output (bytes); simgap's are far smaller.
MAX_JSON_BYTES = 64 * 2**20
#: Keys every diagnosis ``result.json`` has (docs/diagnosis.md, result.json).
DIAGNOSIS_KEYS = frozenset({"where", "ranking", "selected", "unexplained"})


def _json_object(path: Path) -> dict:
    """The JSON object in ``path``, or ``{}`` when it is not one (or too large to be simgap's)."""
    if path.stat().st_size > MAX_JSON_BYTES:
        return {}
    try:
        data = json.loads(path.read_bytes())
    except (ValueError, OSError):
        return {}
    return data if isinstance(data, dict) else {}


#: The ``source`` attr of a result dataset ingested from a real capture or bag.
INGESTED_SOURCES = frozenset({"capture", "bag"})


def _dataset_source(path: Path) -> str | None:
    """The ``source`` attr of a result dataset simgap wrote, or None for any other file.

    ``""`` for a simulated dataset (it has none).
    """
    from simgap.results.provenance import result_dataset_attrs

    attrs = result_dataset_attrs(path)
    return None if attrs is None else str(attrs.get("source", ""))


def _is_simulated_dataset(path: Path) -> bool:
    """A simulated result dataset simgap wrote (not one ingested from a capture or bag)."""
    source = _dataset_source(path)
    return source is not None and source not in INGESTED_SOURCES


def _is_ingested_dataset(path: Path) -> bool:
    """A result dataset simgap ingested from a capture or a bag."""
    return _dataset_source(path) in INGESTED_SOURCES


def _is_error_model(path: Path) -> bool:
    """An error model simgap wrote: netCDF or JSON with the model schema."""
    from simgap.analysis.errormodel import SCHEMA
    from simgap.results.provenance import netcdf_header

    header = netcdf_header(path)
    schema = header[0].get("schema") if header is not None else _json_object(path).get("schema")
    return schema == SCHEMA


def _is_photo_dataset(path: Path) -> bool:
    """A photo dataset simgap measured (``ingest --board``)."""
    from simgap.pipeline.photos import PHOTO_SOURCE
    from simgap.results.provenance import netcdf_header

    header = netcdf_header(path)
    return header is not None and header[0].get("source") == PHOTO_SOURCE


def _is_diagnosis_json(path: Path) -> bool:
    """A diagnosis ``result.json`` (its top-level keys)."""
    return DIAGNOSIS_KEYS <= _json_object(path).keys()


def _is_exported_bag(path: Path) -> bool:
    """A ROS 1 or ROS 2 bag simgap exported."""
    from simgap.pipeline.bag import is_exported_bag

    return is_exported_bag(path)


def _is_ros2_bag_or_empty(folder: Path) -> bool:
    """A ROS 2 bag simgap exported, or an empty folder (either may be replaced whole)."""
    return next(folder.iterdir(), None) is None or _is_exported_bag(folder)


def _any_folder(folder: Path) -> bool:
    """Any folder: ``study`` writes two named entries into it, each checked on its own."""
    return True


#: What ``run`` and ``study`` write; an ingested dataset is another kind (its replacement by a
#: simulation needs ``--overwrite``).
RESULT_DATASET = OutputKind(
    "simulated result dataset (netCDF)", is_ours=_is_simulated_dataset, suffixes=(".nc",)
)
#: What ``ingest`` writes.
INGESTED_DATASET = OutputKind(
    "ingested result dataset (netCDF)", is_ours=_is_ingested_dataset, suffixes=(".nc",)
)
#: First line of a calibration file ``calibrate`` writes (how it knows one of its own).
CALIBRATION_HEADER = "# simgap calibrate:"
#: First line of a response file ``camera-response`` writes (how it knows one of its own).
RESPONSE_HEADER = "# simgap camera-response:"


def _first_line_is(header: str) -> Callable[[Path], bool]:
    """Whether a file is one a simgap command wrote: its first line starts with ``header``."""

    def is_ours(path: Path) -> bool:
        try:
            with path.open("rb") as f:
                return f.readline().startswith(header.encode())
        except OSError:
            return False

    return is_ours


#: What ``calibrate`` writes.
CALIBRATION_OUTPUT = OutputKind(
    "calibration file (ROS camera_info YAML)",
    is_ours=_first_line_is(CALIBRATION_HEADER),
    suffixes=(".yaml", ".yml"),
)
#: What ``camera-response`` writes.
RESPONSE_OUTPUT = OutputKind(
    "camera response file (YAML)",
    is_ours=_first_line_is(RESPONSE_HEADER),
    suffixes=(".yaml", ".yml"),
)
#: What ``ingest --board`` writes.
PHOTO_DATASET = OutputKind(
    "board photo dataset (netCDF)", is_ours=_is_photo_dataset, suffixes=(".nc",)
)
ERROR_MODEL = OutputKind(
    "error model (netCDF or JSON)", is_ours=_is_error_model, suffixes=(".nc", ".json")
)
DIAGNOSIS_JSON = OutputKind(
    "diagnosis result (JSON)", is_ours=_is_diagnosis_json, suffixes=(".json",)
)
REPORT_FOLDER = OutputKind("report folder", folder=True)
COMPARISON_FOLDER = OutputKind("comparison folder", folder=True)
DIAGNOSIS_FOLDER = OutputKind("diagnosis folder", folder=True)
VALIDATION_FOLDER = OutputKind("validation folder", folder=True)
CAPTURE_FOLDER = OutputKind(
    "capture folder", folder=True, names=(CALIBRATION_FILE, MANIFEST_FILE, IMAGES_DIR)
)
ROS1_BAG = OutputKind("ROS 1 bag", is_ours=_is_exported_bag)
ROS2_BAG_FILE = OutputKind("ROS 2 bag file (.mcap or .db3)", is_ours=_is_exported_bag)
ROS2_BAG = OutputKind(
    "ROS 2 bag folder", folder=True, is_ours=_is_ros2_bag_or_empty, replaced_whole=True
)
STUDY_FOLDER = OutputKind("study folder", folder=True, is_ours=_any_folder)


def experiment_inputs(path: Path, label: str) -> list[Input]:
    """An experiment file, the files it inherits from and the calibration files they name."""
    from simgap.pipeline.experiment_files import calibration_files, read_chain

    try:
        chain = read_chain(Path(path))
    except (ConfigError, OSError):  # the command's own loading names the problem
        return [(label, path)]
    inherited = [(f"{label} (inherited)", p) for p, _ in chain[:-1]]
    return (
        [(label, path)]
        + inherited
        + [(f"{label} (rig.camera.calibration)", p) for p in calibration_files(chain)]
    )


def check_experiment_output(
    experiment: Path,
    output: Path,
    kind: OutputKind,
    overwrite: bool,
    calibration: Path | None = None,
) -> list[Input]:
    """Check the ``-o/--output`` of a command that runs the experiment YAML ``EXPERIMENT``.

    Returns the command's inputs (the experiment, the files it inherits from and the
    calibration files, ``--calibration`` among them), against which it checks any further
    outputs.

    Raises
    ------
    simgap.core.outputs.OutputPathError
        As :func:`check_outputs`.
    """
    inputs = experiment_inputs(experiment, "EXPERIMENT")
    inputs += [("--calibration", calibration)] if calibration is not None else []
    check_outputs([(OUTPUT, output, kind)], inputs, overwrite)
    return inputs


def simulation_inputs(path: Path, label: str) -> list[Input]:
    """The inputs of an experiment YAML or result dataset given as the simulation."""
    if Path(path).suffix in (".yaml", ".yml"):
        return experiment_inputs(path, label)
    return [(label, path)]


def check_outputs(
    outputs: Iterable[tuple[str, Path | None, OutputKind]],
    inputs: Sequence[Input],
    overwrite: bool,
) -> None:
    """Check a command's outputs ``(option, path, kind)`` before it works (None: not given).

    Raises
    ------
    simgap.core.outputs.OutputPathError
        As :func:`simgap.core.outputs.check_output`, when two outputs are one path, or when a
        file's path was given with a trailing ``/`` (a folder's).
    """
    from simgap.pipeline.capture.calibration import calibration_source

    # a calibration named FILE:camN (one camera of a Kalibr camchain) is the input FILE
    inputs = [(label, None if p is None else calibration_source(p)[0]) for label, p in inputs]
    seen: dict[Path, str] = {}
    for option, path, kind in outputs:
        if path is None:
            continue
        if not kind.folder and Path(path) in FOLDER_SPELLED:
            raise OutputPathError(
                f"{option} {path}/: a trailing / names a folder, and the {kind.what} is a file; "
                "give the file's name"
            )
        check_output(path, option, kind, inputs, overwrite)
        real = Path(path).resolve()
        if real in seen:
            raise OutputPathError(
                f"{option} {path}: also given as {seen[real]}; expected another path"
            )
        seen[real] = option
