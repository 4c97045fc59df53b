"""Ingest a capture folder: detect, estimate every tag, and build the result dataset."""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path

import cv2
import numpy as np
import xarray as xr
import yaml
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

from simgap.core.config import to_mapping
from simgap.core.limits import MAX_PIXELS
from simgap.core.paths import CALIBRATION_FILE
from simgap.core.rig import CameraModel, Rig, load_rig
from simgap.pipeline.capture.folder import CaptureWarning, read_capture, read_image
from simgap.pipeline.capture.manifest import CaptureFrame
from simgap.pose.camera_response import CameraResponse
from simgap.pose.cfa import CfaTraces, around_markers
from simgap.pose.detect import Detector, DetectorSettings
from simgap.pose.estimate import PnPSettings
from simgap.pose.image_stats import is_grey
from simgap.pose.tags import Estimation, add_image_stats, estimate_tags
from simgap.results.contract import CONVENTIONS
from simgap.results.dataset import (
    build_dataset,
    empty_results,
    ground_truth,
    software_versions,
)

VARIANT = "real"
DEFAULT_DETECTOR = DetectorSettings()
DEFAULT_PNP = PnPSettings()


def _progress(show: bool) -> Progress:
    """A progress bar with counts (hidden unless ``show``)."""
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        disable=not show,
    )


def _read_frame(
    frame: CaptureFrame, cal: CameraModel, failed: list[str]
) -> tuple[np.ndarray, np.ndarray | None] | None:
    """The 8-bit grey frame and its 8-bit RGB, or None (warned, added to ``failed``) when unusable.

    The RGB is None where the frame is grey (its three decoded channels are equal). A frame
    whose header gives another size than the calibration's is not decoded.
    """
    img = read_image(frame.image, cal.width, cal.height)
    if isinstance(img, str):
        warnings.warn(
            f"{frame.image}: frame {img}; recorded as not detected", CaptureWarning, stacklevel=3
        )
        failed.append(str(frame.image))
        return None
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), None if is_grey(img) else img[..., ::-1]


