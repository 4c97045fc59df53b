"""Image evidence around each tag: levels, contrast, edge width, noise, clipping, highlights.

Measured the same way on real and simulated 8-bit grey frames, from the frame around the tag's
detected corners (or its expected corners when it was not detected), so that the diagnosis can
compare what the camera sees, not only where the corners land.

Regions are defined in the marker's own normalised coordinates (the outer black square is
``[-0.5, 0.5]^2``, one cell is ``1 / cells``), mapped to the image by the homography of the four
corners, and every pixel centre of the sticker's bounding box is classified by mapping it back:

``ink``
    the middle half of the marker's one-cell black border, ``0.5 - 0.75 c <= r <= 0.5 - 0.25 c``
    with ``r = max(|x|, |y|)``;
``paper``
    the middle of the white quiet zone, ``0.5 + 0.5 c <= r <= 0.5 + 1.5 c`` (the quiet zone is
    ``quiet_cells`` wide; at least 2 cells are needed);
``sticker``
    everything inside ``r <= 0.5 + quiet_cells c``.

Statistics (see :data:`STATS` for names, units and meanings):

- levels: medians of the ink and paper regions, in 8-bit DN and linearised with the sRGB
  transfer curve (IEC 61966-2-1, via colour-science), or with the camera's measured response
  where one is given (:func:`linearised`; every linearised statistic alike), as a fraction of
  full scale;
- contrast: Michelson contrast of the linear levels;
- edge width: the 10-90 % rise of an edge-spread function fitted across the marker's outer border
  (the slanted-edge idea of ISO 12233: pixels at many sub-pixel distances from a straight edge
  sample the edge-spread function finely). The model is ``ink + (paper - ink) E(d - d0; s)`` on
  linearised values, with ``E`` a Gaussian PSF of ``s`` px seen through square pixels
  (:func:`simgap.pose.edge_spread.pixel_esf`), fitted by robust least squares; the width is the
  10-90 % rise of ``E`` (px; 0.8 px for a perfectly sharp edge, ``~2.563 sqrt(s^2 + 1/12)`` for a
  blurred one). All four sides, and the left/right (``x``) and top/bottom (``y``) pairs apart, which
  tells a directional blur (motion) from an isotropic one. Only from detected corners (expected
  corners can be off by pixels);
- noise: standard deviation of flat ink and paper pixels from differences of horizontal
  neighbours (``std(diff) / sqrt(2)``, insensitive to smooth shading), in DN and linear units;
  pairs of (level, variance) over many tags give the photon transfer curve (EMVA 1288);
- temporal noise: where a second frame of the same pose is given (a repeat), the standard
  deviation of the two frames' difference in the same flat ink and paper pixels over sqrt(2),
  linearised: EMVA 1288's own temporal noise, which every fixed pattern (print texture, the
  photo-response non-uniformity, a renderer's Monte Carlo noise) cancels from. NaN from one frame;
- clipped fraction: share of sticker pixels at 0 or 255 DN;
- highlight fraction: share of sticker pixels far above the tag's own paper level
  (more than ``max(5 sigma_paper, 12 DN)`` above it);
- rejected candidates: quadrilaterals the ArUco detector rejected whose centre lies on the sticker;
- blockiness: the mean absolute step between horizontal and vertical neighbours in the flat
  parts of the sticker (more than :data:`BLOCK_EDGE_MARGIN_PX` from every cell edge) where they
  straddle a boundary of the full frame's 8 x 8 JPEG block grid, over the same mean elsewhere
  (the blocking measure of Wang, Bovik & Evans, ICIP 2000, on flat pixels so that the marker's
  own edges do not count). About 1 without compression whatever the noise; JPEG at quality 70
  raises it by about half a stop to a stop, at 30 by about a stop (rotated synthetic tags,
  tests/test_image_stats.py). Tags whose edges run along the pixel grid leave few flat pixels
  between blurred edges and read less reliably;
- JPEG DC step: the quantisation step on whose lattice the DC coefficients of the sticker's
  whole 8 x 8 blocks lie (DN; NaN without compression or above quality about 85):
  :mod:`simgap.pose.jpeg_blocks`;
- black-clipped fraction: share of sticker pixels at 0 DN (crushed blacks: a black level set too
  high, an underexposure, a steep tone curve); ``clipped_fraction`` counts both ends together;
- edge overshoot: the sharpening halo, from the same edge pixels as the edge width (all four
  sides pooled, linearised): their signed distances to the edge binned every
  :data:`OVERSHOOT_BIN_PX` px, the median of each bin of at least :data:`MIN_PIXELS` pixels, and
  the larger of the brightest paper-side median's excess over the paper level and the darkest
  ink-side median's deficit under the ink level, over the edge step ``paper - ink`` (ratio,
  floored at 0). About 0 for an edge blurred or sharp but not sharpened; an unsharp mask
  raises it (tests/test_image_stats.py). Only from detected corners, like the edge width;
- colour fringe: how far (DN, RGB) the pixels within :data:`FRINGE_EDGE_PX` px of the marker's
  outer edge lie from the line through the ink's and the paper's colours (per-channel medians
  of the ink and paper regions), as an RMS over those pixels, less in quadrature the RMS distance
  of the flat ink and paper pixels from the same line (floored at 0), so that noise and a spread
  of the colour cast cancel. Demosaicing and lateral chromatic aberration colour the edges
  and raise it; a grey edge reads about 0 whatever its blur, and so does a tinted one (a coloured
  light or paper: the blend of two colours of one hue stays near their line). NaN without the
  8-bit RGB frame, from a grey one (all channels equal) and where the corners were not detected;
- repeat gain: where a second frame of the same pose is given, ``log2`` of the paper level over
  the repeat's paper level (the same median over the same paper pixels, linearised): the gain
  or exposure change between the two frames (EV, positive where this frame is the brighter),
  0 for two frames of one gain whatever their noise. NaN from one frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import colour
import cv2
import numpy as np
from numpy.typing import ArrayLike

from simgap.core.robust import MAD_TO_SIGMA
from simgap.pose.edge_spread import fit_esf_width
from simgap.pose.jpeg_blocks import JPEG_BLOCK_PX, dc_step

#: Long name of a temporal noise statistic (``{}``: ink or paper).
TEMPORAL = "temporal noise sigma in flat {} pixels (two frames of one pose), linearised"
#: ``(name, units, long name)`` of every statistic, in storage order.
STATS: tuple[tuple[str, str, str], ...] = (
    ("ink_dn", "DN", "median 8-bit level of the marker's black border"),
    ("paper_dn", "DN", "median 8-bit level of the white quiet zone"),
    (
        "ink_linear",
        "1",
        "ink level linearised with the sRGB curve or the camera's measured response "
        "(fraction of full scale)",
    ),
    (
        "paper_linear",
        "1",
        "paper level linearised with the sRGB curve or the camera's measured response "
        "(fraction of full scale)",
    ),
    ("contrast", "1", "Michelson contrast of the linear levels (paper - ink) / (paper + ink)"),
    ("edge_width_px", "px", "10-90 % rise of the edge-spread function across the outer border"),
    ("edge_width_x_px", "px", "edge width across the marker's left and right sides (along x)"),
    ("edge_width_y_px", "px", "edge width across the marker's top and bottom sides (along y)"),
    ("noise_ink_dn", "DN", "noise standard deviation in flat ink pixels"),
    ("noise_paper_dn", "DN", "noise standard deviation in flat paper pixels"),
    ("noise_ink_linear", "1", "noise standard deviation in flat ink pixels, linearised"),
    ("noise_paper_linear", "1", "noise standard deviation in flat paper pixels, linearised"),
    ("temporal_noise_ink_linear", "1", TEMPORAL.format("ink")),
    ("temporal_noise_paper_linear", "1", TEMPORAL.format("paper")),
    ("clipped_fraction", "1", "share of sticker pixels at 0 or 255 DN"),
    ("highlight_fraction", "1", "share of sticker pixels far above the tag's paper level"),
    ("rejected_candidates", "1", "detector candidates rejected on the sticker"),
    (
        "blockiness",
        "1",
        "mean |step| between neighbours across 8x8 JPEG block boundaries over that inside blocks",
    ),
    ("jpeg_dc_step_dn", "DN", "quantisation step of the 8x8 JPEG blocks' DC coefficient"),
    ("black_clipped_fraction", "1", "share of sticker pixels at 0 DN"),
    (
        "edge_overshoot",
        "1",
        "overshoot of the edge profile beyond ink and paper over the edge step",
    ),
    ("colour_fringe_dn", "DN", "RMS colour distance of edge pixels from the ink-paper colour line"),
    ("repeat_gain_ev", "1", "log2 of the paper level over a repeat frame's (EV), gain change"),
)
STAT_NAMES: tuple[str, ...] = tuple(s[0] for s in STATS)


#: The statistics that each take an edge-spread fit (most of a tag's measuring time), and the
#: marker sides (0 top, 1 right, 2 bottom, 3 left) each one pools.
EDGE_WIDTH_SIDES: dict[str, tuple[int, ...]] = {
    "edge_width_px": (0, 1, 2, 3),
    "edge_width_x_px": (1, 3),
    "edge_width_y_px": (0, 2),
}
EDGE_WIDTH_STATS: tuple[str, ...] = tuple(EDGE_WIDTH_SIDES)
STAT_INDEX = {name: i for i, name in enumerate(STAT_NAMES)}

#: Highlight threshold above the paper level: this many paper noise sigmas, at least
#: :data:`HIGHLIGHT_MIN_DN`.
HIGHLIGHT_SIGMAS = 5.0
HIGHLIGHT_MIN_DN = 12.0
#: Largest distance from the edge used in the edge-spread fit (px), and the share of a cell
#: (across the edge) it may reach on either side, so that neighbouring edges stay out of the fit.
ESF_MAX_DISTANCE_PX = 4.0
ESF_MAX_CELL_SHARE = 0.9
#: Share of each side (about its middle) used for the edge-spread fit: corners are left out.
ESF_SIDE_SHARE = 0.7
#: Fewest pixels a region needs for its statistic (else NaN).
MIN_PIXELS = 12
#: Width of the distance bins of the edge overshoot (px): half a pixel resolves a halo one or two
#: pixels wide and still holds :data:`MIN_PIXELS` pixels a bin on a side of some 20 px.
OVERSHOOT_BIN_PX = 0.5
#: Pixels at most this far from the marker's outer edge (px) are the edge of the colour fringe.
FRINGE_EDGE_PX = 1.5
#: Added to both mean steps of the blockiness (DN): noise-free flat regions read 1, not 0 / 0.
BLOCK_EPSILON_DN = 0.5
#: Pixels closer than this to a cell edge of the marker are left out of the blockiness (px).
BLOCK_EDGE_MARGIN_PX = 2.5
#: Neighbour differences further than this many robust sigmas from their median are edges or
#: texture, not noise, and are left out of the noise estimate.
NOISE_CLIP_SIGMAS = 6.0

_SRGB_TO_LINEAR = colour.cctf_decoding(np.arange(256) / 255.0, function="sRGB").astype(np.float64)
_UNIT_SQUARE = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]], np.float64)


def linearise(dn: ArrayLike) -> np.ndarray:
    """8-bit sRGB-encoded values (DN) to linear values (fraction of full scale)."""
    return _SRGB_TO_LINEAR[np.clip(np.asarray(dn), 0, 255).astype(np.intp)]


def linearised(dn: ArrayLike, response: Sequence[float] | None = None) -> np.ndarray:
    """8-bit codes (DN) to linear values: through the camera's ``response`` where given.

    ``response`` (256,): the relative exposure at each code (fraction of full scale,
    :class:`simgap.pose.camera_response.CameraResponse`); None: the sRGB curve
    (:func:`linearise`).
    """
    table = _SRGB_TO_LINEAR if response is None else np.asarray(response, float)
    return table[np.clip(np.asarray(dn), 0, 255).astype(np.intp)]


def is_grey(image: np.ndarray) -> bool:
    """Whether an image carries no colour: 2-D, or its channels (last axis) all equal."""
    return image.ndim != 3 or bool((image == image[..., :1]).all())


@dataclass(frozen=True)
class MarkerLayout:
    """Cells across the marker (including its black border) and quiet-zone cells around it."""

    cells: int
    quiet_cells: int

    @property
    def cell(self) -> float:
        """One cell in normalised marker units."""
        return 1.0 / self.cells


def _noise(values: np.ndarray, mask: np.ndarray) -> float:
    """Noise sigma from differences of horizontal neighbours that are both in ``mask``."""
    pair = mask[:, :-1] & mask[:, 1:]
    if pair.sum() < MIN_PIXELS:
        return float("nan")
    return _difference_sigma((values[:, 1:] - values[:, :-1])[pair])


def _temporal_noise(values: np.ndarray, repeat: np.ndarray, mask: np.ndarray) -> float:
    """Noise sigma from the differences of two frames of one pose in the pixels of ``mask``."""
    if mask.sum() < MIN_PIXELS:
        return float("nan")
    return _difference_sigma((values - repeat)[mask])


def _difference_sigma(d: np.ndarray) -> float:
    """Sigma of each of two noisy values from their differences ``d``: ``std(d) / sqrt(2)``.

    Differences further than :data:`NOISE_CLIP_SIGMAS` robust sigmas from their median (edges,
    texture, a moved edge) are left out.
    """
    med = np.median(d)
    mad = MAD_TO_SIGMA * np.median(np.abs(d - med))
    keep = (
        np.abs(d - med) <= max(NOISE_CLIP_SIGMAS * mad, 1e-12)
        if mad > 0
        else np.ones(d.shape, bool)
    )
    return float(np.std(d[keep]) / np.sqrt(2.0))


def _blockiness(
    patch: np.ndarray, flat: np.ndarray, x0: int, y0: int, epsilon_dn: float = BLOCK_EPSILON_DN
) -> float:
    """Mean |step| across 8 x 8 block boundaries over the mean |step| elsewhere (see module doc).

    ``x0, y0`` are the full-frame pixel coordinates of ``patch[0, 0]``; only pairs of
    neighbours that are both in ``flat`` count, and ``epsilon_dn`` is added to both means.
    """
    steps_at, steps_off = [], []
    for axis, start in ((1, x0), (0, y0)):
        step = np.abs(np.diff(patch, axis=axis))
        pair = (flat[:, 1:] & flat[:, :-1]) if axis == 1 else (flat[1:, :] & flat[:-1, :])
        at = (start + np.arange(step.shape[axis]) + 1) % JPEG_BLOCK_PX == 0
        at = at[None, :] if axis == 1 else at[:, None]
        steps_at.append(step[pair & at])
        steps_off.append(step[pair & ~at])
    on, off = np.concatenate(steps_at), np.concatenate(steps_off)
    if on.size < MIN_PIXELS or off.size < MIN_PIXELS:
        return float("nan")
    return float((on.mean() + epsilon_dn) / (off.mean() + epsilon_dn))


def _edge_overshoot(d: np.ndarray, values: np.ndarray, ink: float, paper: float) -> float:
    """Overshoot of an edge profile beyond its ink and paper levels, over the step (see module doc).

    Parameters
    ----------
    d : ndarray (n,)
        Signed distances of the edge pixels to the edge (px, positive towards the paper).
    values : ndarray (n,)
        Their linearised values (fraction of full scale).
    ink, paper : float
        The ink and paper levels (fraction of full scale).

    Returns
    -------
    float
        The larger of the paper-side excess and the ink-side deficit over ``paper - ink``
        (ratio, at least 0); NaN where no bin holds :data:`MIN_PIXELS` pixels or the step is not
        positive.
    """
    step = paper - ink
    if not step > 0:
        return float("nan")
    n_bins = int(round(2 * ESF_MAX_DISTANCE_PX / OVERSHOOT_BIN_PX))
    edges = np.linspace(-ESF_MAX_DISTANCE_PX, ESF_MAX_DISTANCE_PX, n_bins + 1)
    which = np.digitize(d, edges) - 1
    excess = []
    for k in range(n_bins):
        in_bin = values[which == k]
        if in_bin.size < MIN_PIXELS:
            continue
        median = float(np.median(in_bin))
        excess.append(median - paper if edges[k] >= 0 else ink - median)
    if not excess:
        return float("nan")
    return max(max(excess) / step, 0.0)


def _colour_fringe(rgb: np.ndarray, edge: np.ndarray, ink: np.ndarray, paper: np.ndarray) -> float:
    """RMS distance of edge colours from the ink-paper colour line, flat spread removed (DN).

    Parameters
    ----------
    rgb : ndarray (n, 3)
        The sticker's 8-bit RGB values (DN), one row a pixel.
    edge, ink, paper : ndarray of bool (n,)
        The edge pixels and the flat ink and paper pixels.

    Returns
    -------
    float
        ``sqrt(max(a^2 - b^2, 0))`` with ``a`` the RMS distance of the edge pixels from the line
        through the ink's and the paper's per-channel median colours and ``b`` that of the flat
        pixels (DN); NaN with fewer than :data:`MIN_PIXELS` edge pixels or where the two colours
        coincide.
    """
    if edge.sum() < MIN_PIXELS:
        return float("nan")
    ink_colour = np.median(rgb[ink], axis=0)
    axis = np.median(rgb[paper], axis=0) - ink_colour
    length = float(np.linalg.norm(axis))
    if length < 1.0:
        return float("nan")
    axis /= length

    def mean_square_distance(colours: np.ndarray) -> float:
        offset = colours - ink_colour
        off_line = offset - np.outer(offset @ axis, axis)
        return float(np.mean(np.sum(off_line**2, axis=1)))

    excess = mean_square_distance(rgb[edge]) - mean_square_distance(rgb[ink | paper])
    return float(np.sqrt(max(excess, 0.0)))


def _edge_samples(
    pts: np.ndarray, norm: np.ndarray, corners: np.ndarray, layout: MarkerLayout
) -> list[np.ndarray] | None:
    """Pixels for the edge-spread fit of each side (top, right, bottom, left).

    Returns, per side, an array (2, n): pixel indices and their signed distances to the marker's
    outer edge (px, positive outwards); None when the marker is too small.
    """
    c = layout.cell
    inner_mid = np.array([[0.0, -0.5 + c], [0.5 - c, 0.0], [0.0, 0.5 - c], [-0.5 + c, 0.0]])
    inner = _map(inner_mid, corners)
    out = []
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        side = b - a
        length = float(np.hypot(*side))
        if length < 4.0:
            return None
        tangent = side / length
        # outward normal: corners run clockwise on screen (TL, TR, BR, BL), outside is on the left
        normal = np.array([tangent[1], -tangent[0]])
        # along-side and across-side coordinates in the marker's own units (0 at the middle)
        along = norm[:, 0] if k in (0, 2) else norm[:, 1]
        across = norm[:, 1] if k in (0, 2) else norm[:, 0]
        outward_sign = -1.0 if k in (0, 3) else 1.0
        on_side = (np.abs(along) <= ESF_SIDE_SHARE / 2) & (outward_sign * across > 0)
        # width of one cell across this edge (px), at the side's middle
        cell_px = float(np.hypot(*(inner[k] - (a + b) / 2)))
        reach = min(ESF_MAX_DISTANCE_PX, ESF_MAX_CELL_SHARE * cell_px)
        if reach < 1.0:
            return None
        d = (pts - a) @ normal
        sel = np.flatnonzero(on_side & (np.abs(d) <= reach))
        out.append(np.stack([sel, d[sel]]))
    return out


def _map(norm: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Normalised marker coordinates (N, 2) to image pixels (N, 2)."""
    h = cv2.getPerspectiveTransform(_UNIT_SQUARE.astype(np.float32), corners.astype(np.float32))
    return cv2.perspectiveTransform(norm.reshape(-1, 1, 2).astype(np.float64), h).reshape(-1, 2)


