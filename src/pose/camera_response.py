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
from those inside (tests/test_camera_response.py). Above the top, the line runs to the exposure
at which the bracket's pixels first read 255 (:func:`saturation_exposure`, each pixel's exposure
from its unbiased codes): a tone curve's shoulder spreads exposures 0.55-0.97 of full scale over
its last 15 codes, and the slope below them put full scale 0.2-0.5 EV low, every exposure that
much high.

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
#: Most pixel values per photo read for the saturation exposure (:func:`saturation_exposure`;
#: every so many of a larger photo): a bracket of a grey ramp has some hundred thousand values
#: per photo, and a 12-megapixel camera's would take gigabytes.
SATURATION_SAMPLES = 2**18
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


def scaled(raw: np.ndarray, saturation: float | None = None) -> CameraResponse:
    """A response from relative exposures per code (any scale), made monotone and scaled.

    ``raw`` (256,): as an estimation returns it, NaN at codes no photo delivered (interpolated
    from their neighbours). Each code takes at least the exposure of the code below (an
    estimation's noise at the ends of the range, where few pixels fall), the codes beyond
    :data:`RELIABLE_BOTTOM` and :data:`RELIABLE_TOP` are extrapolated (no lower than 0), and
    the whole is scaled to 1 at code 255 (module doc). With ``saturation`` (the exposure, on
    ``raw``'s scale, at which the camera first reads 255: :func:`saturation_exposure`) the
    codes above :data:`RELIABLE_TOP` lie instead on the line from that code's exposure to
    ``saturation`` at code 255: a tone curve's shoulder spreads a wide range of exposures over
    its last codes, which the slope below them does not reach.
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
    if saturation is not None and saturation > values[top]:
        slope = (saturation - values[top]) / (CODES - 1 - top)
    values[top + 1 :] = values[top] + slope * np.arange(1, CODES - top)
    # below the darkest kept code: the estimate where it lies above the line through the codes
    # above (a camera without a black level keeps its dark codes), the line where the estimate
    # falls under it (crushed pixels pull a black level's codes down)
    slope = (values[bottom + SLOPE_CODES] - values[bottom]) / SLOPE_CODES
    line = values[bottom] - slope * np.arange(bottom, 0, -1)
    values[:bottom] = np.maximum(values[:bottom], np.clip(line, 0.0, None))
    values = np.maximum.accumulate(values)
    return CameraResponse(values / values[-1])


def saturation_exposure(codes: np.ndarray, exposure_s: np.ndarray, raw: np.ndarray) -> float | None:
    """The exposure at which the camera first reads 255, on the scale of the estimate ``raw``.

    Each pixel's irradiance is the median of ``raw[code] / time`` over its photos whose code lies
    within :data:`RELIABLE_BOTTOM`-:data:`RELIABLE_TOP` (where the estimate is unbiased); its
    exposure in each photo is that irradiance times the photo's time. The saturation exposure is
    the threshold that best splits the exposures of the pixels reading 255 from those reading
    above :data:`RELIABLE_TOP` but less (fewest on the wrong side; the middle of the tie). None
    where the bracket has no pixel on either side.

    Parameters
    ----------
    codes : ndarray (n_photos, n_pixels), uint8
        The bracket's codes, one row a photo.
    exposure_s : ndarray (n_photos,)
        The photos' exposure times (s).
    raw : ndarray (256,)
        Relative exposure per code (any scale; finite between the reliable codes).
    """
    codes = np.asarray(codes)
    times = np.asarray(exposure_s, float)[:, None]
    reliable = (codes >= RELIABLE_BOTTOM) & (codes <= RELIABLE_TOP)
    irradiance = np.where(reliable, raw[codes] / times, np.nan)
    seen = reliable.any(axis=0)
    if not seen.any():
        return None
    per_pixel = np.full(codes.shape[1], np.nan)
    per_pixel[seen] = np.nanmedian(irradiance[:, seen], axis=0)
    exposure = per_pixel[None, :] * times
    ok = np.isfinite(exposure)
    clipped = np.sort(exposure[ok & (codes == CODES - 1)])
    below = np.sort(exposure[ok & (codes > RELIABLE_TOP) & (codes < CODES - 1)])
    if clipped.size == 0 or below.size == 0:
        return None
    # a threshold at each candidate exposure: clipped pixels under it plus unclipped ones at or
    # above it are on the wrong side
    candidates = np.concatenate([clipped, below])
    wrong = np.searchsorted(clipped, candidates, side="left") + (
        below.size - np.searchsorted(below, candidates, side="left")
    )
    best = candidates[wrong == wrong.min()]
    return float(np.sqrt(best.min() * best.max()))


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
    raw = np.asarray(response, float).reshape(CODES, 3).mean(axis=1)
    stride = max(1, images[0].size // SATURATION_SAMPLES)
    codes = np.stack([p.reshape(-1)[::stride] for p in images])
    return scaled(raw, saturation_exposure(codes, times, raw))


__all__ = [
    "CODES",
    "MIN_PHOTOS",
    "RELIABLE_BOTTOM",
    "RELIABLE_TOP",
    "RESPONSE_VALUES",
    "CameraResponse",
    "estimate_response",
    "is_response",
    "saturation_exposure",
    "scaled",
]
