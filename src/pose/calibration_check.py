"""A calibration file held against photos of a board, one parameter at a time.

A full calibration from a handful of photos pins its parameters only loosely (the focal length
to 2-22 % on the real sets of docs/results/real_photos.md), because every parameter trades off
against the others. Holding a file against the photos asks a narrower question: with the file's
other parameters as they are, does correcting this one explain the photos' board points better?
Each checked parameter (:data:`CHECKS`) is refitted alone, every photo's board pose re-solved
(:func:`simgap.pose.board_pose.solve_board_pose`), to the least RMS reprojection of all points
(px); its uncertainty is the leave-one-photo-out jackknife's (Efron & Tibshirani 1993, ch. 11).

A correction says the file does not describe the camera where it is both clear and useful: at
least :data:`DISAGREE_SIGMAS` jackknife standard deviations from zero, and lowering the points'
RMS by at least :data:`MIN_RMS_FALL`. Measured on two real sets (docs/results/real_photos.md): the
files as shipped improve by 0.5-0.8 % at most (one k1 correction of -0.012 at 3.9 sd on 8
photos); a k1 shifted by 0.1 in the file is corrected by -0.096 and -0.112 (RMS down 33-59 %);
a focal length 2 % long is corrected by -1.5 % and -1.8 % but lowers the RMS by 4-7 % only (a
board's depth and the focal length trade off), so it is reported with its value and not as a
fault. Every distortion model is held the same way, its k1 and k2 being the file's first two
coefficients: a rational_polynomial file fitted on 28 RealSense photos (k1-k6 large and
balanced) is no fault on 8 of them and its k1 shifted by 0.1 is corrected by -0.123 (its
denominator divides k1's effect by up to 2.2 over the board; the jackknife sd is 2.8 times
plumb_bob's); an equidistant (fisheye) file's (its theta^3 term) by -0.113.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

import numpy as np
from scipy.optimize import minimize_scalar

from simgap.core.progress import ProgressCallback, Steps
from simgap.core.rig import CameraModel
from simgap.core.robust import jackknife_std
from simgap.pose.board_pose import solve_board_pose

#: A correction this many jackknife standard deviations from zero is clear: the two-sided
#: 99.7 % level of a normal estimate.
DISAGREE_SIGMAS: Final[float] = 3.0
#: ... and useful where it lowers the board points' RMS reprojection by this share: the
#: relative tolerance simgap's diagnosis gives every evidence channel (10 %).
MIN_RMS_FALL: Final[float] = 0.10
#: Fewest photos for a jackknife (with fewer, no correction is called clear).
MIN_PHOTOS: Final[int] = 4


def _focal(camera: CameraModel, x: float) -> CameraModel:
    return dataclasses.replace(camera, fx=camera.fx * (1 + x), fy=camera.fy * (1 + x))


def _coefficient(k: int) -> Callable[[CameraModel, float], CameraModel]:
    def apply(camera: CameraModel, x: float) -> CameraModel:
        d = list(camera.distortion)
        d[k] += x
        return dataclasses.replace(camera, distortion=tuple(d))

    return apply


@dataclass(frozen=True)
class Check:
    """One parameter a file is checked on: how a correction applies, its unit and its range."""

    name: str
    unit: str
    apply: Callable[[CameraModel, float], CameraModel]
    bound: float
    scale: float = 1.0  # of the correction as printed (100 for a fraction shown in %)


#: The parameters checked: the focal length (fx and fy together, relative), the principal
#: point (px) and the first two distortion coefficients (additive).
CHECKS: Final = (
    Check("focal length", "%", _focal, 0.10, 100.0),
    Check("cx", "px", lambda c, x: dataclasses.replace(c, cx=c.cx + x), 50.0),
    Check("cy", "px", lambda c, x: dataclasses.replace(c, cy=c.cy + x), 50.0),
    Check("k1", "", _coefficient(0), 0.5),
    Check("k2", "", _coefficient(1), 2.0),
)


@dataclass(frozen=True)
class ParameterCheck:
    """A file's parameter corrected alone on the photos.

    Attributes
    ----------
    name, unit : str
        The parameter and the unit of ``correction`` and ``std`` (``%``, ``px`` or none).
    correction : float
        What the photos ask to add to the file's value (in ``unit``).
    std : float
        Its jackknife standard deviation (in ``unit``; NaN with too few photos).
    rms_before_px, rms_after_px : float
        RMS reprojection of all board points with the file's value and with the correction.
    disagrees : bool
        The correction is clear and useful (module doc): the file does not describe the camera.
    """

    name: str
    unit: str
    correction: float
    std: float
    rms_before_px: float
    rms_after_px: float
    disagrees: bool


def _rms(points: list[tuple[np.ndarray, np.ndarray]], camera: CameraModel) -> float:
    """RMS reprojection (px) of all photos' points, each photo's board pose solved anew."""
    total, count = 0.0, 0
    for obj, img in points:
        _, _, rms = solve_board_pose(obj, img, camera)
        total, count = total + rms**2 * len(obj), count + len(obj)
    return float(np.sqrt(total / count))


def _correct(points: list[tuple[np.ndarray, np.ndarray]], camera: CameraModel, check: Check):
    """The correction of one parameter minimising :func:`_rms`, and that RMS (px)."""
    res = minimize_scalar(
        lambda x: _rms(points, check.apply(camera, x)),
        bounds=(-check.bound, check.bound),
        method="bounded",
        options={"xatol": check.bound * 1e-5},
    )
    return float(res.x), float(res.fun)


def check_calibration(
    points: list[tuple[np.ndarray, np.ndarray]],
    camera: CameraModel,
    progress: ProgressCallback | None = None,
) -> list[ParameterCheck]:
    """Each parameter of :data:`CHECKS` of ``camera`` corrected alone on the photos' ``points``.

    ``points``: each photo's board and image points
    (:func:`simgap.pose.board_calibration.board_points`); ``progress`` is told of each parameter
    checked (step ``"checking the file"``).
    """
    before = _rms(points, camera)
    n = len(points)
    out = []
    steps = Steps(progress)
    steps.start("checking the file", len(CHECKS))
    for check in CHECKS:
        if check.name.startswith("k") and len(camera.distortion) < int(check.name[1:]):
            steps.advance()
            continue
        correction, after = _correct(points, camera, check)
        std = float("nan")
        if n >= MIN_PHOTOS:
            loo = [_correct(points[:i] + points[i + 1 :], camera, check)[0] for i in range(n)]
            std = float(jackknife_std(np.array(loo)))
        clear = bool(std > 0 and abs(correction) >= DISAGREE_SIGMAS * std)
        useful = after <= (1.0 - MIN_RMS_FALL) * before
        out.append(
            ParameterCheck(
                check.name,
                check.unit,
                correction * check.scale,
                std * check.scale,
                before,
                after,
                clear and useful,
            )  # fmt: skip
        )
        steps.advance()
    return out


__all__ = [
    "CHECKS",
    "DISAGREE_SIGMAS",
    "MIN_PHOTOS",
    "MIN_RMS_FALL",
    "Check",
    "ParameterCheck",
    "check_calibration",
]
