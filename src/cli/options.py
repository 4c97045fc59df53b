"""Options several commands share, each declared once (typer's ``Annotated`` form).

Defaults stay in the command signatures. Every long command (one that simulates: ``run``,
``study``, ``diagnose``, ``validate``) takes :data:`CacheOption`, :data:`SchedulerOption` and
:data:`ProgressOption`; a fixed set of values is an :class:`enum.Enum` (typer's choice: a wrong
value exits with code 2 and a line naming the option and the allowed values).
"""

from __future__ import annotations

import enum
from pathlib import Path
from typing import Annotated, Any

import typer

CACHE_HELP = "Cache folder for renders and results (default: $SIMGAP_CACHE or ~/.cache/simgap)."
SCHEDULER_HELP = (
    "Dask scheduler address (tcp://HOST:PORT); default: a LocalCluster on this machine. "
    "Workers must see the cache folder under the same path."
)
PROGRESS_HELP = "Show progress bars (on a terminal) while the command works."
OVERWRITE_HELP = (
    "Replace an existing file, or write into a folder, that simgap did not write (never an "
    "input, a device or a folder where a file goes)."
)

#: ``--cache FOLDER`` (default ``None``: $SIMGAP_CACHE or ~/.cache/simgap).
CacheOption = Annotated[Path | None, typer.Option("--cache", help=CACHE_HELP)]
#: ``--scheduler ADDRESS`` (default ``None``: an in-process cluster).
SchedulerOption = Annotated[str | None, typer.Option("--scheduler", help=SCHEDULER_HELP)]
#: ``--progress/--no-progress`` (default ``True``).
ProgressOption = Annotated[bool, typer.Option("--progress/--no-progress", help=PROGRESS_HELP)]
#: ``--variant NAME`` of a result dataset (default ``None``: the first).
VariantOption = Annotated[
    str | None, typer.Option("--variant", help="Variant of the dataset (default: the first).")
]
CALIBRATION_HELP = (
    "Camera calibration file (ROS camera_info YAML, OpenCV FileStorage or Kalibr camchain, "
    "FILE:cam1 for its cam1; plumb_bob, rational_polynomial, thin prism, tilted or "
    "equidistant/fisheye): the simulated camera."
)
#: ``--calibration FILE`` (default ``None``: the experiment's camera).
CalibrationOption = Annotated[Path | None, typer.Option("--calibration", help=CALIBRATION_HELP)]
#: ``--poses CSV``: each board photo's reference pose from outside the photos.
PosesOption = Annotated[
    Path | None,
    typer.Option(
        "--poses",
        help="With --board: CSV image,tx,ty,tz,qx,qy,qz,qw giving each photo's reference "
        "camera_from_board (the board in the OpenCV camera frame; m, quaternion x y z w) "
        "instead of the board's pose from its points.",
    ),
]
#: ``--robot-poses CSV``: the robot flange's pose per board photo (with ``--hand-eye``).
RobotPosesOption = Annotated[
    Path | None,
    typer.Option(
        "--robot-poses",
        help="With --board and --hand-eye: CSV image,tx,ty,tz,qx,qy,qz,qw of base_from_flange "
        "(the robot flange in its base frame) per photo; the reference is the robot's chain.",
    ),
]
#: ``--hand-eye FILE``: the camera in the robot flange's frame.
HandEyeOption = Annotated[
    Path | None,
    typer.Option(
        "--hand-eye",
        help="With --robot-poses: YAML flange_from_camera (the OpenCV camera frame in the "
        "flange's): translation [x, y, z] (m) and quaternion [qx, qy, qz, qw], or a 4x4 matrix.",
    ),
]
#: ``--board-in-base FILE``: the board in the robot base frame.
BoardInBaseOption = Annotated[
    Path | None,
    typer.Option(
        "--board-in-base",
        help="With --robot-poses: YAML base_from_board, as --hand-eye; default: solved from the "
        "photos' board poses (per-axis median and rotation mean).",
    ),
]
#: Help of the positional ``EXPERIMENT`` of every command that simulates (its older option
#: spelling is kept as a hidden alias: :func:`one_experiment`).
EXPERIMENT_HELP = "Experiment YAML (or a result .nc it was run from, where a command takes one)."


def one_experiment(positional: Path | None, alias: Path | None, alias_name: str) -> Path | None:
    """The experiment named as the positional ``EXPERIMENT`` or by its older option spelling.

    Raises
    ------
    simgap.core.config.ConfigError
        Where both are given and differ.
    """
    from simgap.core.config import ConfigError

    if positional is not None and alias is not None and Path(positional) != Path(alias):
        raise ConfigError(
            f"EXPERIMENT: {positional} and {alias_name} {alias} name two experiments; give one "
            f"(EXPERIMENT; {alias_name} is its older spelling)"
        )
    return positional if positional is not None else alias


#: ``--overwrite`` (default ``False``).
OverwriteOption = Annotated[bool, typer.Option("--overwrite", help=OVERWRITE_HELP)]


#: Output paths given with a trailing ``/`` this run: they name a folder, whatever follows
#: (``pathlib`` drops the slash, so the parser records it; :func:`output_path`).
FOLDER_SPELLED: set[Path] = set()


def output_path(text: str) -> Path:
    """An ``-o`` value as a path, remembering a trailing ``/`` (:data:`FOLDER_SPELLED`)."""
    path = Path(text)
    if text.endswith("/") and text.strip("/"):
        FOLDER_SPELLED.add(path)
    return path


def output_option(help_text: str) -> Any:
    """The ``-o/--output PATH`` option, with what the command writes there as its help."""
    return typer.Option("-o", "--output", help=help_text, parser=output_path)


class BagFormat(str, enum.Enum):
    """``export-bag --format``: the bag formats of :data:`simgap.pipeline.bag.BAG_FORMATS`."""

    ros1 = "ros1"
    ros2 = "ros2"


class ImageEncoding(str, enum.Enum):
    """``export-bag --images``: ``simgap.pipeline.bag.formats.IMAGE_ENCODINGS``."""

    raw = "raw"
    png = "png"
    jpeg = "jpeg"


class BagStorage(str, enum.Enum):
    """``export-bag --storage``: the ROS 2 storages of ``bag.formats.BAG_STORAGES``."""

    sqlite3 = "sqlite3"
    mcap = "mcap"