def tag_stats(
    gray: np.ndarray,
    corners: np.ndarray,
    layout: MarkerLayout,
    offset: tuple[int, int] = (0, 0),
    rejected: list[np.ndarray] | tuple = (),
    edge_widths: tuple[str, ...] = EDGE_WIDTH_STATS,
    repeat: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    response: Sequence[float] | None = None,
) -> np.ndarray:
    """Statistics of one tag, in the order of :data:`STATS`; NaN where not measurable.

    Parameters
    ----------
    gray : ndarray of uint8 (H, W)
        8-bit grey frame or a crop of it.
    corners : ndarray (4, 2)
        Marker corners TL, TR, BR, BL in full-frame pixels (OpenCV convention).
    layout : MarkerLayout
        Cells across the marker and quiet-zone cells.
    offset : tuple of int
        Full-frame pixel of the crop's top-left corner (px).
    rejected : sequence of ndarray (4, 2)
        Rejected detector candidates in full-frame pixels.
    edge_widths : tuple of str
        The edge widths (of :data:`EDGE_WIDTH_STATS`) to fit; the others are NaN. Empty where
        the corners are only expected, not detected (the fit needs accurate corners), or where
        the caller reads no edge width (the fits are most of a tag's measuring time).
    repeat : ndarray of uint8 (H, W), optional
        A second frame of the same pose (same crop): the temporal noise and the repeat gain are
        measured from it.
    rgb : ndarray of uint8 (H, W, 3), optional
        The same frame in 8-bit RGB (same crop and offset as ``gray``): the colour fringe is
        measured from it (NaN without it, or where it is grey: 2-D or all channels equal).

    response : sequence of float (256,), optional
        The camera's measured response, the relative exposure at each code
        (:class:`simgap.pose.camera_response.CameraResponse`): the linearised statistics are
        read through it instead of the sRGB curve (:func:`linearised`).

    Raises
    ------
    ValueError
        Where ``rgb`` is given with another height and width than ``gray``.
    """
    out = np.full(len(STATS), np.nan)
    if rgb is not None and rgb.shape[:2] != gray.shape[:2]:
        raise ValueError(f"rgb is {rgb.shape[:2]}, gray {gray.shape[:2]}: expected the same crop")
    corners = np.asarray(corners, np.float64).reshape(4, 2)
    if not np.isfinite(corners).all():
        return out
    local = corners - np.asarray(offset, np.float64)
    reach = 0.5 + layout.quiet_cells * layout.cell
    sticker = _map(_UNIT_SQUARE * 2 * reach, local)
    x0, y0 = np.floor(sticker.min(axis=0)).astype(int)
    x1, y1 = np.ceil(sticker.max(axis=0)).astype(int)
    h, w = gray.shape[:2]
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1 + 1, w), min(y1 + 1, h)
    if x1 - x0 < 4 or y1 - y0 < 4:
        return out
    patch = np.asarray(gray[y0:y1, x0:x1], np.float64)
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    pts = np.stack([xx.ravel(), yy.ravel()], axis=1)
    hinv = cv2.getPerspectiveTransform(local.astype(np.float32), _UNIT_SQUARE.astype(np.float32))
    norm = cv2.perspectiveTransform(pts.reshape(-1, 1, 2), hinv).reshape(-1, 2)
    r = np.max(np.abs(norm), axis=1).reshape(patch.shape)
    c = layout.cell
    ink_mask = (r >= 0.5 - 0.75 * c) & (r <= 0.5 - 0.25 * c)
    paper_mask = (r >= 0.5 + 0.5 * c) & (r <= 0.5 + 1.5 * c)
    sticker_mask = r <= reach
    if ink_mask.sum() < MIN_PIXELS or paper_mask.sum() < MIN_PIXELS or layout.quiet_cells < 2:
        return out
    lin = linearised(patch, response)
    ink_dn, paper_dn = float(np.median(patch[ink_mask])), float(np.median(patch[paper_mask]))
    ink_lin, paper_lin = float(np.median(lin[ink_mask])), float(np.median(lin[paper_mask]))
    s = STAT_INDEX
    out[s["ink_dn"]], out[s["paper_dn"]] = ink_dn, paper_dn
    out[s["ink_linear"]], out[s["paper_linear"]] = ink_lin, paper_lin
    total = paper_lin + ink_lin
    out[s["contrast"]] = (paper_lin - ink_lin) / total if total > 0 else np.nan
    out[s["noise_ink_dn"]] = _noise(patch, ink_mask)
    out[s["noise_paper_dn"]] = _noise(patch, paper_mask)
    out[s["noise_ink_linear"]] = _noise(lin, ink_mask)
    out[s["noise_paper_linear"]] = _noise(lin, paper_mask)
    if repeat is not None:
        lin_repeat = linearised(repeat[y0:y1, x0:x1], response)
        out[s["temporal_noise_ink_linear"]] = _temporal_noise(lin, lin_repeat, ink_mask)
        out[s["temporal_noise_paper_linear"]] = _temporal_noise(lin, lin_repeat, paper_mask)
        repeat_paper = float(np.median(lin_repeat[paper_mask]))
        if paper_lin > 0 and repeat_paper > 0:
            out[s["repeat_gain_ev"]] = float(np.log2(paper_lin / repeat_paper))
    values = patch[sticker_mask]
    out[s["clipped_fraction"]] = float(np.mean((values <= 0) | (values >= 255)))
    out[s["black_clipped_fraction"]] = float(np.mean(values <= 0))
    sigma = out[s["noise_paper_dn"]]
    spread = HIGHLIGHT_SIGMAS * (sigma if np.isfinite(sigma) else 0.0)
    limit = paper_dn + max(spread, HIGHLIGHT_MIN_DN)
    out[s["highlight_fraction"]] = float(np.mean(values > limit))
    # flat pixels: on the sticker and away from every cell edge of the marker and its border
    px_per_unit = float(np.mean(np.linalg.norm(np.diff(local, axis=0, append=local[:1]), axis=1)))
    edge_dist = np.abs((norm + 0.5) / c - np.round((norm + 0.5) / c)) * c * px_per_unit
    rr = r.ravel()
    near = np.where((rr <= 0.5)[:, None], edge_dist, np.inf).min(axis=1)
    near = np.minimum(near, np.minimum(np.abs(rr - 0.5), np.abs(rr - reach)) * px_per_unit)
    flat = sticker_mask & (near.reshape(patch.shape) >= BLOCK_EDGE_MARGIN_PX)
    full_x0, full_y0 = int(offset[0]) + x0, int(offset[1]) + y0
    out[s["blockiness"]] = _blockiness(patch, flat, full_x0, full_y0)
    out[s["jpeg_dc_step_dn"]] = dc_step(patch, full_x0, full_y0)
    samples = _edge_samples(pts, norm, local, layout) if edge_widths else None
    if samples is not None:
        lin_values = lin.ravel()
        for name in edge_widths:
            sides = EDGE_WIDTH_SIDES[name]
            idx = np.concatenate([samples[k][0] for k in sides]).astype(np.intp)
            d = np.concatenate([samples[k][1] for k in sides])
            out[s[name]] = fit_esf_width(d, lin_values[idx], ink_lin, paper_lin, 2 * MIN_PIXELS)
        idx = np.concatenate([side[0] for side in samples]).astype(np.intp)
        d = np.concatenate([side[1] for side in samples])
        out[s["edge_overshoot"]] = _edge_overshoot(d, lin_values[idx], ink_lin, paper_lin)
        colour = None if rgb is None or rgb.ndim != 3 else rgb[y0:y1, x0:x1]
        if colour is not None and not is_grey(colour):
            edge = np.zeros(patch.size, bool)
            edge[idx[np.abs(d) <= FRINGE_EDGE_PX]] = True
            out[s["colour_fringe_dn"]] = _colour_fringe(
                colour.reshape(-1, colour.shape[-1]).astype(np.float64),
                edge,
                ink_mask.ravel(),
                paper_mask.ravel(),
            )
    n_rejected = 0
    for quad in rejected:
        centre = np.asarray(quad, np.float64).reshape(4, 2).mean(axis=0) - offset
        m = cv2.perspectiveTransform(centre.reshape(1, 1, 2), hinv).reshape(2)
        n_rejected += bool(np.max(np.abs(m)) <= reach)
    out[s["rejected_candidates"]] = float(n_rejected)
    return out
