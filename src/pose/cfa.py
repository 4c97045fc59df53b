"""Traces of a Bayer colour filter array in a demosaiced colour frame: its layout and method.

A colour camera samples one channel per photosite and interpolates the other two; every
demosaicing method keeps (or nearly keeps) the sampled values at their own sites. Mosaicking a
demosaiced frame again with its own layout and demosaicing it reproduces it closely; with another
layout the sampled values are thrown away and interpolated ones kept, and it does not. Over the
pixels near edges (where interpolation errs; flat areas tell nothing):

``residual[transfer, layout, method]``
    the mean absolute difference (in the frame's own 8-bit code values) between the frame and
    the frame mosaicked with ``layout`` and demosaicked with ``method`` (OpenCV's bilinear or
    edge-aware) in the linear light of ``transfer``: cameras demosaic linear raw data and then
    apply their own tone response, which is not known (sRGB, a gamma, an S-curve). The code
    values are linearised with each power law of :data:`TRANSFER_GAMMAS` in turn, mosaicked,
    demosaicked and encoded back; the camera's response is the power law that reproduces the
    frame best;
``ratio``
    at that transfer, the best layout's residual over the median of the other three layouts'
    (each at its best method): about 1 for a frame without a colour filter array (a three-chip
    camera, a render), well below 1 for a demosaiced one. The method is the one of simgap's
    catalogue that reproduces the frame best at that layout and transfer (the nearest, where the
    camera used another).

This is the re-interpolation idea of CFA forensics (Popescu & Farid, "Exposing digital forgeries
in color filter array interpolated images", IEEE Trans. Signal Processing 53(10), 2005; Kirchner,
"Efficient estimation of CFA pattern configuration in digital camera images", Proc. SPIE 7541,
2010). The layout is that of the full frame's top-left pixel, so crops must start at even pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from simgap.pose.image_stats import is_grey

#: Layouts of the 2 x 2 tile at the top-left pixel, and the channel each of its four sites keeps.
LAYOUTS = ("RGGB", "BGGR", "GRBG", "GBRG")
#: simgap's demosaicing methods (:class:`simgap.effects.camera_pipeline.Bayer`) and OpenCV's codes.
METHODS = ("bilinear", "edge_aware")
_CODES = {
    ("RGGB", "bilinear"): cv2.COLOR_BayerRGGB2RGB,
    ("BGGR", "bilinear"): cv2.COLOR_BayerBGGR2RGB,
    ("GRBG", "bilinear"): cv2.COLOR_BayerGRBG2RGB,
    ("GBRG", "bilinear"): cv2.COLOR_BayerGBRG2RGB,
    ("RGGB", "edge_aware"): cv2.COLOR_BayerRGGB2RGB_EA,
    ("BGGR", "edge_aware"): cv2.COLOR_BayerBGGR2RGB_EA,
    ("GRBG", "edge_aware"): cv2.COLOR_BayerGRBG2RGB_EA,
    ("GBRG", "edge_aware"): cv2.COLOR_BayerGBRG2RGB_EA,
}
_CHANNEL = {"R": 0, "G": 1, "B": 2}
#: Exponents of the power-law tone responses searched (code value ** gamma = linear level): from
#: linear data to a steep response. With sRGB linearisation alone the method is misread behind a
#: gamma, an S-curve and denoising (tests/test_camera_pipeline.py; docs/results/camera_pipeline.md).
TRANSFER_GAMMAS = (1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5, 3.0)
_CODES_01 = np.arange(256) / 255.0
#: Per transfer: 8-bit code -> linear level on a 16-bit scale.
_TO_LINEAR_16 = [np.round(65535.0 * _CODES_01**g).astype(np.uint16) for g in TRANSFER_GAMMAS]
#: Per transfer: 16-bit linear level -> code value (8-bit units, not rounded).
_TO_CODE = [255.0 * (np.arange(65536) / 65535.0) ** (1.0 / g) for g in TRANSFER_GAMMAS]
#: A pixel is near an edge where its 3 x 3 neighbourhood's green spans at least this (8-bit DN).
EDGE_RANGE_DN = 24
#: Fewest edge pixels for a verdict.
MIN_EDGE_PIXELS = 200
#: Largest ratio (best layout's residual over the others') read as a demosaiced frame. Set on
#: renders of near to far, frontal and oblique tags (tests/test_camera_pipeline.py), measured on
#: validation captures with the tone response searched: demosaiced 0.02-0.43 (43 captures, layout
#: and method right in 43), without a colour filter array 0.97-1.00 (55 captures through noise,
#: blur, sharpening, denoising, JPEG), 0.93 through 1.5 px of lateral colour. JPEG's 4:2:0 chroma
#: subsampling erases the traces (0.92-1.00 on 9 demosaiced, then compressed captures;
#: docs/results/camera_pipeline.md).
DEMOSAICED_RATIO = 0.7


def mosaic(rgb: np.ndarray, layout: str) -> np.ndarray:
    """Keep one channel per pixel as ``layout`` samples it: (H, W, 3) -> (H, W), same dtype."""
    out = np.empty(rgb.shape[:2], rgb.dtype)
    for k, name in enumerate(layout):
        dy, dx = divmod(k, 2)
        out[dy::2, dx::2] = rgb[dy::2, dx::2, _CHANNEL[name]]
    return out


def demosaic(raw: np.ndarray, layout: str, method: str) -> np.ndarray:
    """OpenCV's demosaicing of a mosaic (8- or 16-bit) laid out as ``layout``, to RGB."""
    return cv2.demosaicing(raw, _CODES[(layout, method)])


