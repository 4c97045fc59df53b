"""Traces of a Bayer colour filter array in a demosaiced colour frame: its layout and method.

A colour camera samples one channel per photosite and interpolates the other two; every
demosaicing method keeps (or nearly keeps) the sampled values at their own sites. Mosaicking a
demosaiced frame again with its own layout and demosaicing it reproduces it closely; with another
layout the sampled values are thrown away and interpolated ones kept, and it does not. Over the
pixels near edges (where interpolation errs; flat areas tell nothing):

``residual[layout, method]``
    the mean absolute difference (linear, in units of 1/255 of full scale) between the frame
    and the frame mosaicked with ``layout`` and demosaicked with ``method`` (OpenCV's bilinear or
    edge-aware), both linearised with the sRGB curve (cameras demosaic linear raw data);
``ratio``
    the best layout's residual over the median of the other three layouts' (each at its best
    method): about 1 for a frame without a colour filter array (a three-chip camera, a render),
    well below 1 for a demosaiced one. The method is the one of simgap's catalogue that
    reproduces the frame best at that layout (the nearest, where the camera used another).

This is the re-interpolation idea of CFA forensics (Popescu & Farid, "Exposing digital forgeries
in color filter array interpolated images", IEEE Trans. Signal Processing 53(10), 2005; Kirchner,
"Efficient estimation of CFA pattern configuration in digital camera images", Proc. SPIE 7541,
2010). The layout is that of the full frame's top-left pixel, so crops must start at even pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from simgap.pose.image_stats import is_grey, linearise

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
#: 8-bit sRGB code -> linear level on a 16-bit scale (IEC 61966-2-1), and 16-bit -> 8-bit units.
_SRGB_TO_LINEAR_16 = 65535.0 * linearise(np.arange(256))
_TO_DN = 255.0 / 65535.0
#: A pixel is near an edge where its 3 x 3 neighbourhood's green spans at least this (8-bit DN).
EDGE_RANGE_DN = 24
#: Fewest edge pixels for a verdict.
MIN_EDGE_PIXELS = 200
#: Largest ratio (best layout's residual over the others') read as a demosaiced frame. Measured
#: on renders of near to far, frontal and oblique tags (tests/test_camera_pipeline.py): demosaiced
#: 0.03 (bilinear) to 0.53 (edge-aware, then a 20 DN bilateral denoise and a steep tone curve);
#: without a colour filter array 0.98-1.00 through noise, blur, sharpening, denoising and JPEG.
#: JPEG's 4:2:0 chroma subsampling erases the traces (0.98-1.00 at quality 60 after demosaicing).
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
    residual_sum : ndarray (4, 2)
        Per layout (:data:`LAYOUTS`) and method (:data:`METHODS`), the summed absolute
        differences (DN) over the edge pixels and channels.
    pixels : int
        Edge pixels summed over.
    """

    residual_sum: np.ndarray = field(default_factory=lambda: np.zeros((len(LAYOUTS), len(METHODS))))
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
        # cameras demosaic raw (linear) data: undo the transfer curve first (sRGB, the curve
        # the image evidence assumes), on a 16-bit scale
        linear = np.round(_SRGB_TO_LINEAR_16[rgb]).astype(np.uint16)
        values = linear[edge].astype(np.float64)
        for i, layout in enumerate(LAYOUTS):
            raw = mosaic(linear, layout)
            for j, method in enumerate(METHODS):
                again = demosaic(raw, layout, method)[edge].astype(np.float64)
                self.residual_sum[i, j] += float(np.abs(again - values).sum()) * _TO_DN
        self.pixels += n

    def residuals(self) -> np.ndarray:
        """Mean absolute residual per layout and method (DN per channel), (4, 2)."""
        return self.residual_sum / max(3 * self.pixels, 1)

    def verdict(self) -> CfaVerdict:
        """The layout and nearest method where the frames are demosaiced, else none."""
        if self.pixels < MIN_EDGE_PIXELS:
            return CfaVerdict(None, None, float("nan"), self.pixels)
        res = self.residuals()
        per_layout = res.min(axis=1)
        best = int(np.argmin(per_layout))
        others = np.delete(per_layout, best)
        ratio = float(per_layout[best] / max(float(np.median(others)), 1e-9))
        if ratio > DEMOSAICED_RATIO:
            return CfaVerdict(None, None, ratio, self.pixels)
        return CfaVerdict(LAYOUTS[best], METHODS[int(np.argmin(res[best]))], ratio, self.pixels)


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
    """

    layout: str | None
    method: str | None
    ratio: float
    pixels: int


__all__ = [
    "CfaTraces",
    "around_markers",
    "CfaVerdict",
    "DEMOSAICED_RATIO",
    "LAYOUTS",
    "METHODS",
    "demosaic",
    "mosaic",
]