def ingest(
    folder: Path,
    rig: Rig | None = None,
    detector: DetectorSettings = DEFAULT_DETECTOR,
    pnp: PnPSettings = DEFAULT_PNP,
    calibration: CameraModel | None = None,
    show_progress: bool = False,
    calibration_file: Path | None = None,
    max_pixels: int = MAX_PIXELS,
    response: CameraResponse | None = None,
) -> xr.Dataset:
    """Detect markers and estimate poses in a capture; return the result dataset.

    The dataset follows the contract of a simulated sweep (docs/conventions.md §3): variant
    ``"real"``; coords ``p``, ``theta`` and ``repeat`` are the sorted unique values of the manifest,
    ``tag`` the rig's tag ids; configurations absent from the manifest are not detected (NaN). Poses
    are estimated with the capture's calibration, and the image evidence measured, exactly as
    :func:`simgap.pose.tags.estimate_tags` and :func:`~simgap.pose.tags.add_image_stats` do for
    renders. Where a pose has more than one frame (repeats), its first frame's statistics also carry
    the temporal noise and the repeat gain measured against its second. The colour fringe is
    measured on colour frames (NaN on grey ones).

    Parameters
    ----------
    folder : Path
        The capture folder.
    rig : Rig, optional
        Ground truth (expected poses, visibility, grid); default: the packaged rig.
    detector : DetectorSettings
        ArUco detector settings.
    pnp : PnPSettings
        PnP settings.
    calibration : CameraModel, optional
        Estimate with this calibration instead of ``camera.yaml`` (e.g. to test a corrected
        calibration on real corners); recorded in the attrs.
    show_progress : bool
        Show a progress bar.
    calibration_file : Path, optional
        The calibration file to read instead of the folder's ``camera.yaml`` (any name; see
        :func:`~simgap.pipeline.capture.folder.read_capture`); ``calibration`` still wins.
    max_pixels : int
        The pixel budget (:data:`~simgap.core.limits.MAX_PIXELS`).
    response : CameraResponse, optional
        The camera's measured response (``simgap camera-response``): the frames' levels are
        linearised through it (:func:`simgap.pose.image_stats.linearised`) and the diagnosis
        simulates through it; recorded in the attrs.

    Returns
    -------
    xarray.Dataset
        Attrs: ``source = "capture"``, ``capture_dir``, ``calibration_yaml`` (the calibration
        used, as a CameraModel mapping: px, dimensionless distortion), ``calibration_source``
        (``"override"``: ``calibration``; ``"camera.yaml"``: the folder's; ``"--calibration"``:
        ``calibration_file``), ``calibration_path`` (the absolute path of the file read),
        ``calibration_file`` (that file's text), ``detector``, ``pnp``, ``frames``,
        ``frames_unreadable`` (count of frames that could not be decoded or had the wrong size,
        each recorded as not detected), ``frames_failed`` (JSON list of their paths),
        ``frames_identical_repeats`` (JSON list of the second frames of poses whose first two
        readable frames are identical pixels: no temporal noise is measured there),
        ``camera_demosaicing`` (JSON: the colour filter layout and nearest demosaicing method
        the colour frames show around their markers, :class:`simgap.pose.cfa.CfaVerdict`; null
        layout where none shows), ``camera_response`` (JSON list: ``response``'s relative
        exposure at each 8-bit code; absent without one), versions.

    Raises
    ------
    simgap.core.config.ConfigError
        As :func:`read_capture`.

    Warns
    -----
    CaptureWarning
        For each frame that cannot be decoded or has the wrong size.
    """
    rig = rig or load_rig()
    cap = read_capture(folder, rig, calibration_file, max_pixels)
    cal = calibration or cap.calibration
    cal_path = cap.calibration_path or cap.folder / CALIBRATION_FILE
    source = CALIBRATION_FILE if calibration_file is None else "--calibration"
    source = "override" if calibration is not None else source
    measured = None if response is None else tuple(float(v) for v in response.linear)
    estimation = Estimation(calibration=cal, detector=detector, pnp=pnp, response=measured)
    det = Detector(detector)
    tags = rig.tags.ids
    ps = sorted({f.p for f in cap.frames})
    thetas = sorted({f.theta for f in cap.frames})
    repeats = sorted({f.repeat for f in cap.frames})
    shape = (1, len(repeats), len(tags), len(ps), len(thetas))
    res = empty_results(shape)
    failed: list[str] = []
    by_pose: dict[tuple[int, float], list[CaptureFrame]] = {}
    for frame in cap.frames:
        by_pose.setdefault((frame.p, frame.theta), []).append(frame)
    cfa_traces = CfaTraces()
    identical: list[str] = []  # poses whose first two readable frames are the same pixels
    with _progress(show_progress) as bar:
        task = bar.add_task(f"ingest {cap.folder.name}", total=len(cap.frames))
        for frames in by_pose.values():
            frames = sorted(frames, key=lambda f: f.repeat)
            images = [_read_frame(frame, cal, failed) for frame in frames]
            readable = [k for k, image in enumerate(images) if image is not None]
            if len(readable) > 1 and np.array_equal(
                images[readable[0]][0], images[readable[1]][0]
            ):  # a copied file is no second exposure: its temporal noise would read zero
                identical.append(str(frames[readable[1]].image))
                readable = readable[:1]
            for k, (frame, image) in enumerate(zip(frames, images, strict=True)):
                bar.advance(task)
                if image is None:
                    continue
                gray, rgb = image
                # the first readable frame of a pose with another one also gets the temporal noise
                # and the repeat gain
                other = images[readable[1]][0] if len(readable) > 1 and k == readable[0] else None
                found, rejected = det.detect_with_rejected(gray)
                if rgb is not None and found:
                    cfa_traces.add(*around_markers(rgb, found))
                out = estimate_tags(rig, estimation, tags, found, frame.p, frame.theta)
                add_image_stats(
                    out,
                    rig,
                    estimation,
                    tags,
                    gray,
                    (0, 0),
                    found,
                    rejected,
                    frame.p,
                    frame.theta,
                    other,
                    rgb=rgb,
                )
                idx = (0, repeats.index(frame.repeat), slice(None), ps.index(frame.p))
                idx = idx + (thetas.index(frame.theta),)
                for key, v in out.arrays().items():
                    res[key][idx] = v
    if identical:
        warnings.warn(
            f"{cap.folder}: {len(identical)} pose(s) offer identical frames as repeats (e.g. "
            f"{identical[0]}): a copy is no second exposure, so their temporal noise and gain "
            "change are not measured",
            CaptureWarning,
            stacklevel=2,
        )
    expected, visible = ground_truth(rig, tags, ps, thetas)
    attrs = {
        "title": f"simgap result: capture {cap.folder.name}",
        "source": "capture",
        "capture_dir": str(cap.folder.resolve()),
        "calibration_yaml": yaml.safe_dump(to_mapping(cal), sort_keys=False),
        "calibration_source": source,
        "calibration_path": str(Path(cal_path).resolve()),
        "calibration_file": Path(cal_path).read_text(),
        "rig_yaml": yaml.safe_dump(to_mapping(rig), sort_keys=False),
        "repeats": str(len(repeats)),
        "frames": len(cap.frames),
        "frames_unreadable": len(failed),
        "frames_failed": json.dumps(failed),
        "frames_identical_repeats": json.dumps(identical),
        "detector": json.dumps({VARIANT: f"{detector}"}),
        "pnp": json.dumps({VARIANT: f"{pnp}"}),
        "camera_demosaicing": json.dumps(dataclasses.asdict(cfa_traces.verdict())),
        **({} if measured is None else {"camera_response": json.dumps(measured)}),
        **software_versions(),
        "conventions": CONVENTIONS,
    }
    return build_dataset(
        tags,
        tuple(ps),
        np.asarray(thetas),
        expected,
        visible,
        res,
        variants=(VARIANT,),
        repeats=tuple(repeats),
        attrs=attrs,
    )
