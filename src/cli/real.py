"""Commands on real data: ingest, calibrate, measure the camera's response, export a bag."""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from simgap.cli.app import app, fail, read_experiment, read_result_dataset, read_simulation
from simgap.cli.options import (
    BagFormat,
    BagStorage,
    BoardInBaseOption,
    CacheOption,
    CalibrationOption,
    HandEyeOption,
    ImageEncoding,
    OverwriteOption,
    PosesOption,
    ProgressOption,
    RobotPosesOption,
    VariantOption,
    one_experiment,
    output_option,
)
from simgap.cli.outputs import (
    CALIBRATION_HEADER,
    CALIBRATION_OUTPUT,
    CAPTURE_FOLDER,
    INGESTED_DATASET,
    OUTPUT,
    PHOTO_DATASET,
    RESPONSE_HEADER,
    RESPONSE_OUTPUT,
    ROS1_BAG,
    ROS2_BAG,
    ROS2_BAG_FILE,
    check_outputs,
    experiment_inputs,
    simulation_inputs,
)
from simgap.core.limits import MAX_PIXELS, PHOTO_SPP

if TYPE_CHECKING:
    from collections.abc import Sequence

    import numpy as np

    from simgap.core.board import Board
    from simgap.core.rig import CameraModel
    from simgap.pipeline.photo_references import PhotoReference, ResolvedReference
    from simgap.pose.calibration_check import FileCheck, ReferencePoses


