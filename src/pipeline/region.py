"""Which pixels of a configuration are rendered: the facing stickers and a margin around them.

The detector and the image statistics look only at the stickers (the statistics inside them, the
detector's adaptive thresholds up to half their largest window beyond their edges), so only the
pixels within ``margin_px`` of a facing sticker's outline are sampled. They are rendered as a list
(:meth:`simgap.render.scene.FixtureScene.render_pixels`: one kernel for regions of any size and
shape) and placed in their bounding crop; the crop's other pixels take the median of the region's
outermost ring, so that the image stage and the detector see a flat surround instead of edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from simgap.effects.image import BLOCK_ALIGN_PX

#: Points projected along each sticker side, so that the outline follows lens distortion.
OUTLINE_POINTS_PER_SIDE = 8
#: Fixed-point bits of the outline passed to OpenCV's polygon fill (1/16 px).
_SHIFT_BITS = 4


@dataclass(frozen=True)
class Region:
    """The rendered pixels of one configuration, in their crop of the full image.

    Attributes
    ----------
    offset : tuple of int
        Full-image pixel ``(x0, y0)`` of the crop's top-left corner (px; a multiple of
        :data:`simgap.effects.image.BLOCK_ALIGN_PX`).
    mask : ndarray of bool (H, W)
        The crop's pixels that are rendered.
    """

    offset: tuple[int, int]
    mask: np.ndarray

    @property
    def size(self) -> tuple[int, int]:
        """Crop width and height (px)."""
        return self.mask.shape[1], self.mask.shape[0]

    def pixels(self) -> np.ndarray:
        """Full-image columns and rows ``(u, v)`` of the rendered pixels (N, 2), row-major."""
        rows, cols = np.nonzero(self.mask)
        return np.stack([cols + self.offset[0], rows + self.offset[1]], axis=1)

    def crop(self, values: np.ndarray) -> np.ndarray:
        """The crop (H, W, C) with ``values`` (N, C, in :meth:`pixels` order) at the region.

        The crop's other pixels take the per-channel median of the region's outermost ring.
        """
        values = np.asarray(values)
        out = np.empty((*self.mask.shape, values.shape[1]), values.dtype)
        out[self.mask] = values
        outside = ~self.mask
        if outside.any():
            inner = cv2.erode(self.mask.astype(np.uint8), np.ones((3, 3), np.uint8),
                              borderType=cv2.BORDER_CONSTANT, borderValue=0)  # fmt: skip
            ring = self.mask & ~inner.astype(bool)
            out[outside] = np.median(out[ring], axis=0)
        return out


def sticker_region(
    outlines: dict[int, np.ndarray], margin_px: float, image: tuple[int, int]
) -> Region | None:
    """The pixels within ``margin_px`` of a sticker outline, in a block-aligned crop.

    Parameters
    ----------
    outlines : dict of int to ndarray (K, 2)
        Image outlines of the facing stickers (px), e.g.
        :func:`simgap.render.scene.projected_sticker_outlines`.
    margin_px : float
        Distance around each sticker that is rendered too (px).
    image : tuple of int
        Full image width and height (px).

    Returns
    -------
    Region or None
        None when no sticker faces the camera or the region lies outside the image.
    """
    if not outlines:
        return None
    pts = np.concatenate(list(outlines.values()))
    a = BLOCK_ALIGN_PX
    lo = np.floor((pts.min(axis=0) - margin_px) / a).astype(int) * a
    hi = np.ceil((pts.max(axis=0) + margin_px + 1) / a).astype(int) * a
    x0, y0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    x1, y1 = min(int(hi[0]), image[0]), min(int(hi[1]), image[1])
    if x1 <= x0 or y1 <= y0:
        return None
    inside = np.zeros((y1 - y0, x1 - x0), np.uint8)
    scale = 1 << _SHIFT_BITS
    polys = [np.round((uv - (x0, y0)) * scale).astype(np.int32) for uv in outlines.values()]
    cv2.fillPoly(inside, polys, 1, lineType=cv2.LINE_8, shift=_SHIFT_BITS)
    distance = cv2.distanceTransform(1 - inside, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    mask = distance <= margin_px
    return Region((x0, y0), mask) if mask.any() else None
