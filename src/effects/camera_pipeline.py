"""A real camera's own image pipeline (ISP): the stages between its sensor and the file.

Every real photo passes through them, and each leaves a signature in the image statistics
(:mod:`simgap.pose.image_stats`) and moves the detected corners:

=====================  =====  ======================================  ==============================
effect                 order  what the camera does                    signature
=====================  =====  ======================================  ==============================
``edge_offset``        15     the pipeline's net shift of the edges   the markers' size change: the
                              between dark and light (see below)      same px at every size
``auto_exposure``      29     meters the scene, sets exposure / gain  paper and ink levels; the
                                                                      chosen EV per frame
``gain_change``        31     exposure / gain that changes per frame  ``repeat_gain_ev``
``black_level``        42     subtracts a black level, crushing       ``black_clipped_fraction``,
                              the shadows to 0                        lower ``ink_linear``
``bayer``              44     colour filter array + demosaicing       ``colour_fringe_dn``
``camera_response``    52     a measured response instead of sRGB     every level (what a tone
                              (exposure bracket, ISO 14524 OECF)      curve and black level do)
``denoise``            55     spatial edge-preserving denoising       lower noise, edges kept
``tone_curve``         56     an S-shaped output LUT (not sRGB)       ink and paper levels, contrast
``sharpen``            60     unsharp mask                            ``edge_overshoot``
=====================  =====  ======================================  ==============================

Stages below :data:`~simgap.effects.image.ENCODE_ORDER` act on linear float RGB (relative to
full scale), those above it on the encoded 8-bit frame, as a camera's ISP does: black level and
demosaicing on raw data, denoising, the tone curve and sharpening on the encoded image, JPEG
last. ``edge_offset`` is no stage of its own but what the stages together do to a soft edge: a
tone curve, a black level or demosaicing move the point where a blurred dark-to-light edge
reads as an edge, by about the same pixels on every marker whatever its size (a print or a
focal length changes the size by a share instead). It is the diagnosis's model of the
pipeline's net effect on the corners (:mod:`simgap.analysis.candidates`), fitted where the
stages themselves are not. Temporal denoising (frames blended over time) is not modelled:
simgap renders each frame independently.

References
----------
Ramanath, Snyder, Yoo & Drew, "Color image processing pipeline", IEEE Signal Processing
Magazine 22(1), 2005 (the stage order). Tomasi & Manduchi, "Bilateral filtering for gray and
color images", ICCV 1998. ImageMagick's ``-sigmoidal-contrast`` (the tone curve's form).
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import cv2
import numpy as np
from numpy.typing import ArrayLike

from simgap.effects.base import EffectParams, param
from simgap.effects.image import METER_STRIDE_PX, ImageContext, ImageEffect
from simgap.effects.state import VariantState
from simgap.pose import camera_response, cfa
from simgap.scene.lights import BT709_LUMINANCE

#: Raw code of linear 0 in the 16-bit frame handed to OpenCV's demosaicing, as a fraction of
#: full scale: a sensor's own pedestal, so that read noise below black survives demosaicing.
RAW_PEDESTAL = 1.0 / 16.0
#: 16-bit full scale of that frame.
RAW_FULL_SCALE = 65535.0


#: Weight of the centre-weighted meter: a Gaussian over the frame of this standard deviation,
#: relative to the half-diagonal (0.5: the centre counts about 7x the corners, as a camera's
#: centre-weighted average meter that gives the middle most of the weight).
CENTRE_WEIGHT_SIGMA = 0.5


class AutoExposure(ImageEffect, name="auto_exposure", order=29):
    """The camera meters the scene and sets its exposure so that the metered level is a target.

    The metered value is the mean linear luminance (BT.709, relative to full scale at the
    pipeline's base exposure ``image.exposure``) over: ``tags``, the crop around the stickers
    (a camera's region-of-interest metering, the RealSense AE ROI, set to where the tags are
    expected); ``frame``, the whole frame (every :data:`METER_STRIDE_PX` px of it); ``centre``,
    the whole frame weighted by a Gaussian about the principal point
    (:data:`CENTRE_WEIGHT_SIGMA`). The camera then multiplies the signal by
    ``2 ** ev`` with ``ev = log2(target / metered)`` limited to ``[ev_min, ev_max]`` (its
    shortest and longest exposure times and its gain, in stops from the base exposure), so
    that clipped paper or drowned ink follow from the light whenever the limits bind. The
    chosen ``ev`` is recorded per frame (``auto_exposure_ev`` in the dataset). A black frame
    meters 0 and takes ``ev_max``. A manual ``exposure`` after it is exposure compensation;
    noise follows the signal as before (the gain's amplified read noise is not modelled).
    """

    class Params(EffectParams):
        """Metering mode, target level and exposure limits."""

        metering: Literal["tags", "frame", "centre"] = "tags"
        target: float = param(0.18, "0 < target < 1 (linear, of full scale)", lambda v: 0 < v < 1)
        ev_min: float = param(-20.0, "-30..0 EV", lambda v: -30 <= v <= 0)
        ev_max: float = param(4.0, "0..20 EV", lambda v: 0 <= v <= 20)

    def meters_frame(self) -> bool:
        """Whether it meters the whole frame (``frame``, ``centre``)."""
        return self.params.metering != "tags"

    def metered(self, img: np.ndarray, ctx: ImageContext) -> float:
        """The metered mean luminance (linear, relative to full scale)."""
        lum = np.asarray(BT709_LUMINANCE, np.float32)
        mode = self.params.metering
        if mode == "tags" or ctx.meter is None:
            return float(np.mean(img[..., :3] @ lum))
        grid = np.asarray(ctx.meter, np.float32) @ lum
        if mode == "frame":
            return float(np.mean(grid))
        rows, cols = np.indices(grid.shape) * METER_STRIDE_PX + METER_STRIDE_PX // 2
        cam = ctx.camera
        half_diagonal2 = 0.25 * (cam.width**2 + cam.height**2)
        r2 = ((cols - cam.cx) ** 2 + (rows - cam.cy) ** 2) / half_diagonal2
        weight = np.exp(-0.5 * r2 / CENTRE_WEIGHT_SIGMA**2)
        return float(np.sum(weight * grid) / np.sum(weight))

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Scale the frame to the target, within the limits; record the EV chosen."""
        p = self.params
        level = self.metered(img, ctx)
        ev = p.ev_max if level <= 0 else float(np.log2(p.target / level))
        ev = float(np.clip(ev, p.ev_min, p.ev_max))
        ctx.record["auto_exposure_ev"] = ev
        return img * np.float32(2.0**ev)


#: Standard deviation of the Gaussian the luminance is smoothed with before its gradient gives
#: :class:`EdgeOffset` the direction across an edge (px): the Sobel kernel's own scale, so that
#: the direction follows the edge, not the render's pixel noise.
EDGE_DIRECTION_SIGMA_PX = 1.0
#: Smallest squared length of the mean of nearby unit normals :class:`EdgeOffset` divides by:
#: that of a corner of 60 deg, ``(1 - cos 60 deg) / 2`` (a marker's corners seen obliquely
#: stay wider), so that where opposite edges meet (a thin stroke) the shift stays bounded.
MIN_CORNER_NORMAL2 = 0.25


class EdgeOffset(ImageEffect, name="edge_offset", order=15):
    """Every edge between dark and light moved by ``offset_px`` towards the light side.

    Each pixel takes the value found back along the directions in which the luminance rises
    (the unit normals of the edges within :data:`EDGE_DIRECTION_SIGMA_PX`, weighted by their
    gradient, averaged to ``m``), ``offset_px m / |m|^2`` away, read bilinearly: a straight
    edge moves by exactly ``offset_px`` along its normal and keeps its profile, so a dark
    marker on light paper grows by ``offset_px`` on every side (a negative offset shrinks it),
    and a corner moves to where its two moved sides meet, kept sharp. Flat regions keep their
    values (a render's own noise there is resampled; the camera's noise comes after). The
    detector's corners follow by a response of their own (a marker's inner edges
    move too; :mod:`simgap.analysis.candidates._edge_offset`). Applied on the soft linear image,
    after the optics.
    """

    class Params(EffectParams):
        """The edges' shift."""

        offset_px: float = param(0.3, "-3 < offset < 3 px", lambda v: -3 < v < 3)

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Resample every pixel ``offset_px`` back across its edges (bilinear)."""
        lum = np.ascontiguousarray(img.astype(np.float32) @ np.float32(BT709_LUMINANCE))
        lum = cv2.GaussianBlur(lum, (0, 0), EDGE_DIRECTION_SIGMA_PX, borderType=cv2.BORDER_REFLECT)
        gx = cv2.Sobel(lum, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT)
        gy = cv2.Sobel(lum, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT)
        # the edge-weighted mean of the unit normals nearby: one normal n on a side, the mean of
        # the two sides' normals m at a corner, where d m / |m|^2 is where the moved sides meet
        # (n_a . v = n_b . v = d)
        weight = np.sqrt(gx * gx + gy * gy)
        total = cv2.GaussianBlur(weight, (0, 0), EDGE_DIRECTION_SIGMA_PX) + np.float32(1e-12)
        mx = cv2.GaussianBlur(gx, (0, 0), EDGE_DIRECTION_SIGMA_PX) / total
        my = cv2.GaussianBlur(gy, (0, 0), EDGE_DIRECTION_SIGMA_PX) / total
        length2 = np.maximum(mx * mx + my * my, np.float32(MIN_CORNER_NORMAL2))
        step = np.float32(self.params.offset_px) / length2
        ys, xs = np.indices(lum.shape, dtype=np.float32)
        return cv2.remap(
            img.astype(np.float32),
            xs - mx * step,
            ys - my * step,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REFLECT,
        )

    def reach_px(self) -> float:
        """The shift, the direction's smoothing and the bilinear pixel (px)."""
        return abs(self.params.offset_px) + 3.0 * EDGE_DIRECTION_SIGMA_PX + 2.0


class GainChange(ImageEffect, name="gain_change", order=31):
    """Exposure or gain that changes from frame to frame (auto exposure hunting, flicker).

    Each frame's linear signal is multiplied by ``2 ** e`` with ``e`` drawn from a normal
    distribution of standard deviation ``sigma_ev`` (EV, stops): two frames of one pose differ
    in level (``repeat_gain_ev``) while each frame's own noise is unchanged.
    """

    stochastic = True

    class Params(EffectParams):
        """Frame-to-frame spread of the exposure."""

        sigma_ev: float = param(0.1, "0 < sigma < 2 EV", lambda v: 0 < v < 2)

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Scale the frame by its drawn gain."""
        return img * np.float32(2.0 ** ctx.rng.normal(0.0, self.params.sigma_ev))


class BlackLevel(ImageEffect, name="black_level", order=42):
    """A black level subtracted beyond the sensor's own: the shadows crushed to 0.

    ``out = max(x - level, 0) / (1 - level)`` on linear values (fraction of full scale): a
    camera whose black-level correction takes more than the sensor's offset, or a contrast
    setting that clips the shadows. Dark ink whose level (with its noise) lies below ``level``
    reads 0 DN; the rest is stretched to keep white at full scale.
    """

    class Params(EffectParams):
        """The subtracted level."""

        level: float = param(
            0.02, "0 < level < 0.5 (fraction of full scale)", lambda v: 0 < v < 0.5
        )

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Subtract, clip at 0 and restore full scale (:func:`crushed`, in float32)."""
        return crushed(img, np.float32(self.params.level))


def crushed(values: ArrayLike, level: float, floor: float = 0.0) -> np.ndarray:
    """Linear values (fraction of full scale) through a black level (:class:`BlackLevel`).

    ``max(v - level, floor) / (1 - level)``: the camera's clips at 0 (``floor`` 0); a model
    that takes logs of the result keeps a crushed level finite with a small ``floor``. Monotone,
    so a median of pixels commutes with it; a float32 ``level`` keeps float32 values float32.
    """
    return np.maximum(np.asarray(values) - level, floor) / (1.0 - level)


class Bayer(ImageEffect, name="bayer", order=44):
    """A Bayer colour filter array and the camera's demosaicing.

    Each photosite keeps only the channel of its filter (``pattern``: the 2 x 2 tile at the
    frame's top-left pixel), then the camera interpolates the missing two per pixel
    (``method``: ``bilinear`` or OpenCV's ``edge_aware``). On an achromatic edge the
    interpolated channels disagree, which leaves colour fringes (``colour_fringe_dn``) and moves
    the grey frame's edges by a fraction of a pixel. The crop offsets are even
    (:data:`~simgap.effects.image.BLOCK_ALIGN_PX`), so a crop sees the full frame's pattern.
    """

    class Params(EffectParams):
        """Filter layout and interpolation."""

        pattern: Literal["RGGB", "BGGR", "GRBG", "GBRG"] = "RGGB"
        method: Literal["bilinear", "edge_aware"] = "bilinear"

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Mosaic the linear frame on a 16-bit raw scale, demosaic, return linear RGB."""
        raw = np.clip(
            np.round(
                (img + np.float32(RAW_PEDESTAL)) * np.float32(RAW_FULL_SCALE / (1 + RAW_PEDESTAL))
            ),
            0,
            RAW_FULL_SCALE,
        ).astype(np.uint16)
        rgb = cfa.demosaic(
            cfa.mosaic(raw, self.params.pattern), self.params.pattern, self.params.method
        )
        scale = np.float32((1 + RAW_PEDESTAL) / RAW_FULL_SCALE)
        return rgb.astype(np.float32) * scale - np.float32(RAW_PEDESTAL)

    def reach_px(self) -> float:
        """The interpolation's neighbourhood: two pixels (px)."""
        return 2.0


def _to_uint8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


class Denoise(ImageEffect, name="denoise", order=55):
    """Spatial, edge-preserving denoising of the encoded frame (a bilateral filter).

    Pixels are averaged with neighbours within about ``radius_px`` (the spatial kernel's
    standard deviation) whose values differ by less than about ``strength_dn`` (the range
    kernel's, 8-bit DN): flat ink and paper become smoother, an edge's steps are kept, so the
    edge widens by much less than the radius.
    """

    class Params(EffectParams):
        """Range and spatial kernels."""

        strength_dn: float = param(8.0, "0 < strength <= 100 DN", lambda v: 0 < v <= 100)
        radius_px: float = param(1.0, "0.3 <= radius <= 5 px", lambda v: 0.3 <= v <= 5)

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Bilateral filter (OpenCV; neighbourhood from the spatial kernel)."""
        out = cv2.bilateralFilter(
            img.astype(np.float32),
            0,
            self.params.strength_dn,
            self.params.radius_px,
            borderType=cv2.BORDER_REFLECT,
        )
        return _to_uint8(out)

    def reach_px(self) -> float:
        """OpenCV's neighbourhood radius for the spatial kernel (1.5 of its sigmas, px)."""
        return float(np.ceil(1.5 * self.params.radius_px))


class ToneCurve(ImageEffect, name="tone_curve", order=56):
    """A camera's S-shaped output curve (LUT) on the encoded frame, instead of plain sRGB.

    ``y = (S(c (x - m)) - S(-c m)) / (S(c (1 - m)) - S(-c m))`` on the encoded value ``x`` in
    [0, 1], with ``S`` the logistic function, ``c = contrast`` its slope and ``m = midpoint``:
    black and white stay, mid-tones gain contrast (darker shadows, brighter highlights); small
    ``contrast`` tends to the identity.
    """

    class Params(EffectParams):
        """Slope and midpoint of the curve."""

        contrast: float = param(4.0, "0 < contrast <= 20", lambda v: 0 < v <= 20)
        midpoint: float = param(0.5, "0 < midpoint < 1", lambda v: 0 < v < 1)

    def curve(self, encoded: np.ndarray | float) -> np.ndarray:
        """The curve on encoded values in [0, 1] (float in, float out)."""
        c, m = self.params.contrast, self.params.midpoint

        def s(t: np.ndarray | float) -> np.ndarray:
            return 1.0 / (1.0 + np.exp(-np.asarray(t, float)))

        return (s(c * (np.asarray(encoded, float) - m)) - s(-c * m)) / (s(c * (1 - m)) - s(-c * m))

    def lut(self) -> np.ndarray:
        """The curve as an 8-bit lookup table (256,)."""
        return _to_uint8(255.0 * self.curve(np.arange(256) / 255.0))

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Look every value up."""
        return cv2.LUT(img, self.lut())


class CameraResponse(ImageEffect, name="camera_response", order=52):
    """A camera's measured response curve in place of the simulation's sRGB encoding.

    ``linear_at_dn`` is the relative exposure (fraction of full scale) at each 8-bit code 0-255,
    non-decreasing, 1 at code 255 (:class:`simgap.pose.camera_response.CameraResponse`, measured
    from an exposure bracket by ``simgap camera-response``). The encoded frame is looked up from
    the simulation's sRGB code to the camera's: every level, and with them the point where a
    soft edge reads as an edge, as the camera's own black level, encoding and tone curve
    deliver them. The estimator then reads the levels through the same response, as it reads
    the capture's (:func:`simgap.pose.image_stats.linearised`).
    """

    class Params(EffectParams):
        """The measured response."""

        linear_at_dn: tuple[float, ...] = param(
            tuple(float(v) for v in np.linspace(0.0, 1.0, camera_response.CODES)),
            f"{camera_response.RESPONSE_VALUES} (fraction of full scale)",
            camera_response.is_response,
        )

    def apply(self, state: VariantState) -> VariantState:
        """Append the lookup to an sRGB-encoding pipeline; the estimator reads through it too.

        The simulation's levels are then read as the capture's are
        (:attr:`simgap.pose.tags.Estimation.response`).
        """
        state = super().apply(state)
        # the lookup starts from the sRGB codes (another encoding would be looked up as if sRGB)
        image = dataclasses.replace(state.image, encoding="srgb")
        estimation = dataclasses.replace(state.estimation, response=self.params.linear_at_dn)
        return dataclasses.replace(state, image=image, estimation=estimation)

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Look every code up (:meth:`simgap.pose.camera_response.CameraResponse.lut_from_srgb`)."""
        response = camera_response.CameraResponse(np.asarray(self.params.linear_at_dn, float))
        return cv2.LUT(img, response.lut_from_srgb())


class Sharpen(ImageEffect, name="sharpen", order=60):
    """Sharpening of the encoded frame by an unsharp mask.

    ``out = x + amount (x - G_radius * x)`` where the difference exceeds ``threshold_dn``
    (8-bit DN), ``G_radius`` a Gaussian of standard deviation ``radius_px``: edges gain a dark
    and a bright halo (``edge_overshoot``), noise is amplified. A camera's "sharpness" setting.
    """

    class Params(EffectParams):
        """Strength, width and threshold of the mask."""

        amount: float = param(0.8, "0 < amount <= 5", lambda v: 0 < v <= 5)
        radius_px: float = param(1.0, "0.3 <= radius <= 5 px", lambda v: 0.3 <= v <= 5)
        threshold_dn: float = param(0.0, "0 <= threshold < 64 DN", lambda v: 0 <= v < 64)

    def process(self, img: np.ndarray, ctx: ImageContext) -> np.ndarray:
        """Add the amplified difference from the blurred frame."""
        x = img.astype(np.float32)
        detail = x - cv2.GaussianBlur(
            x, (0, 0), self.params.radius_px, borderType=cv2.BORDER_REFLECT
        )
        if self.params.threshold_dn > 0:
            detail[np.abs(detail) <= self.params.threshold_dn] = 0.0
        return _to_uint8(x + np.float32(self.params.amount) * detail)

    def reach_px(self) -> float:
        """Three sigmas of the mask's blur (px)."""
        return 3.0 * self.params.radius_px


__all__ = [
    "Bayer",
    "BlackLevel",
    "Denoise",
    "EdgeOffset",
    "GainChange",
    "Sharpen",
    "ToneCurve",
    "crushed",
]
