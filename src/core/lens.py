"""OpenCV's camera models: the distortion models a calibration writes, projection and its inverse.

Every model maps a point ``(X, Y, Z)`` of the OpenCV camera frame (x right, y down, z forward; m)
to a pixel ``(u, v)`` (px, pixel centres at integers) through normalised coordinates
``(a, b) = (X / Z, Y / Z)``, exactly as OpenCV computes it (``cv2.projectPoints`` and
``cv2.fisheye.projectPoints``); simgap's renderer follows the same formulas per ray
(:mod:`simgap.render.camera`), and its PnP undoes them (:mod:`simgap.pose.estimate`).

The pinhole family (OpenCV's ``calib3d`` model; ``r^2 = a^2 + b^2``)::

    x' = a (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
         + 2 p1 a b + p2 (r^2 + 2 a^2) + s1 r^2 + s2 r^4
    y' = b (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
         + p1 (r^2 + 2 b^2) + 2 p2 a b + s3 r^2 + s4 r^4
    (x'', y'') = (x', y') through the sensor tilt (tau_x, tau_y)  (:func:`tilt_matrix`)
    u = fx x'' + cx,  v = fy y'' + cy

with, by the number of coefficients (OpenCV's order), ``plumb_bob`` (5: k1 k2 p1 p2 k3; ROS's
name), ``rational_polynomial`` (8: + k4 k5 k6; ROS's name), ``thin_prism`` (12: + s1..s4) and
``tilted`` (14: + tau_x tau_y, rad); absent coefficients are 0.

``equidistant`` (ROS's name for OpenCV's fisheye model, Kannala-Brandt; 4 coefficients)::

    theta = atan(r),  theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
    x' = (theta_d / r) a,  y' = (theta_d / r) b,  u = fx x' + cx,  v = fy y' + cy
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import cv2
import numpy as np

#: Each model's coefficients, in OpenCV's order (module docstring).
DISTORTION_MODELS: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "plumb_bob": ("k1", "k2", "p1", "p2", "k3"),
        "rational_polynomial": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
        "thin_prism": (
            *("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
            *("s1", "s2", "s3", "s4"),
        ),
        "tilted": (
            *("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
            *("s1", "s2", "s3", "s4", "tau_x", "tau_y"),
        ),
        "equidistant": ("k1", "k2", "k3", "k4"),
    }
)
#: The model of each pinhole-family coefficient count (OpenCV reads a model from the count).
MODEL_OF_COUNT: Mapping[int, str] = MappingProxyType(
    {len(c): m for m, c in DISTORTION_MODELS.items() if m != "equidistant"}
)
#: Bounds of the coefficients by kind (dimensionless; tilt in rad): radial terms up to 100, and
#: up to 1000 in the rational models, whose numerator and denominator balance (a RealSense
#: D415's file: k3 100 and k6 103, within about 1 px of a 5-coefficient fit inside the image);
#: tangential and thin-prism terms are small; a sensor tilt beyond 0.5 rad (29 deg) is no lens.
COEFF_BOUNDS: Mapping[str, float] = MappingProxyType(
    {"k": 100.0, "k_rational": 1000.0, "p": 1.0, "s": 1.0, "tau": 0.5}
)
#: The models whose radial terms are a ratio of polynomials (``k4``-``k6`` in the denominator).
RATIONAL_MODELS = ("rational_polynomial", "thin_prism", "tilted")
#: Iterations and tolerance of the inverse (undistortion): 100 and 1e-14 in normalised units,
#: far below a thousandth of a pixel.
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)


def coefficient_bound(name: str, model: str) -> float:
    """The largest magnitude coefficient ``name`` of ``model`` may have (:data:`COEFF_BOUNDS`)."""
    if name.startswith("tau"):
        return COEFF_BOUNDS["tau"]
    if name[0] == "k" and model in RATIONAL_MODELS:
        return COEFF_BOUNDS["k_rational"]
    return COEFF_BOUNDS[name[0]]


def is_fisheye(model: str) -> bool:
    """Whether ``model`` is OpenCV's fisheye (``equidistant``) rather than the pinhole family."""
    return model == "equidistant"


def project(
    points: np.ndarray, matrix: np.ndarray, model: str, coeffs: np.ndarray
) -> np.ndarray:
    """Pixels (..., 2) (px) of camera-frame points (..., 3) (m), OpenCV's projection of ``model``.

    Points must lie in front of the camera (z > 0).
    """
    pts = np.asarray(points, dtype=np.float64)
    flat = np.ascontiguousarray(pts.reshape(-1, 1, 3))
    zero = np.zeros(3)
    if is_fisheye(model):
        uv, _ = cv2.fisheye.projectPoints(flat, zero, zero, matrix, np.asarray(coeffs, float))
    else:
        uv, _ = cv2.projectPoints(flat, zero, zero, matrix, np.asarray(coeffs, float))
    return uv.reshape(pts.shape[:-1] + (2,))


