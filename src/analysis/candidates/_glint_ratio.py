"""The ink-to-paper ratio of a tag under a glint: a laminate's signature whatever the lights.

Any matte light, exposure, colour or vignetting scales a tag's ink and its paper alike; a glint
(the laminate's mirror reflection of a light beside the lens), the laminate's veil (its mirror
reflection of the surroundings) and veiling flare add the same radiance to both. So the ratio of
ink to paper of a tag whose paper is not clipped is

    r = h r_sim + (1 - h r_sim) (S + V R(theta_o) + F) / P

with ``r_sim`` the simulation's ratio (matte print, its lights), ``h`` a constant (a transfer
curve's or the print's darker ink), ``P`` the real paper level, ``F`` a flare level (the same on
every tag), ``S = c D(theta_h; alpha) / (d^2 cos(theta_o))`` the glint of
:mod:`simgap.analysis.candidates._gloss` (its level model, step 2) and ``V R(theta_o)`` the veil:
the surroundings' radiance ``V`` times the coating's Fresnel reflectance relative to its normal one
(:func:`simgap.analysis.candidates.fresnel_veil`), which grows towards grazing views where flare
does not. The capture's own lights cancel: the level model of ink and paper must absorb them
with its exposure and a matte light beside the lens. The model without a laminate has ``h``
and ``F``; the laminate adds the glint and the veil. A laminate under a room's ambient light
and a weak light beside the lens shows mostly its veil (oblique tags' ink lifted beyond any
flare) and a few faint glints; without the veil the flare absorbs the oblique tags and the
glint's gain stays below the support (docs/results/laminate.md).

The model needs tags whose paper is not clipped (``P`` is known): at least :data:`MIN_TAGS`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simgap.analysis.candidates._appearance import capped_rms
from simgap.analysis.candidates._fitting import on_bound
from simgap.analysis.candidates._lobe import MIN_COS, beckmann, fresnel_veil, lobe_geometry
from simgap.analysis.candidates._subset_fit import fit_subset
from simgap.analysis.candidates._tag_levels import TagLevels
from simgap.analysis.thresholds import IMAGE_FLOORS, SIGNATURE_MIN_GAIN

#: Fewest tags with unclipped ink and paper for the ratio model: its five fitted parameters and
#: three more. Below it (an overexposed capture whose papers clip) the level model decides.
MIN_TAGS = 8
#: Starts of the glint's search, here and in the level model
#: (:func:`simgap.analysis.candidates.fit_levels`): roughness x horizontal offset (m); the
#: light's side is what the turntable's two directions tell apart.
STARTS: tuple[tuple[float, ...], tuple[float, ...]] = ((0.05, 0.12, 0.3), (-0.05, 0.05))
#: The light's height above the lens is not fitted (m): the turntable turns about a vertical
#: axis, so a height only widens the lobe, as roughness does. Measured on the development
#: captures with a laminate and enough unclipped papers: the misfit at height 0 was within 0.02
#: floors of the best over +-0.15 m (a tenth of the equivalence tolerance), and a free height
#: ran to its bound (docs/results/design_evidence.md#glint_ratio).
HEIGHT_M = 0.0
#: Horizontal offsets (m) at which the light is held where a fit's offset runs onto the end of
#: its searched range (:func:`held_inside`): at the lens, and the searches' own starts.
HELD_OFFSETS_M: tuple[float, ...] = (0.0, *STARTS[1])


def held_inside(
    free: tuple[np.ndarray, float], held: list[tuple[np.ndarray, float]]
) -> tuple[np.ndarray, float]:
    """The glint's fit, or one with its light held inside where the levels do not ask for the end.

    A light's offset fitted onto the end of its searched range stands in for a light the
    level or ratio model lacks (the capture's own key light elsewhere than the simulation's),
    or the tags' views leave the offset undetermined (mostly frontal tags: roughness, offset
    and intensity trade off). Where the best of the ``held`` fits (the light held at
    :data:`HELD_OFFSETS_M` level with the lens, everything else fitted) is within the
    signature's smallest gain (:data:`~simgap.analysis.thresholds.SIGNATURE_MIN_GAIN`, floors
    RMS) of the ``free`` one, the levels do not ask for the end and the held fit is kept: a
    light on the camera body.

    Parameters
    ----------
    free : (ndarray, float)
        The fit with a free offset and its RMS misfit (floors).
    held : list of (ndarray, float)
        Fits with the offset held inside and their RMS misfits; empty where the free fit's
        offset is inside its range.
    """
    if not held:
        return free
    inside = min(held, key=lambda fit: fit[1])
    return inside if inside[1] - free[1] < SIGNATURE_MIN_GAIN else free


@dataclass(frozen=True)
class RatioFit:
    """The ratio model fitted without a glint (``h`` and flare) and with one.

    Attributes
    ----------
    x : ndarray (7,)
        ``(log2 h, F, c, alpha, offset_x_m, offset_z_m, V)`` of the model with a laminate (the
        height ``offset_z_m`` is :data:`HEIGHT_M`, or the ``fixed`` one); ``F`` and ``V`` in
        linear full scale.
    rms_flat, rms_glint : float
        RMS misfits (floors of ``ink_linear``) without a laminate and with its glint and veil.
    tags : int
        Tags fitted.
    """

    x: np.ndarray
    rms_flat: float
    rms_glint: float
    tags: int

    @property
    def gain(self) -> float:
        """What the laminate (glint and veil) explains beyond flare and a flat ratio (floors)."""
        return self.rms_flat - self.rms_glint

    @property
    def supported(self) -> bool:
        """Whether the laminate is called for, with a glint or a veil.

        Its gain reaches the signature's smallest gain
        (:data:`~simgap.analysis.thresholds.SIGNATURE_MIN_GAIN`, floors).
        """
        return self.gain >= SIGNATURE_MIN_GAIN and (self.glint_scale > 0 or self.veil > 0)

    @property
    def geometry(self) -> tuple[float, float, float]:
        """``(alpha, offset_x_m, offset_z_m)`` of the glint."""
        return float(self.x[3]), float(self.x[4]), float(self.x[5])

    @property
    def veil(self) -> float:
        """``V``: the surroundings' radiance the coating mirrors, at normal view (full scale)."""
        return float(self.x[6])

    @property
    def glint_scale(self) -> float:
        """``c``: the glint's scale (linear full scale x m^2 sr)."""
        return float(self.x[2])


