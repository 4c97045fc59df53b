"""Real captures in and out: read and validate a capture folder, ingest it, write one.

A capture folder (docs/conventions.md §3) is what a rig operator records on real hardware, and
also what pseudo-real data is written as::

    capture/
      camera.yaml     the calibration the operator believes in: ROS camera_info YAML, OpenCV
                      FileStorage YAML (first line ``%YAML:1.0`` or ``%YAML 1.2``) or a Kalibr
                      camchain (its cam0)
      manifest.csv    header image,p,theta_rad (optional columns: repeat, note)
      images/...      8-bit PNG or JPEG frames, as the camera delivered them

:func:`read_capture` validates a folder against a rig, :func:`ingest` turns it into a result
dataset with the same contract as a simulated sweep (variant ``"real"``), and
:func:`write_capture` writes one. Every problem with a folder raises
:class:`~simgap.core.config.ConfigError` naming the file, the row or key, and what was expected; a
frame that cannot be decoded is not an error but a recorded detection failure (and a
:class:`CaptureWarning`).

Examples
--------
>>> from simgap.pipeline.capture import ingest
>>> ds = ingest(Path("captures/run-2024-05-01"))           # doctest: +SKIP
>>> ds.error.sel(axis="ty").mean().item()                   # doctest: +SKIP

Modules, by job: :mod:`.calibration` (the registry of calibration formats, with
:mod:`.ros_yaml`, :mod:`.opencv_yaml` and :mod:`.kalibr_yaml` registered in it),
:mod:`.manifest` (``manifest.csv``), :mod:`.folder` (a folder validated against a rig),
:mod:`.ingest` and :mod:`.writer`.
"""

from __future__ import annotations

from simgap.pipeline.capture import kalibr_yaml, opencv_yaml, ros_yaml  # noqa: F401  (registration)
from simgap.pipeline.capture.calibration import (
    CALIBRATION_FORMATS,
    CalibrationFormat,
    calibration_format,
    calibration_to_yaml,
    read_calibration,
    register_format,
)
from simgap.pipeline.capture.folder import Capture, CaptureWarning, read_capture
from simgap.pipeline.capture.ingest import ingest
from simgap.pipeline.capture.manifest import CaptureFrame, snap_theta, turntable_stop
from simgap.pipeline.capture.writer import image_name, write_capture

__all__ = [
    "CALIBRATION_FORMATS",
    "CalibrationFormat",
    "Capture",
    "CaptureFrame",
    "CaptureWarning",
    "calibration_format",
    "calibration_to_yaml",
    "image_name",
    "ingest",
    "read_calibration",
    "read_capture",
    "register_format",
    "snap_theta",
    "turntable_stop",
    "write_capture",
]
