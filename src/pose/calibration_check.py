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

**Against an external reference.** Where each photo's board pose is known from outside the
photos (a tracker's poses, a robot's chain: :mod:`simgap.pipeline.photo_references`), the poses
are held there instead of re-solved: the board's distance is then no longer free to absorb the
focal length, and a focal error shows as the points' scale about the principal point. The
reference's own error (a tracker's, a robot's, a hand-eye's) enters the RMS and the jackknife
as the photos' scatter does. A reference that depends on the camera (a robot whose board-in-base
is solved from the photos' own board poses) is given as a :data:`ReferencePoses` and re-solved
through each correction tried: solved once through the file, it would absorb the file's focal
error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
from scipy.optimize import minimize_scalar

from simgap.core.progress import ProgressCallback, Steps
from simgap.core.rig import CameraModel
from simgap.core.robust import jackknife_std
from simgap.pose.board_pose import reprojection_rms, solve_board_pose

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


#: :attr:`FileCheck.against` where each photo's board was posed from its own points.
OWN_POINTS: Final[str] = "the photos"
#: The focal length's name among the checks (fx and fy together).
FOCAL_LENGTH: Final[str] = "focal length"
#: The parameters checked: the focal length (fx and fy together, relative), the principal
#: point (px) and the first two distortion coefficients (additive).
CHECKS: Final = (
    Check(FOCAL_LENGTH, "%", _focal, 0.10, 100.0),
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
    """

    name: str
    unit: str
    correction: float
    std: float
    rms_before_px: float
    rms_after_px: float

    @property
    def clear(self) -> bool:
        """The correction stands :data:`DISAGREE_SIGMAS` jackknife sd from zero."""
        return bool(self.std > 0 and abs(self.correction) >= DISAGREE_SIGMAS * self.std)

    @property
    def useful(self) -> bool:
        """The correction lowers the board points' RMS by :data:`MIN_RMS_FALL`."""
        return self.rms_after_px <= (1.0 - MIN_RMS_FALL) * self.rms_before_px

    @property
    def disagrees(self) -> bool:
        """Clear and useful (module doc): the file does not describe the camera."""
        return self.clear and self.useful

    @property
    def value(self) -> str:
        """The correction and its unit, in words (``-1.545 %``, ``-0.09601``)."""
        return f"{self.correction:+.4g} {self.unit}".rstrip()


@dataclass(frozen=True)
class FileCheck:
    """A calibration file held against photos: what it was held against and each parameter.

    Attributes
    ----------
    against : str
        What held the board in each photo, in words (:data:`OWN_POINTS`: each board posed
        from its own points; or the external reference).
    parameters : tuple of ParameterCheck
        Each parameter corrected alone (:func:`check_calibration`, :data:`CHECKS`' order).
    """

    against: str
    parameters: tuple[ParameterCheck, ...]

    @property
    def faults(self) -> list[ParameterCheck]:
        """The parameters the photos disagree with, the one that explains them best first."""
        return sorted((c for c in self.parameters if c.disagrees), key=lambda c: c.rms_after_px)

    def verdict(self, name: str) -> str:
        """One sentence on the file ``name``: which parameter does not describe the photos.

        The fault whose correction lowers the RMS most, with the others that alone explain
        less; or that no correction is both clear and useful (module doc), with the corrections
        that are clear but lower the RMS too little (a focal length 2 % long, held against
        photos that pose their boards themselves).
        """
        faults = self.faults
        if faults:
            worst, others = faults[0], ", ".join(c.name for c in faults[1:])
            return (
                f"{name} does not describe this camera: its {worst.name} corrected by "
                f"{worst.value} lowers the RMS {worst.rms_before_px:.3f} -> "
                f"{worst.rms_after_px:.3f} px"
                + (f" ({others} alone explain less)" if others else "")
            )
        text = (
            f"{name} describes the photos: no correction is both {DISAGREE_SIGMAS:g} sd from "
            f"zero and lowering the RMS by {100 * MIN_RMS_FALL:g} %"
        )
        leaning = [c for c in self.parameters if c.clear]
        if not leaning:
            return text
        each = ", ".join(
            f"{c.name} {c.value} (+- {c.std:.2g} {c.unit}".rstrip()
            + f"; RMS -{100 * (1.0 - c.rms_after_px / c.rms_before_px):.1f} %)"
            for c in leaning
        )
        text += f"; clear but small, each alone: {each}"
        if self.against == OWN_POINTS and any(c.name == FOCAL_LENGTH for c in leaning):
            text += (
                " (a board's distance absorbs most of a focal length's error; a reference "
                "pose per photo, --poses or --robot-poses, would pin it)"
            )
        return text

    def to_mapping(self) -> dict:
        """The check as plain Python values (a NaN standard deviation as None), for a file.

        Each parameter's ``disagrees`` is written for a reader of the file; it is derived again
        on reading (:meth:`from_mapping`).
        """
        return {
            "against": self.against,
            "parameters": [
                {
                    **dataclasses.asdict(c),
                    "std": None if np.isnan(c.std) else c.std,
                    "disagrees": c.disagrees,
                }
                for c in self.parameters
            ],
        }

    @classmethod
    def from_mapping(cls, mapping: dict) -> FileCheck:
        """The check :meth:`to_mapping` wrote.

        Raises
        ------
        KeyError, TypeError
            Where a key is missing or a value has the wrong type.
        """
        parameters = tuple(
            ParameterCheck(
                name=str(c["name"]),
                unit=str(c["unit"]),
                correction=float(c["correction"]),
                std=float("nan") if c["std"] is None else float(c["std"]),
                rms_before_px=float(c["rms_before_px"]),
                rms_after_px=float(c["rms_after_px"]),
            )
            for c in mapping["parameters"]
        )
        return cls(against=str(mapping["against"]), parameters=parameters)


#: Each photo's board points (n, 3) m and image points (n, 2) px.
Points = list[tuple[np.ndarray, np.ndarray]]
#: The reference poses (``camera_from_board``, 4 x 4, m) of the photos at the given indices of
#: the points, given the camera they are seen through: a robot chain whose board-in-base is
#: solved from the photos' own board poses depends on the camera being checked.
ReferencePoses = Callable[[CameraModel, Sequence[int]], Sequence[np.ndarray]]


def _rms(
    points: Points, camera: CameraModel, reference: ReferencePoses | None, photos: Sequence[int]
) -> float:
    """RMS reprojection (px) of the points of ``photos`` (indices into ``points``).

    Each photo's board pose solved anew, or held at its ``reference`` pose where one is given.
    """
    poses = None if reference is None else reference(camera, photos)
    total, count = 0.0, 0
    for k, i in enumerate(photos):
        obj, img = points[i]
        if poses is None:
            _, _, rms = solve_board_pose(obj, img, camera)
        else:
            rms = reprojection_rms(obj, img, camera, poses[k])
        total, count = total + rms**2 * len(obj), count + len(obj)
    return float(np.sqrt(total / count))


def _correct(
    points: Points,
    camera: CameraModel,
    check: Check,
    reference: ReferencePoses | None,
    photos: Sequence[int],
) -> tuple[float, float]:
    """The correction of one parameter minimising :func:`_rms`, and that RMS (px)."""
    res = minimize_scalar(
        lambda x: _rms(points, check.apply(camera, x), reference, photos),
        bounds=(-check.bound, check.bound),
        method="bounded",
        options={"xatol": check.bound * 1e-5},
    )
    return float(res.x), float(res.fun)


def check_calibration(
    points: Points,
    camera: CameraModel,
    progress: ProgressCallback | None = None,
    reference: Sequence[np.ndarray] | ReferencePoses | None = None,
) -> list[ParameterCheck]:
    """Each parameter of :data:`CHECKS` of ``camera`` corrected alone on the photos' ``points``.

    Parameters
    ----------
    points : list of (numpy.ndarray, numpy.ndarray)
        Each photo's board and image points (:func:`simgap.pose.board_calibration.board_points`).
    camera : CameraModel
        The file held against them.
    progress : callable, optional
        Told of each parameter checked (step ``"checking the file"``).
    reference : sequence of numpy.ndarray or ReferencePoses, optional
        Each photo's board pose from an external reference (``camera_from_board``, 4 x 4, m;
        the order of ``points``), or a :data:`ReferencePoses` that gives them for a camera: the
        poses are held there (module doc). None: each photo's pose is solved from its own
        points.

    Raises
    ------
    ValueError
        Where a sequence ``reference`` does not give one pose per photo.
    """
    if reference is not None and not callable(reference):
        if len(reference) != len(points):
            raise ValueError(f"{len(reference)} reference poses for {len(points)} photos")
        fixed = list(reference)

        def held(_: CameraModel, photos: Sequence[int]) -> Sequence[np.ndarray]:
            return [fixed[i] for i in photos]

        reference = held
    n = len(points)
    every = list(range(n))
    before = _rms(points, camera, reference, every)
    out = []
    steps = Steps(progress)
    steps.start("checking the file", len(CHECKS))
    for check in CHECKS:
        if check.name.startswith("k") and len(camera.distortion) < int(check.name[1:]):
            steps.advance()
            continue
        correction, after = _correct(points, camera, check, reference, every)
        std = float("nan")
        if n >= MIN_PHOTOS:
            loo = [
                _correct(points, camera, check, reference, every[:i] + every[i + 1 :])[0]
                for i in range(n)
            ]
            std = float(jackknife_std(np.array(loo)))
        out.append(
            ParameterCheck(
                check.name, check.unit, correction * check.scale, std * check.scale, before, after
            )
        )
        steps.advance()
    return out


__all__ = [
    "CHECKS",
    "DISAGREE_SIGMAS",
    "FOCAL_LENGTH",
    "MIN_PHOTOS",
    "MIN_RMS_FALL",
    "OWN_POINTS",
    "Check",
    "FileCheck",
    "ParameterCheck",
    "Points",
    "ReferencePoses",
    "check_calibration",
]