def ratio_residuals(levels: TagLevels, x: np.ndarray) -> np.ndarray:
    """Log ratio residuals (floors of ``ink_linear``) of the unclipped tags at ``x``."""
    ok = levels.readable
    r_sim = levels.sim_ink[ok] / levels.sim_paper[ok]
    paper = levels.real_paper[ok]
    cos_h, cos_o, _, distance = lobe_geometry(levels.eye_from_tag[ok], x[4], x[5])
    glint = x[2] * beckmann(cos_h, x[3]) / (distance**2 * np.maximum(cos_o, MIN_COS))
    added = glint + x[6] * fresnel_veil(cos_o) + x[1]
    flat = 2.0 ** x[0] * r_sim
    ratio = flat + (1.0 - flat) * np.minimum(added / paper, 1.0)
    observed = levels.real_ink[ok] / paper
    return np.log2(np.maximum(ratio, 1e-6) / observed) / IMAGE_FLOORS["ink_linear"][1]


def fit_ratios(
    levels: TagLevels,
    alpha_range: tuple[float, float],
    offset_range: tuple[float, float],
    fixed: tuple[float, float, float] | None = None,
) -> RatioFit | None:
    """Robust least squares of the ratio model; None with fewer than :data:`MIN_TAGS` tags.

    With ``fixed`` ``(alpha, offset_x_m, offset_z_m)`` only ``h``, the flare, the glint's scale
    and the veil are fitted (the calibration render of
    :meth:`simgap.analysis.candidates.GlossCandidate.intensity`). A free offset fitted onto the
    end of ``offset_range`` is kept only where the ratios ask for it (:func:`held_inside`).
    """
    tags = int(np.count_nonzero(levels.readable))
    if tags < MIN_TAGS:
        return None

    def solve(x0: np.ndarray, free: np.ndarray, lower, upper) -> tuple[np.ndarray, float]:
        x = fit_subset(lambda v: ratio_residuals(levels, v), x0, free, lower, upper)
        return x, capped_rms(ratio_residuals(levels, x))

    flat_x, rms_flat = solve(
        np.array([0.0, 0.0, 0.0, alpha_range[1], 0.0, HEIGHT_M, 0.0]),
        np.array([1, 1, 0, 0, 0, 0, 0], bool),
        (-4.0, 0.0),
        (4.0, 1.0),
    )
    # a start's glint: a hundredth of the median paper at the lobe's peak, per unit of D
    scale = 0.01 * float(np.median(levels.real_paper[~levels.clipped]))
    if fixed is not None:
        start = flat_x.copy()
        start[2], start[3:6] = scale * fixed[0], fixed
        x, rms = solve(
            start, np.array([1, 1, 1, 0, 0, 0, 1], bool), (-4, 0, 0, 0), (4, 1, np.inf, 1)
        )
        return RatioFit(x, rms_flat, rms, tags)
    lower = (-4.0, 0.0, 0.0, alpha_range[0], offset_range[0], 0.0, 0.0)
    upper = (4.0, 1.0, np.inf, alpha_range[1], offset_range[1], 0.0, 1.0)

    def from_starts(offsets: tuple[float, ...], free: np.ndarray) -> list[tuple[np.ndarray, float]]:
        """The glint fitted from each roughness start x each horizontal offset (height fixed)."""
        lo, hi = tuple(np.asarray(lower)[free]), tuple(np.asarray(upper)[free])
        fits = []
        for alpha in STARTS[0]:
            for offset_x in offsets:
                start = flat_x.copy()
                start[2:5] = scale * alpha, alpha, offset_x
                fits.append(solve(start, free, lo, hi))
        return fits

    # the first of equal misfits: the flat ratio before any glint
    fits = [(flat_x, rms_flat), *from_starts(STARTS[1], np.array([1, 1, 1, 1, 1, 0, 1], bool))]
    best, best_rms = min(fits, key=lambda fit: fit[1])
    held = []
    if on_bound(float(best[4]), *offset_range):
        held = from_starts(HELD_OFFSETS_M, np.array([1, 1, 1, 1, 0, 0, 1], bool))
    best, best_rms = held_inside((best, best_rms), held)
    return RatioFit(best, rms_flat, best_rms, tags)