@dataclass
class CfaTraces:
    """Residuals accumulated over frames (:meth:`add`), and the verdict (:meth:`verdict`).

    Attributes
    ----------
    residual_sum : ndarray (T, 4, 2)
        Per transfer (:data:`TRANSFER_GAMMAS`), layout (:data:`LAYOUTS`) and method
        (:data:`METHODS`), the summed absolute differences (8-bit code values) over the edge
        pixels and channels.
    pixels : int
        Edge pixels summed over.
    """

    residual_sum: np.ndarray = field(
        default_factory=lambda: np.zeros((len(TRANSFER_GAMMAS), len(LAYOUTS), len(METHODS)))
    )
    pixels: int = 0

    def add(self, rgb: np.ndarray, offset: tuple[int, int] = (0, 0)) -> None:
        """Add an 8-bit RGB frame (or a crop of one starting at ``offset``, px) to the residuals.

        Grey frames (all channels equal) carry no trace and are skipped.
        """
        if is_grey(rgb):
            return
        dx, dy = offset[0] % 2, offset[1] % 2
        rgb = rgb[dy:, dx:]  # restart the crop at an even full-frame pixel
        h, w = rgb.shape[0] // 2 * 2, rgb.shape[1] // 2 * 2
        rgb = np.ascontiguousarray(rgb[:h, :w])
        green = rgb[..., 1]
        kernel = np.ones((3, 3), np.uint8)
        span = cv2.dilate(green, kernel).astype(np.int16) - cv2.erode(green, kernel)
        edge = span >= EDGE_RANGE_DN
        edge[:2], edge[-2:], edge[:, :2], edge[:, -2:] = False, False, False, False
        n = int(edge.sum())
        if n == 0:
            return
        # cameras demosaic raw (linear) data, then apply their tone response: undo each
        # candidate response on a 16-bit scale, re-mosaic, demosaic, encode back
        values = rgb[edge].astype(np.float64)
        for t, (to_linear, to_code) in enumerate(zip(_TO_LINEAR_16, _TO_CODE, strict=True)):
            linear = to_linear[rgb]
            for i, layout in enumerate(LAYOUTS):
                raw = mosaic(linear, layout)
                for j, method in enumerate(METHODS):
                    again = to_code[demosaic(raw, layout, method)[edge]]
                    self.residual_sum[t, i, j] += float(np.abs(again - values).sum())
        self.pixels += n

    def residuals(self) -> np.ndarray:
        """Mean absolute residual per transfer, layout and method (code values), (T, 4, 2)."""
        return self.residual_sum / max(3 * self.pixels, 1)

    def verdict(self) -> CfaVerdict:
        """The layout, nearest method and tone response where the frames are demosaiced."""
        if self.pixels < MIN_EDGE_PIXELS:
            return CfaVerdict(None, None, float("nan"), self.pixels)
        res = self.residuals()
        t, best, method = np.unravel_index(int(np.argmin(res)), res.shape)
        per_layout = res[t].min(axis=1)
        others = np.delete(per_layout, best)
        ratio = float(per_layout[best] / max(float(np.median(others)), 1e-9))
        if ratio > DEMOSAICED_RATIO:
            return CfaVerdict(None, None, ratio, self.pixels)
        return CfaVerdict(
            LAYOUTS[best], METHODS[method], ratio, self.pixels, float(TRANSFER_GAMMAS[t])
        )


#: Margin around a frame's detected markers searched for traces (px): the markers' outer edges.
MARKER_MARGIN_PX = 8


def around_markers(
    rgb: np.ndarray, markers: dict[int, np.ndarray]
) -> tuple[np.ndarray, tuple[int, int]]:
    """The crop of a full frame around its detected markers' corners, and its offset (px).

    The crop reaches :data:`MARKER_MARGIN_PX` beyond the corners' bounding box (the edges the
    traces are read from), cut to the frame.
    """
    pts = np.concatenate([np.asarray(c, np.float64).reshape(-1, 2) for c in markers.values()])
    x0, y0 = np.maximum(np.floor(pts.min(axis=0) - MARKER_MARGIN_PX), 0).astype(int)
    x1, y1 = np.ceil(pts.max(axis=0) + MARKER_MARGIN_PX).astype(int) + 1
    return rgb[y0:y1, x0:x1], (int(x0), int(y0))


@dataclass(frozen=True)
class CfaVerdict:
    """Whether frames were demosaiced: layout, nearest method, the evidence.

    Attributes
    ----------
    layout : str or None
        The colour filter layout at the frame's top-left pixel (:data:`LAYOUTS`); None where no
        trace was found (or too few edge pixels).
    method : str or None
        The demosaicing method of simgap's catalogue that reproduces the frames best.
    ratio : float
        The best layout's residual over the others' median (NaN without enough edge pixels).
    pixels : int
        Edge pixels the verdict rests on.
    transfer_gamma : float or None
        The power-law tone response (code value ** gamma = linear) in whose linear light the
        frames are reproduced best (:data:`TRANSFER_GAMMAS`); None where no trace was read.
    """

    layout: str | None
    method: str | None
    ratio: float
    pixels: int
    transfer_gamma: float | None = None


__all__ = [
    "CfaTraces",
    "around_markers",
    "CfaVerdict",
    "DEMOSAICED_RATIO",
    "LAYOUTS",
    "METHODS",
    "TRANSFER_GAMMAS",
    "demosaic",
    "mosaic",
]