@app.command()
def ingest(
    capture: Annotated[
        Path,
        typer.Argument(
            help="Capture folder (camera.yaml, manifest.csv, images), ROS 1 .bag or ROS 2 bag; "
            "with --board, a folder of photos of that board."
        ),
    ],
    output: Annotated[Path, output_option("Result dataset to write (netCDF).")],
    experiment: Annotated[
        Path | None,
        typer.Argument(
            help="Experiment YAML to take the rig, detector and PnP settings from (also "
            "--experiment)."
        ),
    ] = None,
    experiment_alias: Annotated[Path | None, typer.Option("--experiment", hidden=True)] = None,
    progress: ProgressOption = True,
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
    calibration: Path | None = typer.Option(
        None,
        "--calibration",
        help="Calibration file under any name (ROS ost.yaml / camera_info YAML, OpenCV YAML or "
        "Kalibr camchain, FILE:cam1 for its cam1); wins over camera.yaml and a bag's CameraInfo.",
    ),
    max_pixels: int = typer.Option(
        MAX_PIXELS,
        "--max-pixels",
        help="Pixel budget: frames larger than this (px, width x height) are refused before "
        "any decode, whatever the calibration states (covers real cameras up to 50 MP).",
        min=1,
    ),
    response: Path | None = typer.Option(
        None,
        "--response",
        help="The camera's measured response (simgap camera-response): its frames' levels are "
        "read through it, and the diagnosis simulates through it instead of sRGB.",
    ),
    simulate: bool = typer.Option(
        False,
        "--simulate",
        help="With --board: render each photo at its reference pose, fit the camera's exposure "
        "and blur on the markers' image statistics, and print the gap before and after "
        "(cross-fitted: each photo with the camera fitted on the other half); the dataset "
        "gains an image dimension (real, simulated, simulated_fitted).",
    ),
    spp: int = typer.Option(
        PHOTO_SPP, "--spp", help="With --simulate: samples per pixel of the renders.", min=1
    ),
    seed: int = typer.Option(0, "--seed", help="With --simulate: the renders' seed.", min=0),
    board: Path | None = typer.Option(
        None,
        "--board",
        help="Board file (YAML: kind charuco or grid, columns, rows, marker_m, square_m or "
        "separation_m, dictionary): CAPTURE is then a folder of photos of it, each marker's "
        "pose measured against the board's own, or --poses / --robot-poses (needs "
        "--calibration).",
    ),
    poses: PosesOption = None,
    robot_poses: RobotPosesOption = None,
    hand_eye: HandEyeOption = None,
    board_in_base: BoardInBaseOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Detect markers and estimate poses in a real capture or ROS bag; write its result dataset.

    With --board, a folder of photos of a board of markers: each marker's single-marker pose
    error against the board's pose from all its points, or against the poses of --poses or
    --robot-poses with --hand-eye, printed near / mid / far.
    """
    experiment = one_experiment(experiment, experiment_alias, "--experiment")
    reference = _ReferenceFiles(poses, robot_poses, hand_eye, board_in_base)
    if board is not None and response is not None:
        fail("--response: not with --board (a board's photos are measured in DN)")
    if board is not None:
        photo_options = _PhotoOptions(
            calibration, experiment, max_pixels, simulate, spp, seed, reference
        )
        _ingest_photos(capture, output, board, photo_options, progress, overwrite)
        return
    if simulate:
        fail("--simulate: only with --board (a folder of board photos)")
    if reference.given:
        fail(f"{reference.given[0][0]}: only with --board (a folder of board photos)")
    from simgap.core.outputs import claimed_folder
    from simgap.pipeline.bag import ingest_bag, is_bag
    from simgap.pipeline.capture import ingest as ingest_capture
    from simgap.pipeline.capture.response_file import read_response
    from simgap.results.dataset import write_netcdf

    bag = is_bag(capture)
    inputs = [("CAPTURE", capture), ("--ranges", ranges), ("--calibration", calibration)]
    inputs += [("--response", response)]
    inputs += experiment_inputs(experiment, "EXPERIMENT") if experiment is not None else []
    outputs = [(OUTPUT, output, INGESTED_DATASET)]
    outputs += [("--keep-capture", keep_capture, CAPTURE_FOLDER)] if bag else []
    check_outputs(outputs, inputs, overwrite)
    kwargs: dict = {"calibration_file": calibration, "max_pixels": max_pixels}
    if response is not None:
        kwargs["response"] = read_response(response)
    if experiment is not None:
        exp = read_experiment(experiment)
        kwargs |= {"rig": exp.rig_model, "detector": exp.detector, "pnp": exp.pnp}
    if bag:
        bag_options = {
            "ranges_csv": ranges,
            "image_topic": image_topic,
            "camera_info_topic": camera_info_topic,
            "fixture_topic": fixture_topic,
            "keep_capture": keep_capture,
        }
        with claimed_folder(keep_capture) if keep_capture is not None else nullcontext():
            ds = ingest_bag(capture, show_progress=progress, **bag_options, **kwargs)
    else:
        ds = ingest_capture(capture, show_progress=progress, **kwargs)
    write_netcdf(ds, output)
    vis = ds.visible.values
    det = ds.detected.values[0].any(axis=0)
    typer.echo(
        f"wrote {output}: {ds.attrs['frames']} frame(s), {ds.attrs['frames_unreadable']} "
        f"unreadable; {vis.sum()} visible items (tag x configuration), {(det & vis).sum()} detected"
    )


@dataclass(frozen=True)
class _ReferenceFiles:
    """The reference options of ``ingest --board`` (see :func:`ingest`)."""

    poses: Path | None
    robot_poses: Path | None
    hand_eye: Path | None
    board_in_base: Path | None

    @property
    def given(self) -> list[tuple[str, Path]]:
        """The options given, with their paths (the command's inputs)."""
        named = (
            ("--poses", self.poses),
            ("--robot-poses", self.robot_poses),
            ("--hand-eye", self.hand_eye),
            ("--board-in-base", self.board_in_base),
        )
        return [(option, path) for option, path in named if path is not None]

    def read(self) -> PhotoReference | None:
        """The external reference the options name (None: the board's own pose).

        Exits with code 2 for options that do not go together; the files' errors are
        ConfigErrors naming the file and row or key.
        """
        from simgap.pipeline.photo_references import PosesReference, RobotReference

        if self.poses is not None and self.robot_poses is not None:
            fail("--poses, --robot-poses: two references; give one")
        if self.robot_poses is None:
            for option, path in self.given:
                if option in ("--hand-eye", "--board-in-base"):
                    fail(f"{option} {path}: only with --robot-poses (the robot's flange poses)")
        if self.poses is not None:
            return PosesReference.read(self.poses)
        if self.robot_poses is not None and self.hand_eye is not None:
            return RobotReference.read(self.robot_poses, self.hand_eye, self.board_in_base)
        if self.robot_poses is not None:
            fail("--robot-poses: needs --hand-eye FILE (the camera in the flange frame)")
        return None


@dataclass(frozen=True)
class _PhotoOptions:
    """The options of ``ingest --board`` (see :func:`ingest`)."""

    calibration: Path | None
    experiment: Path | None
    max_pixels: int
    simulate: bool
    spp: int
    seed: int
    reference: _ReferenceFiles


def _ingest_photos(
    photos: Path, output: Path, board_file: Path, opts: _PhotoOptions, progress: bool,
    overwrite: bool,
) -> None:  # fmt: skip
    """``ingest --board``: measure a folder of board photos, and simulate them if asked."""
    from simgap.cli.progress import StepBars
    from simgap.core.board import read_board
    from simgap.pipeline.capture.calibration import read_calibration
    from simgap.pipeline.photos import measure_photos, with_calibration_check, write_photo_dataset
    from simgap.results.photo_summary import errors_by_distance, errors_table, gap_table

    if opts.calibration is None:
        fail("--board: the photos' calibration is needed (--calibration FILE)")
    inputs = [("CAPTURE", photos), ("--board", board_file), ("--calibration", opts.calibration)]
    inputs += list(opts.reference.given)
    if opts.experiment is not None:
        inputs += experiment_inputs(opts.experiment, "EXPERIMENT")
    check_outputs([(OUTPUT, output, PHOTO_DATASET)], inputs, overwrite)
    board = read_board(board_file)
    camera = read_calibration(opts.calibration)
    reference = opts.reference.read()
    exp = read_experiment(opts.experiment) if opts.experiment is not None else None
    pnp = exp.pnp if exp is not None else None
    with StepBars(progress) as bars:
        ds = measure_photos(photos, board, camera, pnp=pnp, max_pixels=opts.max_pixels,
                            progress=bars, reference=reference)  # fmt: skip
        diagnosis = None
        if opts.simulate:
            from simgap.analysis.gap import diagnose_photos

            spec = exp.scene_spec if exp is not None else None
            diagnosis = diagnose_photos(ds, board, camera, spec, opts.spp, opts.seed, bars)
    checked = _checked_file(photos, board, camera, opts, reference, progress)
    result = diagnosis.dataset if diagnosis is not None else ds
    if checked is not None:  # the file's verdict travels with the dataset, for its report
        result = with_calibration_check(result, checked)
    write_photo_dataset(result, output)
    seen = int(ds.detected.sum())
    against = f"the board's {ds.attrs['reference']}"
    if reference is not None:
        against = f"the {ds.attrs['reference']}"
        if "board_in_base_spread_m" in ds.attrs:
            against += (
                f" (the board's pose in the robot base {ds.attrs['board_in_base']}; they "
                f"scatter by {1e3 * ds.attrs['board_in_base_spread_m']:.2f} mm, "
                f"{1e3 * ds.attrs['board_in_base_spread_rad']:.2f} mrad)"
            )
    typer.echo(
        f"wrote {output}: {ds.attrs['frames']} photo(s), {ds.attrs['frames_unreadable']} "
        f"unreadable; {seen} marker sightings against {against}"
    )
    typer.echo(errors_table(errors_by_distance(ds)))
    typer.echo(f"its report (mm per third, figures): simgap report {output} -o REPORT_FOLDER")
    if checked is not None:
        _print_check(opts.calibration, checked)
    else:
        typer.echo(f"{opts.calibration}: not checked: no photo shows enough of the board")
    if diagnosis is not None:
        fit = diagnosis.fit
        typer.echo(
            f"the camera, fitted on the markers' images: exposure {fit.exposure_ev:+.2f} EV "
            f"(paper {fit.real_paper_level:.3f} against {fit.simulated_paper_level:.3f}), blur "
            f"{fit.blur_sigma_px:.3f} px (edge width {fit.real_edge_width_px:.3f} px against "
            f"{fit.simulated_edge_width_px:.3f}; {diagnosis.edge_width_after_px:.3f} with it)"
        )
        typer.echo("real - simulated, the simulation as it is:")
        typer.echo(gap_table(diagnosis.gaps.before["distance"]))
        typer.echo("real - simulated, with the camera fitted on the other half of the photos:")
        for bands in diagnosis.gaps.after.values():
            typer.echo(gap_table(bands))
        if diagnosis.gaps.rig is not None:
            for line in diagnosis.gaps.rig.lines(str(ds.attrs["reference"])):
                typer.echo(line)
            if diagnosis.gaps.after_rig:
                typer.echo(
                    "real - simulated, with the camera and the rig fitted on the other half of "
                    "the photos:"
                )
                typer.echo(gap_table(diagnosis.gaps.after_rig["distance"]))


@app.command()
def calibrate(
    photos: Annotated[Path, typer.Argument(help="Folder of photos (PNG or JPEG) of the board.")],
    board: Path = typer.Option(..., "--board", help="Board file (YAML; see ingest --board)."),
    output: Path | None = typer.Option(
        None, "-o", "--output", help="Write the fitted calibration here (ROS camera_info YAML)."
    ),
    calibration: Path | None = typer.Option(
        None,
        "--calibration",
        help="A calibration file to hold against the photos, parameter by parameter.",
    ),
    model: str = typer.Option(
        "plumb_bob", "--model", help="Distortion model fitted: plumb_bob or rational_polynomial."
    ),
    max_pixels: int = typer.Option(
        MAX_PIXELS, "--max-pixels", help="Pixel budget per photo (px).", min=1
    ),
    poses: PosesOption = None,
    robot_poses: RobotPosesOption = None,
    hand_eye: HandEyeOption = None,
    board_in_base: BoardInBaseOption = None,
    progress: ProgressOption = True,
    overwrite: OverwriteOption = False,
) -> None:
    """Calibrate the camera from photos of a board; hold a calibration file against them.

    The fit's standard deviations are the larger of OpenCV's and the leave-one-photo-out
    jackknife's. The given file's focal length, principal point, k1 and k2 are each corrected
    alone on the photos: a correction 3 jackknife sd from zero that lowers the board points'
    RMS by 10 % says the file does not describe the camera. With --poses or --robot-poses the
    board is held at its reference pose in every photo instead of posed from its own points, so
    the board's distance cannot absorb a focal-length error.
    """
    from simgap.core.atomic import atomic_write
    from simgap.core.board import read_board
    from simgap.pipeline.capture.calibration import calibration_to_yaml, read_calibration
    from simgap.pipeline.photos import named_photo_points
    from simgap.pose.board_calibration import CALIBRATION_FLAGS, calibrate_from_photos

    references = _ReferenceFiles(poses, robot_poses, hand_eye, board_in_base)
    inputs = [("PHOTOS", photos), ("--board", board), ("--calibration", calibration)]
    check_outputs([(OUTPUT, output, CALIBRATION_OUTPUT)], inputs + references.given, overwrite)
    if model not in CALIBRATION_FLAGS:
        fail(f"--model: expected one of {', '.join(CALIBRATION_FLAGS)}, got {model!r}")
    if references.given and calibration is None:
        fail(f"{references.given[0][0]}: a reference checks a file: give --calibration FILE")
    spec = read_board(board)
    given = read_calibration(calibration) if calibration is not None else None
    reference = references.read()
    names, points, size = named_photo_points(photos, spec, max_pixels)
    try:
        fit = calibrate_from_photos(points, size, model)
    except ValueError as exc:
        fail(f"{photos}: {exc}")
    cam = fit.camera
    typer.echo(
        f"{fit.photos} photo(s), {fit.points} points, RMS {fit.rms_px:.3f} px; "
        f"fx {cam.fx:.2f} +- {fit.std['fx']:.2f} px ({100 * fit.std['fx'] / cam.fx:.2f} %), "
        f"fy {cam.fy:.2f} +- {fit.std['fy']:.2f}, cx {cam.cx:.2f} +- {fit.std['cx']:.2f}, "
        f"cy {cam.cy:.2f} +- {fit.std['cy']:.2f}"
    )
    for name, camera in (("the fitted calibration", cam), (str(calibration), given)):
        if camera is not None:
            _warn_fold(name, camera, points)
    if given is not None:
        _print_check(calibration, _hold_file(given, names, points, reference, progress))
    if output is not None:
        header = (
            f"{CALIBRATION_HEADER} {fit.photos} photos of {board.name}, RMS {fit.rms_px:.3f} px\n"
        )
        text = header + calibration_to_yaml(cam)
        atomic_write(output, lambda tmp: tmp.write_text(text, encoding="utf-8"))
        typer.echo(f"wrote {output}")


@app.command("camera-response")
def camera_response(
    bracket: Annotated[
        Path,
        typer.Argument(
            help="Folder of photos of one still scene at several exposure times, with "
            "exposures.csv (image,exposure_s)."
        ),
    ],
    output: Annotated[Path, output_option("Response file to write (YAML).")],
    overwrite: OverwriteOption = False,
) -> None:
    """Measure the camera's response curve from an exposure bracket (for ingest --response).

    Debevec and Malik's estimate (OpenCV): the relative exposure at each 8-bit code, which the
    camera's own black level, encoding and tone curve make. A capture ingested with it is read
    through it, and its diagnosis simulates through it instead of sRGB.
    """
    from simgap.core.atomic import atomic_write
    from simgap.pipeline.capture.response_file import read_bracket, response_to_yaml
    from simgap.pose.camera_response import estimate_response

    check_outputs([(OUTPUT, output, RESPONSE_OUTPUT)], [("BRACKET", bracket)], overwrite)
    photos, times = read_bracket(bracket)
    try:
        response = estimate_response(photos, times)
    except ValueError as exc:
        fail(f"{bracket}: {exc}")
    mid = int(response.encode(0.18).round())
    typer.echo(
        f"{len(photos)} photos, {min(times):g}-{max(times):g} s; an 18 % grey at full-scale "
        f"exposure reads {mid} DN (sRGB: 118 DN)"
    )
    text = f"{RESPONSE_HEADER} {len(photos)} photos of {bracket}\n" + response_to_yaml(response)
    atomic_write(output, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    typer.echo(f"wrote {output}")


def _checked_file(
    photos: Path,
    board: Board,
    camera: CameraModel,
    opts: _PhotoOptions,
    reference: PhotoReference | None,
    progress: bool,
) -> FileCheck | None:
    """``ingest --board``'s calibration file held against its photos (:func:`_hold_file`).

    Against the reference where one is given, else each board posed from its own points, as
    ``calibrate --calibration`` holds it. None where no photo shows enough of the board.
    """
    from simgap.pipeline.photos import named_photo_points

    names, points, _ = named_photo_points(photos, board, opts.max_pixels)
    return _hold_file(camera, names, points, reference, progress) if points else None


def _hold_file(
    camera: CameraModel,
    names: list[str],
    points: list[tuple[np.ndarray, np.ndarray]],
    reference: PhotoReference | None,
    progress: bool,
) -> FileCheck:
    """A calibration file ``camera`` held against the photos, parameter by parameter.

    :func:`simgap.pose.calibration_check.check_calibration`, each photo's board posed from its
    own points or held at its pose from ``reference`` (re-solved through each correction tried:
    a robot's board-in-base solved from the photos depends on the camera).
    """
    from simgap.cli.progress import StepBars
    from simgap.pose.calibration_check import OWN_POINTS, FileCheck, check_calibration

    held: list[np.ndarray] | ReferencePoses | None = None
    against = OWN_POINTS
    if reference is not None:
        resolved = _reference_poses(reference, names, points, camera)
        held = resolved.camera_from_board
        against = f"the photos, each board held at its pose from {resolved.attrs['reference']}"
        if reference.uses_board_poses:  # re-solved through each camera the check tries
            chain = reference

            def through(checked: CameraModel, photos: Sequence[int]) -> list[np.ndarray]:
                chosen = ([names[i] for i in photos], [points[i] for i in photos])
                return _reference_poses(chain, *chosen, checked).camera_from_board

            held = through
    with StepBars(progress) as bars:
        return FileCheck(against, tuple(check_calibration(points, camera, bars, reference=held)))


def _print_check(path: Path | None, check: FileCheck) -> None:
    """Print a file's check: each parameter's correction, its sd and the RMS; the verdict."""
    typer.echo(
        f"{path} against {check.against}, each parameter corrected alone (the correction "
        "+- its jackknife sd; the board points' RMS reprojection before -> after):"
    )
    for c in check.parameters:
        flag = "  DOES NOT DESCRIBE THE PHOTOS" if c.disagrees else ""
        typer.echo(
            f"  {c.name:<13} {c.correction:+.4g} +- {c.std:.2g} {c.unit}".ljust(40)
            + f"RMS {c.rms_before_px:.3f} -> {c.rms_after_px:.3f} px{flag}"
        )
    typer.echo(check.verdict(str(path)))


def _reference_poses(
    reference: PhotoReference,
    names: list[str],
    points: list[tuple[np.ndarray, np.ndarray]],
    camera: CameraModel,
) -> ResolvedReference:
    """The reference poses of the photos ``names`` that show the board (``points``' order).

    A robot reference without ``--board-in-base`` solves the board's place from each photo's
    own board pose through ``camera`` (:meth:`RobotReference.resolve`); no other reads them, and
    they are not solved for it.
    """
    from simgap.core import transforms as tf
    from simgap.pose.board_pose import solve_board_pose

    own: list[np.ndarray | None] = [None] * len(points)
    if reference.uses_board_poses:
        for k, (obj, img) in enumerate(points):
            rvec, tvec, _ = solve_board_pose(obj, img, camera)
            own[k] = tf.make(tf.rotvec_to_matrix(rvec), tvec)
    return reference.resolve(names, own)


def _warn_fold(name: str, camera: CameraModel, points: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Say where a calibration's radial distortion folds inside the image.

    :func:`simgap.core.lens.fold_in_image`, beside how far the photos' board points reach from
    the principal point (px). Nothing where it folds beyond the image's corners.
    """
    import numpy as np

    from simgap.core.lens import fold_in_image

    fold = fold_in_image(
        camera.matrix, camera.distortion_model, camera.dist_coeffs, camera.width, camera.height
    )
    if fold is None:
        return
    centre = np.array([camera.cx, camera.cy])
    reach = max(
        (float(np.max(np.linalg.norm(img.reshape(-1, 2) - centre, axis=1))) for _, img in points),
        default=0.0,
    )
    typer.echo(
        f"{name}: its radial distortion folds back {fold[0]:.0f} px from the principal point, "
        f"inside the image (its corners are {fold[1]:.0f} px out; the photos' board points reach "
        f"{reach:.0f} px): past the fold the model gives pixels several rays or none, so a "
        "simulation or an undistortion there means nothing"
    )


@app.command("export-bag")
def export_bag(
    source: Annotated[
        Path,
        typer.Argument(help="Experiment YAML, simulated result dataset (.nc) or capture folder."),
    ],
    output: Annotated[
        Path,
        output_option(
            "Bag to write: NAME.bag (ROS 1), NAME.mcap or NAME.db3 (ROS 2, one file), "
            "NAME (ROS 2 bag folder)."
        ),
    ],
    fmt: BagFormat | None = typer.Option(
        None, "--format", help="Bag format (default: from the output's name; must agree)."
    ),
    storage: BagStorage | None = typer.Option(
        None,
        "--storage",
        help="ROS 2 bag folder storage (default sqlite3; a file's extension decides).",
    ),
    images: ImageEncoding = typer.Option(
        ImageEncoding.raw,
        "--images",
        help="Frames as raw bgr8 Images, or CompressedImages in PNG (lossless) or JPEG "
        "(quality 80, as ROS compressed_image_transport); a capture's files of that format keep "
        "their bytes.",
    ),
    compressed: bool | None = typer.Option(None, "--compressed/--raw", hidden=True),
    variant: VariantOption = None,
    calibration: CalibrationOption = None,
    cache: CacheOption = None,
    progress: ProgressOption = True,
    overwrite: OverwriteOption = False,
) -> None:
    """Write frames, CameraInfo, fixture joints, /tf_static, /tf and tag poses as a ROS bag."""
    from simgap.core.config import ConfigError
    from simgap.core.paths import default_cache_dir
    from simgap.pipeline.bag import capture_to_bag, experiment_to_bag
    from simgap.pipeline.bag.formats import ROS2_FILE_SUFFIXES, bag_target

    fmt = fmt.value if fmt else None
    storage = storage.value if storage else None
    inputs = [("SOURCE", source)] if source.is_dir() else simulation_inputs(source, "SOURCE")
    inputs += [("--calibration", calibration)]
    if calibration is not None and source.suffix not in (".yaml", ".yml"):
        fail(f"--calibration: only with an experiment YAML as SOURCE ({source} is not one)")
    # what the name would be written as: checked before its form, which the name must agree with
    suffix = output.suffix.lower()
    kind = ROS2_BAG_FILE if suffix in ROS2_FILE_SUFFIXES else ROS2_BAG
    kind = ROS1_BAG if fmt == "ros1" or suffix == ".bag" else kind
    check_outputs([(OUTPUT, output, kind)], inputs, overwrite)
    try:
        target = bag_target(output, fmt, storage)
    except ConfigError as exc:
        fail(str(exc))
    encoding = images.value
    if compressed is not None:  # the older spelling: --compressed is PNG, --raw raw
        older = "png" if compressed else "raw"
        if images is not ImageEncoding.raw and images.value != older:
            fail(f"--images {images.value} and --{'compressed' if compressed else 'raw'} disagree")
        encoding = older
    opts = {"images": encoding, "storage": target.storage}
    if source.is_dir():
        path = capture_to_bag(source, output, target.format, **opts)
    else:
        dataset = None
        if source.suffix == ".nc":
            dataset = read_result_dataset(source)
        from simgap.cli.progress import StepBars

        exp = (
            read_simulation(source) if calibration is None else read_experiment(source, calibration)
        )
        cache_dir = cache or default_cache_dir()
        with StepBars(progress) as bars:
            path = experiment_to_bag(
                exp, cache_dir, output, target.format, dataset, variant, **opts, progress=bars
            )
    what = target.format if target.storage is None else f"{target.format}, {target.storage}"
    typer.echo(f"wrote {path} ({what})")