def normalise(uv: np.ndarray, matrix: np.ndarray, model: str, coeffs: np.ndarray) -> np.ndarray:
    """Normalised coordinates ``(X / Z, Y / Z)`` (..., 2) of pixels (..., 2).

    The inverse of :func:`project`, iterated to :data:`UNDISTORT_CRITERIA`.
    """
    pix = np.asarray(uv, dtype=np.float64)
    flat = np.ascontiguousarray(pix.reshape(-1, 1, 2))
    d = np.asarray(coeffs, float)
    if is_fisheye(model):
        out = cv2.fisheye.undistortPoints(flat, matrix, d, criteria=UNDISTORT_CRITERIA)
    else:
        out = cv2.undistortPoints(flat, matrix, d, criteria=UNDISTORT_CRITERIA)
    return out.reshape(pix.shape)


#: Largest normalised radius searched for the radial distortion's fold (:func:`monotone_radius`):
#: tan 85 deg, a view 85 deg off the optical axis (a pinhole-family model past it is no lens).
MAX_NORMALISED_RADIUS = float(np.tan(np.deg2rad(85.0)))
#: Samples of that search: a step of 1e-4 in normalised radius, a tenth of a pixel at a 1000 px
#: focal length.
RADIUS_SAMPLES = 114_300


def distorted_radius(r: np.ndarray, model: str, coeffs: np.ndarray) -> np.ndarray:
    """The radial part of a model: distorted normalised radius of normalised radius ``r``.

    :func:`project` of the points ``(r, 0, 1)`` through the model's radial coefficients alone
    (``k1``-``k6``; the tangential, thin-prism and tilt terms set to 0) and the identity camera
    matrix: the pinhole family's ``r`` times its radial factor, the fisheye's ``theta_d``
    (module docstring).
    """
    r = np.asarray(r, float)
    radial = [
        v if name[0] == "k" else 0.0
        for name, v in zip(DISTORTION_MODELS[model], coeffs, strict=False)
    ]
    points = np.stack([r, np.zeros_like(r), np.ones_like(r)], axis=-1)
    return project(points, np.eye(3), model, np.asarray(radial, float))[..., 0]


def monotone_radius(model: str, coeffs: np.ndarray) -> tuple[float, float]:
    """How far out a model's radial distortion is a lens: it must grow with the radius.

    Returns the normalised radius ``r`` at which the distorted radius
    (:func:`distorted_radius`) first stops growing (a fold, or a pole of a rational model's
    denominator), and the distorted radius reached there; ``(inf, inf)`` where it grows up to
    :data:`MAX_NORMALISED_RADIUS`. Inside it every pixel has one ray; past it pixels have
    several or none, and neither OpenCV's undistortion nor a render through the model means
    anything there (a calibration's polynomial fitted on points that reach only part of the
    image can fold inside it).
    """
    r = np.linspace(0.0, MAX_NORMALISED_RADIUS, RADIUS_SAMPLES)
    rd = distorted_radius(r, model, coeffs)
    bad = ~np.isfinite(rd[1:]) | (np.diff(rd) <= 0)
    if not bad.any():
        return float("inf"), float("inf")
    i = int(np.argmax(bad))
    return float(r[i]), float(rd[i])


def fold_in_image(
    matrix: np.ndarray, model: str, coeffs: np.ndarray, width: int, height: int
) -> tuple[float, float] | None:
    """Whether a model's radial distortion folds inside the image, and where (px).

    Returns ``(fold, corner)``: the distorted radius at which the model stops being a lens
    (:func:`monotone_radius`) and that of the image's farthest corner pixel, both in px from
    the principal point (distorted normalised radius times the mean focal length); None where
    the fold lies beyond every corner.
    """
    _, fold = monotone_radius(model, coeffs)
    fx, fy, cx, cy = matrix[0, 0], matrix[1, 1], matrix[0, 2], matrix[1, 2]
    corners = np.array(
        [[0.0, 0.0], [width - 1.0, 0.0], [0.0, height - 1.0], [width - 1.0, height - 1.0]]
    )
    corner = float(np.max(np.hypot((corners[:, 0] - cx) / fx, (corners[:, 1] - cy) / fy)))
    if fold >= corner:
        return None
    focal = 0.5 * (fx + fy)
    return fold * focal, corner * focal


def tilt_matrix(tau_x: float, tau_y: float) -> np.ndarray:
    """OpenCV's sensor-tilt projection (3x3) for tilts about x and y (rad).

    ``cv::detail::computeTiltProjectionMatrix``: ``R = Ry(tau_y) Rx(tau_x)`` and
    ``T = [[R22, 0, -R02], [0, R22, -R12], [0, 0, 1]] R``; distorted normalised coordinates
    ``(x', y', 1)`` map to ``T (x', y', 1)``, divided by its third component.
    """
    cx, sx, cy, sy = np.cos(tau_x), np.sin(tau_x), np.cos(tau_y), np.sin(tau_y)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]])
    ry = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
    r = ry @ rx
    proj = np.array([[r[2, 2], 0.0, -r[0, 2]], [0.0, r[2, 2], -r[1, 2]], [0.0, 0.0, 1.0]])
    return proj @ r


__all__ = [
    "COEFF_BOUNDS",
    "DISTORTION_MODELS",
    "MAX_NORMALISED_RADIUS",
    "MODEL_OF_COUNT",
    "RATIONAL_MODELS",
    "UNDISTORT_CRITERIA",
    "coefficient_bound",
    "distorted_radius",
    "fold_in_image",
    "is_fisheye",
    "monotone_radius",
    "normalise",
    "project",
    "tilt_matrix",
]
