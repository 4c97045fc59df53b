"""Whether a corner gap is a change of size in proportion to the tag's image size.

A print scale (``tag_scale``) makes every tag larger or smaller by the same share: the distance of
its corners from the tag's centre changes by ``scale x size`` (px), nothing at zero size. An image
effect the model lacks or models with another shape (a motion blur, a pixel filter other than the
simulation's, a defocus read as a Gaussian blur) moves the detected corners of a dark square by an
edge offset of about the same pixels on every tag, whatever its size. Both change the apparent
size, and a fitted print scale follows either; only the first grows with the size. The test
regresses the per-tag size change on the size, with an intercept (the offset), and asks for a
slope that stands out of its standard error, and for an offset that does not cancel it on the
smallest tags (a defocus, whose edge offset changes with depth and so with size, gives a
significant slope with a large offset of the other sign).

Measured on development captures: true print scales give slopes many standard errors out that
reach zero change well inside the smallest tag's size; look-alikes (a motion blur, a JPEG, sensor
noise beside a distortion, a principal point) give slopes within a few standard errors, and a
defocus crosses zero near or inside the sizes measured (the thresholds:
:data:`~simgap.analysis.thresholds.SIZE_SLOPE_Z`,
:data:`~simgap.analysis.thresholds.SIZE_ZERO_SHARE`; the measurements:
docs/results/design_evidence.md#size_signature).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class SizeChange:
    """The per-tag size change regressed on the tag's image size.

    Attributes
    ----------
    n : int
        Tags with four finite corners on both sides.
    slope : float
        Size change per px of size (a share: 0.02 is 2 % larger).
    slope_z : float
        ``slope`` over its standard error (nan with fewer than 4 tags or no spread of sizes).
    offset_px : float
        Intercept: the size change at zero size (px), an edge offset.
    offset_z : float
        ``offset_px`` over its standard error (nan as ``slope_z``).
    smallest_px : float
        The smallest tag's size (px).
    """

    n: int
    slope: float
    slope_z: float
    offset_px: float
    offset_z: float
    smallest_px: float

    @property
    def zero_share(self) -> float:
        """Size at which the fitted change is zero, as a share of the smallest tag's size.

        Zero for a pure print scale; negative where the offset has the slope's sign; between
        0 and 1 the offset, against the slope, cancels most of it on the smallest tags; above 1
        the small tags change size one way and the large ones the other, which no print does.
        """
        if not self.slope or not np.isfinite(self.slope):
            return float("nan")
        return -self.offset_px / self.slope / self.smallest_px


def tag_sizes(corners: np.ndarray) -> np.ndarray:
    """Mean distance of a tag's four corners from their centroid (px), per tag (N,)."""
    centre = corners.mean(axis=-2, keepdims=True)
    return np.linalg.norm(corners - centre, axis=-1).mean(axis=-1)


def size_change(real_corners: np.ndarray, predicted_corners: np.ndarray) -> SizeChange:
    """Regress the size change real - predicted (px) on the predicted size (px), per tag.

    Parameters
    ----------
    real_corners, predicted_corners : ndarray (N, 4, 2)
        Detected and predicted corners (px); tags with a non-finite corner are left out.
    """
    ok = np.isfinite(real_corners).all(axis=(1, 2)) & np.isfinite(predicted_corners).all(
        axis=(1, 2)
    )
    size = tag_sizes(predicted_corners[ok])
    change = tag_sizes(real_corners[ok]) - size
    n = int(ok.sum())
    if n < 4 or np.ptp(size) <= 0:
        return SizeChange(n, *[float("nan")] * 5)
    fit = stats.linregress(size, change)
    return SizeChange(
        n,
        float(fit.slope),
        _z(fit.slope, fit.stderr),
        float(fit.intercept),
        _z(fit.intercept, fit.intercept_stderr),
        float(size.min()),
    )


def _z(value: float, stderr: float) -> float:
    """``value`` over its standard error; +-inf for an exact nonzero value, 0 for an exact 0."""
    if stderr > 0:
        return float(value / stderr)
    return float(np.copysign(np.inf, value)) if value else 0.0
