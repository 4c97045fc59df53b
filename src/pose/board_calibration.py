"""A camera calibrated from photos of a board, with each parameter's uncertainty.

OpenCV's calibration (``cv2.calibrateCameraExtended``) on the board's reference points of every
photo (:func:`simgap.pose.board_pose.reference_points`: a ChArUco board's chessboard corners, a
grid board's marker corners), in the model of a given calibration file (plumb_bob or
rational_polynomial; 5 coefficients without one).

Each parameter's standard deviation is the larger of OpenCV's (from the Jacobian at the
solution and the residuals' variance: it assumes independent corner errors) and the
leave-one-photo-out jackknife's (Efron & Tibshirani 1993, ch. 11; what a different set of views
would have given). On eight real RealSense photos OpenCV's were 1.4-5.3 times smaller than the
jackknife's (docs/results/real_photos.md): the views, not the corners, limit a calibration. A
given file is held against the photos parameter by parameter by
:mod:`simgap.pose.calibration_check`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import cv2
import numpy as np

from simgap.core.board import Board
from simgap.core.rig import CameraModel
from simgap.core.robust import jackknife_std
from simgap.pose.board_pose import MIN_REFERENCE_POINTS, reference_points
from simgap.pose.detect import Detector

#: Distortion models a calibration from photos fits, with OpenCV's flags for each.
CALIBRATION_FLAGS: Final = {"plumb_bob": 0, "rational_polynomial": cv2.CALIB_RATIONAL_MODEL}
#: Fewest photos whose leave-one-out jackknife enters the standard deviations (module doc).
JACKKNIFE_MIN_PHOTOS: Final[int] = 4
#: Names of the intrinsics in OpenCV's order (``stdDeviationsIntrinsics``), coefficients after.
INTRINSIC_NAMES: Final = ("fx", "fy", "cx", "cy")
COEFFICIENT_NAMES: Final = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")


@dataclass(frozen=True)
class PhotoCalibration:
    """A calibration fitted on photos.

    Attributes
    ----------
    camera : CameraModel
        The fitted camera.
    std : dict of str to float
        Standard deviation of each fitted parameter (px for fx, fy, cx, cy; 1 for
        coefficients): the larger of OpenCV's and the jackknife's (module doc).
    rms_px : float
        RMS reprojection error over all points (px).
    photos : int
        Photos used (at least :data:`~simgap.pose.board_pose.MIN_REFERENCE_POINTS` points each).
    points : int
        Points used.
    """

    camera: CameraModel
    std: dict[str, float]
    rms_px: float
    photos: int
    points: int


def board_points(
    grays: list[np.ndarray], board: Board, detector: Detector
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each photo's board points (n, 3) m and image points (n, 2) px, where it shows enough.

    The reference points of :func:`simgap.pose.board_pose.reference_points`; photos with fewer
    than :data:`~simgap.pose.board_pose.MIN_REFERENCE_POINTS` are left out.
    """
    out = []
    for gray in grays:
        markers = {i: c for i, c in detector.detect(gray).items() if i in board.marker_corners}
        obj, img, _ = reference_points(gray, board, markers)
        if len(obj) >= MIN_REFERENCE_POINTS:
            out.append((obj, img))
    return out


def calibrate_from_photos(
    points: list[tuple[np.ndarray, np.ndarray]], size: tuple[int, int], model: str = "plumb_bob"
) -> PhotoCalibration:
    """Calibrate a camera of image ``size`` (w, h px) in ``model`` from its photos' board points.

    ``points``: each photo's board and image points (:func:`board_points`).

    Raises
    ------
    ValueError
        ``"model: ..."`` for a model not in :data:`CALIBRATION_FLAGS`; ``"photos: ..."`` where
        fewer than three photos show enough of the board (OpenCV needs views of several poses).
    """
    if model not in CALIBRATION_FLAGS:
        raise ValueError(f"model: calibration from photos fits {', '.join(CALIBRATION_FLAGS)}")
    obj_all, img_all = [], []
    for obj, img in points:
        obj_all.append(obj.astype(np.float32))
        img_all.append(img.astype(np.float32).reshape(-1, 1, 2))
    if len(obj_all) < 3:
        raise ValueError(
            f"photos: {len(obj_all)} show at least {MIN_REFERENCE_POINTS} board points; "
            "calibration needs at least 3"
        )
    w, h = size
    camera, std, rms = _calibrate(obj_all, img_all, (w, h), model)
    if len(obj_all) >= JACKKNIFE_MIN_PHOTOS:
        loo = [
            _values(_calibrate(obj_all[:i] + obj_all[i + 1:], img_all[:i] + img_all[i + 1:],
                               (w, h), model)[0])
            for i in range(len(obj_all))
        ]  # fmt: skip
        jack = jackknife_std(np.array(loo))
        std = {k: max(v, float(j)) for (k, v), j in zip(std.items(), jack, strict=True)}
    return PhotoCalibration(camera, std, rms, len(obj_all), sum(len(o) for o in obj_all))


def _values(camera: CameraModel) -> np.ndarray:
    """fx, fy, cx, cy and the coefficients of ``camera``, in :data:`INTRINSIC_NAMES` order."""
    return np.array([camera.fx, camera.fy, camera.cx, camera.cy, *camera.distortion])


def _calibrate(
    obj: list[np.ndarray], img: list[np.ndarray], size: tuple[int, int], model: str
) -> tuple[CameraModel, dict[str, float], float]:
    """OpenCV's calibration: the camera, OpenCV's standard deviations and the RMS (px)."""
    rms, k, dist, _, _, std_int, _, _ = cv2.calibrateCameraExtended(
        obj, img, size, None, None, flags=CALIBRATION_FLAGS[model]
    )
    n_coeffs = 8 if model == "rational_polynomial" else 5
    names = INTRINSIC_NAMES + COEFFICIENT_NAMES[:n_coeffs]
    std = dict(zip(names, np.asarray(std_int, float).ravel()[: len(names)].tolist(), strict=True))
    camera = CameraModel(
        width=size[0], height=size[1], fx=float(k[0, 0]), fy=float(k[1, 1]), cx=float(k[0, 2]),
        cy=float(k[1, 2]), distortion=tuple(float(v) for v in np.ravel(dist)[:n_coeffs]),
        distortion_model=model,
    )  # fmt: skip
    return camera, std, float(rms)


__all__ = [
    "CALIBRATION_FLAGS",
    "JACKKNIFE_MIN_PHOTOS",
    "PhotoCalibration",
    "board_points",
    "calibrate_from_photos",
]
