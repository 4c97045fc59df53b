"""JPEG's 8x8 block grid read back from decoded pixels: the DC quantisation step and its quality.

A JPEG encoder transforms each 8 x 8 block of the luma (BT.601 Y, level-shifted by 128) with the
orthonormal 2-D DCT-II and rounds every coefficient to a multiple of its quantisation step. After
decoding, the DC coefficient of a block (the block's sum / 8 - 1024) still lies on that lattice,
up to the rounding of the decoded 8-bit pixels (about 0.3-0.5 DN in the DC), whatever noise the
camera had before compression: the quantiser acts after it. OpenCV's grey conversion uses the
same BT.601 weights, so the grey frame's blocks are the decoded luma's. This is the quantiser
estimation of Fan and de Queiroz (IEEE Trans. Image Processing 12(2), 2003) on the DC term, with
the lattice's known origin (the level shift) as the phase.

The step maps to a quality through libjpeg's standard luminance table (ITU-T T.81 Annex K, DC
entry 16) scaled as ``jpeg_set_quality`` does: ``5000 / q`` percent below quality 50, ``200 - 2 q``
from 50 (what OpenCV's ``IMWRITE_JPEG_QUALITY`` sets). A camera with its own tables still has a
DC step; its libjpeg quality is then the nearest equivalent.
"""

from __future__ import annotations

import numpy as np

#: Side of a JPEG block (px), aligned with the full frame's top-left pixel.
JPEG_BLOCK_PX = 8
#: DC entry of the standard luminance quantisation table (ITU-T T.81, Table K.1).
STANDARD_DC_STEP = 16
#: Searched DC steps (DN of the orthonormal DC): from 3 (below it the decoded pixels' rounding,
#: about 0.5 DN in the DC, blurs the lattice: quality above about 85) to 80 (quality 10).
DC_STEPS = np.arange(3, 81)
#: A step explains a tag's blocks when the mean of ``cos(2 pi DC / step)`` reaches this. An
#: uncompressed tag of n blocks scores about N(0, 1 / (2 n)) at every step (0.16 for 20 blocks:
#: 0.7 is four sigma); a compressed one scores ``exp(-2 pi^2 (sigma / step)^2)``, 0.92 for a
#: rounding sigma of 0.5 DN at step 8 (quality 75). Synthetic tests: tests/test_image_stats.py.
LATTICE_MIN_SCORE = 0.7
#: Fewest distinct lattice points among a tag's blocks: a flat tag whose blocks share one or two
#: DC values fits every divisor of their values.
LATTICE_MIN_LEVELS = 4
#: Fewest unclipped blocks for an estimate.
MIN_BLOCKS = 12


def dc_step(patch: np.ndarray, x0: int, y0: int) -> float:
    """The DC quantisation step of the full-frame 8 x 8 blocks inside ``patch`` (DN), or NaN.

    Parameters
    ----------
    patch : ndarray (H, W)
        8-bit grey values (any numeric dtype).
    x0, y0 : int
        Full-frame pixel coordinates of ``patch[0, 0]`` (the grid is the full frame's).

    Returns
    -------
    float
        The largest step of :data:`DC_STEPS` on whose lattice the DC coefficients of the whole,
        unclipped blocks lie (:data:`LATTICE_MIN_SCORE`, :data:`LATTICE_MIN_LEVELS`): the largest,
        because every divisor of the true step fits too. NaN where none does (no compression, a
        quality above about 85, or too few blocks).
    """
    patch = np.asarray(patch, np.float64)
    bx, by = (-int(x0)) % JPEG_BLOCK_PX, (-int(y0)) % JPEG_BLOCK_PX
    nx = (patch.shape[1] - bx) // JPEG_BLOCK_PX
    ny = (patch.shape[0] - by) // JPEG_BLOCK_PX
    if nx <= 0 or ny <= 0:
        return float("nan")
    grid = patch[by : by + ny * JPEG_BLOCK_PX, bx : bx + nx * JPEG_BLOCK_PX]
    blocks = grid.reshape(ny, JPEG_BLOCK_PX, nx, JPEG_BLOCK_PX).swapaxes(1, 2).reshape(-1, 64)
    blocks = blocks[~np.any((blocks <= 0) | (blocks >= 255), axis=1)]
    if len(blocks) < MIN_BLOCKS:
        return float("nan")
    dc = blocks.sum(axis=1) / JPEG_BLOCK_PX - 128.0 * JPEG_BLOCK_PX
    phase = dc[None, :] / DC_STEPS[:, None]
    score = np.cos(2.0 * np.pi * phase).mean(axis=1)
    points = np.sort(np.round(phase), axis=1)
    levels = 1 + np.count_nonzero(np.diff(points, axis=1), axis=1)  # distinct lattice points
    fits = DC_STEPS[(score >= LATTICE_MIN_SCORE) & (levels >= LATTICE_MIN_LEVELS)]
    return float(fits.max()) if fits.size else float("nan")


def libjpeg_dc_step(quality: int | np.ndarray) -> np.ndarray:
    """The luminance DC step libjpeg uses at ``quality`` (1-100; baseline, clamped to 1-255)."""
    q = np.clip(np.asarray(quality, np.int64), 1, 100)
    scale = np.where(q < 50, 5000 // q, 200 - 2 * q)
    return np.clip((STANDARD_DC_STEP * scale + 50) // 100, 1, 255)


def quality_for_dc_step(step: float) -> int:
    """The libjpeg quality whose DC step is ``step`` (the middle of the qualities that share it).

    Where no quality has exactly that step, the quality whose step is nearest.
    """
    qualities = np.arange(1, 101)
    steps = libjpeg_dc_step(qualities)
    gap = np.abs(steps - step)
    same = qualities[gap == gap.min()]
    return int(same[len(same) // 2])
