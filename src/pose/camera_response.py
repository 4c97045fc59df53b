"""A camera's response curve, measured from an exposure bracket: its pipeline's levels undone.

A camera's file holds ``DN = f(exposure)``: the sensor's linear exposure through the camera's own
black level, encoding and tone curve (:mod:`simgap.effects.camera_pipeline`). The diagnosis cannot
read ``f`` from a capture of the fixture: its levels are a tag's ink and paper, whose reflectances,
lights and exposure are unknown too, and a darker print, a black level and a steeper tone curve
move them alike (docs/results/design_evidence.md#camera_response). A lab measures ``f`` once per
camera and setting, the field's way: photographs of any still scene at several exposure times
(an exposure bracket) give the response up to a scale, by Debevec & Malik's estimation
(OpenCV's ``CalibrateDebevec``; Robertson's, ``CalibrateRobertson``, returned no finite code
on one of two synthetic brackets through a drawn camera). The simulation then images through it
(:class:`simgap.effects.camera_pipeline.CameraResponse`).

Convention: :attr:`CameraResponse.linear` is the relative exposure per 8-bit code (256 values,
non-decreasing), scaled so that code 255 is full scale: the camera saturates where the
simulation's full scale does, and a capture's exposure relative to the simulation stays the
exposure finding's to read. The estimate of the codes next to saturation is biased by the
clipped pixels beside them, and so is the estimate of the darkest codes by the crushed pixels
(measured on synthetic brackets through a known curve: the exposure of the codes from about 245
up read up to 1.25 times too high, of those below 10 down to a third of the truth under a black
level), so the codes beyond :data:`RELIABLE_BOTTOM` and :data:`RELIABLE_TOP` are extrapolated
from those inside (tests/test_camera_response.py).

References
----------
Debevec & Malik, "Recovering high dynamic range radiance maps from photographs", SIGGRAPH 1997.
ISO 14524:2009, Photography -- Electronic still-picture cameras -- Methods for measuring
opto-electronic conversion functions (OECFs).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from simgap.pose.image_stats import linearise

#: 8-bit codes.
CODES = 256
#: The darkest and the brightest code whose estimated exposure is kept (module doc); the codes
#: beyond them follow the slope of the :data:`SLOPE_CODES` inside.
RELIABLE_BOTTOM = 16
RELIABLE_TOP = 240
SLOPE_CODES = 10
#: Fewest photos of a bracket: two exposures give one ratio per pixel, three check each other.
MIN_PHOTOS = 3
#: Least ratio of exposure between :data:`RELIABLE_TOP` and :data:`RELIABLE_BOTTOM` a response
#: must show: a real camera's codes 16 and 240 lie about 5 stops apart (sRGB: 2.0 % and 87 % of
#: full scale, a factor 43); a bracket of a flat field or of one photo's range estimates none.
MIN_RANGE = 4.0


#: What a response's values must be (:func:`is_response`).
RESPONSE_VALUES = f"{CODES} non-decreasing numbers from 0 or more to 1"


def is_response(values: Sequence[float] | np.ndarray) -> bool:
    """Whether ``values`` are a response: :data:`RESPONSE_VALUES` (1 within 1e-6 at code 255)."""
    v = np.asarray(values, float)
    return (
        v.shape == (CODES,)
        and bool(np.isfinite(v).all())
        and v[0] >= 0.0
        and abs(v[-1] - 1.0) <= 1e-6
        and bool(np.all(np.diff(v) >= 0))
    )


@dataclass(frozen=True)
class CameraResponse:
    """A camera's response: relative linear exposure per 8-bit code.

    Attributes
    ----------
    linear : ndarray (256,)
        Exposure (fraction of the simulation's full scale) at each code 0-255, non-decreasing,
        1 at code 255 (module doc).
    """

    linear: np.ndarray

    def __post_init__(self) -> None:
        if not is_response(self.linear):
            raise ValueError(f"response: expected {RESPONSE_VALUES}")
        object.__setattr__(self, "linear", np.asarray(self.linear, float))

    def encode(self, linear: np.ndarray) -> np.ndarray:
        """The camera's code (float, 0-255) of linear exposures (fraction of full scale).

        The inverse of :attr:`linear` by linear interpolation between codes; below code 0's
        exposure 0, above code 255's 255 (the camera clips); an exposure that several codes
        share, the first of them.
        """
        codes = np.arange(CODES, dtype=float)
        x = np.asarray(linear, float)
        # a flat run of the response (codes of one exposure) maps to its first code: np.interp
        # needs strictly increasing x-values
        keep = np.concatenate([[True], np.diff(self.linear) > 0])
        return np.interp(x, self.linear[keep], codes[keep], left=0.0, right=float(CODES - 1))

    def lut_from_srgb(self) -> np.ndarray:
        """A lookup table (256,) uint8 from the simulation's sRGB code to the camera's code."""
        return np.round(self.encode(linearise(np.arange(CODES)))).astype(np.uint8)


def scaled(raw: np.ndarray) -> CameraResponse:
    """A response from relative exposures per code (any scale), made monotone and scaled.

    ``raw`` (256,): as an estimation returns it, NaN at codes no photo delivered (interpolated
    from their neighbours). Each code takes at least the exposure of the code below (an
    estimation's noise at the ends of the range, where few pixels fall), the codes beyond
    :data:`RELIABLE_BOTTOM` and :data:`RELIABLE_TOP` are extrapolated (no lower than 0), and
    the whole is scaled to 1 at code 255 (module doc).
    """
    values = np.asarray(raw, float)
    seen = np.isfinite(values)
    if seen.sum() < 2:
        raise ValueError("response: fewer than two codes estimated")
    # codes no photo delivered (a steep tone curve skips some) lie between their neighbours
    codes = np.arange(CODES)
    values = np.interp(codes, codes[seen], values[seen])
    values = np.maximum.accumulate(np.clip(values, 0.0, None))
    top, bottom = RELIABLE_TOP, RELIABLE_BOTTOM
    if not values[top] >= MIN_RANGE * values[bottom]:
        raise ValueError(
            f"response: codes {bottom}-{top} span less than a factor {MIN_RANGE:g} of exposure "
            "(expected a bracket of one still scene whose photos reach from dark to bright)"
        )
    slope = (values[top] - values[top - SLOPE_CODES]) / SLOPE_CODES
    values[top + 1 :] = values[top] + slope * np.arange(1, CODES - top)
    # below the darkest kept code: the estimate where it lies above the line through the codes
    # above (a camera without a black level keeps its dark codes), the line where the estimate
    # falls under it (crushed pixels pull a black level's codes down)
    slope = (values[bottom + SLOPE_CODES] - values[bottom]) / SLOPE_CODES
    line = values[bottom] - slope * np.arange(bottom, 0, -1)
    values[:bottom] = np.maximum(values[:bottom], np.clip(line, 0.0, None))
    values = np.maximum.accumulate(values)
    return CameraResponse(values / values[-1])


def estimate_response(photos: Sequence[np.ndarray], exposure_s: Sequence[float]) -> CameraResponse:
    """The response of the camera that took ``photos`` at ``exposure_s``: Debevec's estimate.

    Parameters
    ----------
    photos : sequence of ndarray (H, W) or (H, W, 3), uint8
        One still scene, same size, taken at each exposure time (grey or RGB).
    exposure_s : sequence of float
        Each photo's exposure time (s; only their ratios matter), all different and positive.

    Returns
    -------
    CameraResponse
        Grey response: the mean over the colour channels of OpenCV's estimate, scaled
        (:func:`scaled`).

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_PHOTOS` photos, photos of different sizes or not 8-bit, or
        exposure times that are not positive and distinct.
    """
    if len(photos) < MIN_PHOTOS or len(photos) != len(exposure_s):
        raise ValueError(f"expected at least {MIN_PHOTOS} photos, each with its exposure time")
    times = np.asarray(exposure_s, np.float32)
    if not (times > 0).all() or len(np.unique(times)) != len(times):
        raise ValueError("exposure times: expected positive values, all different")
    images = [np.asarray(p) for p in photos]
    if any(p.dtype != np.uint8 for p in images) or len({p.shape for p in images}) != 1:
        raise ValueError("photos: expected 8-bit images of one size")
    images = [p if p.ndim == 3 else cv2.cvtColor(p, cv2.COLOR_GRAY2BGR) for p in images]
    response = cv2.createCalibrateDebevec().process(images, times)  # (256, 1, 3)
    return scaled(np.asarray(response, float).reshape(CODES, 3).mean(axis=1))


__all__ = [
    "CODES",
    "MIN_PHOTOS",
    "RELIABLE_BOTTOM",
    "RELIABLE_TOP",
    "RESPONSE_VALUES",
    "CameraResponse",
    "estimate_response",
    "is_response",
    "scaled",
]
