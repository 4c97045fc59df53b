"""The diagnosis's units and thresholds, each defined once with its source.

Every evidence channel of the diagnosis is measured in *units* of the smallest difference that
matters (corners, pose, detection, each image statistic); the thresholds below are stated in
those units or in the quantity's own (m, rad, px, share). Every value was fixed before the blind
validation runs that report on it (``docs/results/validation_*.md``); the source of each is given
where it is defined, the measurements behind it in docs/results/design_evidence.md#thresholds.
Modules import them from here, never retype them.

Sections: the practical floor of the pose gap and its significance (where), the evidence tests
(where), the channel units and when two models are told apart (which), the model search (which)
and the appearance gates (which).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Final

from simgap.analysis.paper import THRESHOLD_BY_UNIT

# -- where: the pose gap -----------------------------------------------------------------------

#: Share of the paper's high-precision thresholds below which a pose gap does not matter.
PRACTICAL_FLOOR_FRACTION: Final[float] = 0.1
#: Smallest pose gap that matters, per axis unit (m, rad): :data:`PRACTICAL_FLOOR_FRACTION` of
#: the high-precision thresholds (:data:`simgap.analysis.paper.THRESHOLD_BY_UNIT`, 0.005 m and
#: 0.0873 rad), so 0.5 mm and 8.7 mrad. Smaller systematic differences (another light or sensor
#: noise changing the detector's edge bias) are reported but not called significant. It is also
#: the unit of the pose channel where an item's own noise is smaller.
PRACTICAL_FLOOR: Final = MappingProxyType(
    {u: t * PRACTICAL_FLOOR_FRACTION for u, t in THRESHOLD_BY_UNIT.items()}
)
#: A pose gap (its median, its trend with distance, a region's median) is significant beyond
#: this many standard errors, and only when it also exceeds :data:`PRACTICAL_FLOOR`. Four
#: Gaussian standard errors: a two-sided false-alarm rate of 6.3e-5 per test, 7.6e-4 over the
#: 12 tests of a capture's axes (median and trend of six axes). Source: set a priori with the
#: first diagnosis, before any blind validation (docs/results/design_evidence.md#thresholds).
Z_SIGNIFICANT: Final[float] = 4.0
#: Pose noise of one gap value assumed per axis unit (m, rad) where a dataset is too short to
#: measure its own (fewer than 8 second differences along the carriage; without repeats). Set
#: with the first diagnosis (docs/results/design_evidence.md#thresholds); measured since on the
#: public sample-focal's 9 configurations simulated at 4 render seeds, one frame's pose noise
#: (median over items) is 0.014-0.36 mm per translation axis (depth, ty, the largest)
#: and 1.0-4.9 mrad per rotation axis: 0.2 mm and 4 mrad lie within those ranges.
DEFAULT_NOISE: Final = MappingProxyType({"m": 2e-4, "rad": 4e-3})
#: A rotation error beyond this (rad, 8.6 deg) is the other branch of a square marker's planar
#: pose ambiguity, not a gap an effect explains: catalogue effects move rotations by mrad, and
#: a noise-driven flip of one far tag in a 9-item capture decided which effect "explained" the
#: pose (:func:`simgap.diagnosis.items.build_items`).
FLIP_RAD: Final[float] = 0.15

# -- where: the evidence tests -----------------------------------------------------------------

#: Significance level: the family-wise false-alarm rate of each family of evidence tests (scatter
#: and image: Bonferroni over the tests of a family; detection: the overall test is the planned one,
#: the six regional ones Holm's step-down, :mod:`simgap.analysis.gap._evidence`).
SIGNIFICANCE_LEVEL: Final[float] = 0.01
#: Largest number of attempts (the smaller side of a 2 x 2 detection table) for which Boschloo's
#: exact test is run; beyond it Fisher's, whose power is then the same and which is far cheaper
#: (Boschloo on 540 x 2160 attempts: 7.6 s, measured).
BOSCHLOO_MAX_ATTEMPTS: Final[int] = 200
#: Smallest ratio of robust pose scatter (real / simulated, or its inverse) that matters.
SCATTER_RATIO: Final[float] = 1.5
#: The extra pose scatter must reach this share of the practical floor (0.25 mm / 4.4 mrad).
SCATTER_FLOOR_SHARE: Final[float] = 0.5
#: ``stat -> (compared as, floor)``: each image statistic is compared as a difference
#: (``"diff"``) or a log2 ratio (``"log2"``, stops), and its floor is the smallest median
#: difference that matters: the unit of that statistic's evidence channel. ``None`` floors are
#: reported only (the all-sides edge width is measured along x and y apart; rejected candidates
#: count the detector's work, not the image).
IMAGE_FLOORS: Final = MappingProxyType(
    {
        "ink_linear": ("log2", 0.5),
        "paper_linear": ("log2", 0.3),
        "contrast": ("diff", 0.05),
        "edge_width_px": ("diff", None),
        "edge_width_x_px": ("diff", 0.2),
        "edge_width_y_px": ("diff", 0.2),
        "noise_ink_linear": ("log2", 0.5),
        "noise_paper_linear": ("log2", 0.5),
        "clipped_fraction": ("diff", 0.02),
        # the shadows' share at 0 DN, read as the paper's at 255 is (the same floor); the most
        # crushed tag of a capture without a black level or tone curve: at most 0.015 in 45 of
        # 46 validation captures, 0.038 in one; with a black level at least 0.1 in 29 of 37
        # (docs/results/camera_pipeline.md)
        "black_clipped_fraction": ("diff", 0.02),
        "highlight_fraction": ("diff", 0.02),
        "rejected_candidates": ("diff", None),
        "blockiness": ("log2", 0.25),
    }
)


def image_floor(stat: str) -> float:
    """The floor of ``stat`` in :data:`IMAGE_FLOORS`; ValueError for one reported only (None)."""
    floor = IMAGE_FLOORS[stat][1]
    if floor is None:
        raise ValueError(f"{stat} has no floor: it is reported only, never scored")
    return floor


# -- which: channel units and telling models apart ---------------------------------------------

#: Unit of the corner channel (px): the ArUco detector's own corner bias on ideal renders
#: (~0.2 px, measured on them); a capture whose corner noise is larger uses that instead
#: (:func:`simgap.analysis.gap.corner_unit`).
CORNER_UNIT_PX: Final[float] = 0.2
#: Smallest difference of detection rates that matters (share of tags): the unit of the
#: detection channel and the practical floor of the detection tests.
DETECTION_UNIT: Final[float] = 0.05
#: Corner residuals (of scored items) closer than this are indistinguishable (px): a quarter of the
#: detector's own corner bias (:data:`CORNER_UNIT_PX`), ...
EQUIVALENT_PX: Final[float] = 0.05
#: ... or closer than this share of the smaller residual (any channel).
EQUIVALENT_REL: Final[float] = 0.1
#: Channel misfits (in channel units) closer than this are indistinguishable: the corner
#: channel's tolerance in its unit, a quarter unit, applied to every channel.
EQUIVALENT_UNITS: Final[float] = EQUIVALENT_PX / CORNER_UNIT_PX
#: Paired one-sided signed-rank test of per-item corner residuals
#: (:func:`simgap.analysis.gap.clearly_lower`): its false-alarm rate, and the
#: smallest median improvement as a share of the other model's median residual (a lens
#: distortion moves the central tags' corners by tenths of a pixel, consistently).
PAIRED_SIGNIFICANCE_LEVEL: Final[float] = 0.01
PAIRED_MIN_SHARE: Final[float] = 0.05
#: Image-statistic misfits beyond this many floors count as this many (a robust, Huber-like
#: cap): a difference nothing in the catalogue explains (a print whose ink is blacker than the
#: simulation's) is neither credited to nor blamed on an effect. The detection channel is
#: capped the same way (:func:`simgap.analysis.gap.evidence_channels`).
RESIDUAL_CAP: Final[float] = 3.0
#: A significant piece of evidence whose misfit (choose split) with the chosen model is at or above
#: this many channel units (one: the smallest difference that matters) is *unexplained*.
UNEXPLAINED_MISFIT: Final[float] = 1.0

# -- which: the model search -------------------------------------------------------------------

#: Share by which a geometric effect must bring the pose gap (all axes, choose split) closer to the
#: real one to enter a model (:meth:`simgap.analysis.search.ModelSearch.select`): between
#: the look-alikes (at most 6 % closer) and the true effects (at least 19 %) measured on
#: development captures (docs/results/design_evidence.md#thresholds).
MIN_POSE_REDUCTION: Final[float] = 0.10
#: A significant pose gap is *unexplained* when the chosen model lowers it (choose split) by less
#: than this share. Source: set a priori with the first diagnosis, before any blind run; correct
#: answers on blind captures lower it by far more (docs/results/design_evidence.md#thresholds).
EXPLAINED_REDUCTION: Final[float] = 0.3
#: An effect whose pose contribution (median change of the choose split's poses over their noise or
#: the practical floor, :meth:`simgap.analysis.search.ModelSearch.contributions`) is below
#: this moves no pose by a relevant amount: it is *minor* (one unit: the floor itself).
MINOR_CONTRIBUTION: Final[float] = 1.0
#: A projection effect (geometry or calibration) that moves no pose beyond the floor stays in a
#: model, as a minor effect, only where it moves the corners the model predicts by at least
#: this much (px, robust RMS over the scored items): the detector's own corner bias
#: (:data:`CORNER_UNIT_PX`), which another camera's light, edges and pipeline change by as much.
#: A smaller, consistent corner change is what the modelled appearance leaves of that, not a
#: calibration or a fixture the corners single out (:func:`simgap.analysis.search.pruned`).
#: Source: set a priori from the corner unit (docs/results/design_evidence.md#pruning).
MINOR_CORNER_SHIFT_PX: Final[float] = CORNER_UNIT_PX

#: A fitted parameter within this share of the end of its searched range (from the range's
#: largest magnitude) lies *on its bound*: the fit wanted to go further, so the model is a proxy
#: for something it cannot express, not a finding (measured: a defocus whose focus distance sat
#: at the search's 5 m or 0.1 m end, with a 0.07-0.2 mm aperture, rode along with right answers
#: in 6 of 28 captures of another generator; every true effect of the hidden tables lies inside
#: its range by a margin). 2 %: far below the ranges' margins over the hidden magnitudes.
AT_BOUND_SHARE: Final[float] = 0.02
#: Most effects a model may hold (:meth:`simgap.analysis.search.ModelSearch.select`). A real
#: camera brings up to three of its own (exposure, softness and sensor noise) beside the one or
#: two effects that make the gap. Source: blind captures where a full model of the camera's
#: own effects left no room for a lens distortion that lowered the corner gap beside them, so
#: it was never tried (raised from three to four to five;
#: docs/results/design_evidence.md#thresholds).
MAX_EFFECTS: Final[int] = 5
#: Single effects the greedy model search starts from (:meth:`simgap.analysis.search.
#: ModelSearch.select`): the best, and the next geometric ones among the first this many of the
#: ranking; the search's best answer over its starts is kept. One start follows a look-alike that
#: leads alone: a camera mount that leads a focal length and a print scale whose depth scales
#: nearly cancel is grown with a tag offset, and the true pair, which explains the evidence far
#: better, is never tried. Three: the mount, the focal length and the print scale are the first
#: three geometric effects of such a capture (measured: docs/results/design_evidence.md#selection).
MODEL_SEARCH_STARTS: Final[int] = 3
#: Largest corner gap (px, RMS over the choose split's items) a model with a geometric or
#: calibration effect may leave: geometry is fitted on the corners and, once the image formation
#: is modelled, explains them to the detector's bias. A model that leaves more has fitted the
#: geometry to corners that something else moved (a motion smear, an unmodelled defocus), and the
#: search is repeated without geometry. Four corner units (:data:`CORNER_UNIT_PX`): measured on
#: blind captures, every correct geometric model left at most 0.64 px, and most models with a
#: spurious geometric effect 0.97-2.11 px (docs/results/design_evidence.md#thresholds).
GEOMETRY_CORNER_GAP_PX: Final[float] = 4.0 * CORNER_UNIT_PX
#: A print scale (a size signature) enters a model only where the size change it explains grows
#: with the tag's image size by this many standard errors
#: (:mod:`simgap.analysis.candidates._size_signature`): the significance of :data:`Z_SIGNIFICANT`.
#: Measured on development captures, true print scales stand 10.6-34.2 standard errors out,
#: look-alikes 0.6-2.6, two defocused ones 6.0 and 8.9, which :data:`SIZE_ZERO_SHARE` catches
#: (docs/results/design_evidence.md#thresholds).
SIZE_SLOPE_Z: Final[float] = Z_SIGNIFICANT
#: ... and only where an edge offset against the slope does not cancel the size change before
#: this share of the smallest tag's size
#: (:attr:`simgap.analysis.candidates._size_signature.SizeChange.zero_share`). A print scale
#: changes no size at zero size (share 0; measured true ones at most 0.30); defocused look-alikes
#: cross zero near or inside the sizes measured (0.93 and 1.19;
#: docs/results/design_evidence.md#thresholds). Half: the offset is at most half the print's change
#: on the smallest tag.
SIZE_ZERO_SHARE: Final[float] = 0.5
#: The camera's pipeline moving the marker edges (``edge_offset``) is a candidate only where the
#: markers' size change real - simulated has an intercept (an edge offset, the same px at every
#: size) this many standard errors from zero
#: (:mod:`simgap.analysis.candidates._edge_offset`): the significance of :data:`Z_SIGNIFICANT`,
#: as the print scale's slope.
EDGE_OFFSET_Z: Final[float] = Z_SIGNIFICANT

# -- which: the appearance gates ---------------------------------------------------------------

#: An appearance effect is ranked only when one of its own statistics differs significantly in
#: the where step, differs by at least :data:`SIGNATURE_MIN_MISFIT` floors (RMS over the
#: fit split's tags), and the fit lowers that by :data:`SIGNATURE_MIN_GAIN`; else the evidence does
#: not call for it (a JPEG fitted where the blockiness matches within its floor would only be
#: credited for side effects on noise; on sample-null a JPEG passed the RMS gate on a
#: blockiness difference of +0.1 stop, p 0.06). One floor: the smallest difference that matters.
SIGNATURE_MIN_MISFIT: Final[float] = 1.0
#: The gain is the channels' tolerance, a quarter unit (:data:`EQUIVALENT_UNITS`).
SIGNATURE_MIN_GAIN: Final[float] = EQUIVALENT_UNITS
#: A light the simulation lacks (:mod:`simgap.analysis.candidates._sun`) is called for only where
#: what moves every tag's paper alike (one gain) leaves the paper levels at least this far off
#: (RMS over the tags, floors): half a floor, under which one gain fits every tag within the
#: paper's smallest difference that matters, and exposure is the simpler answer; and where the
#: sun then beats one gain and a transfer curve by :data:`SIGNATURE_MIN_GAIN`. Set a priori, not
#: fitted to any capture.
SUN_MIN_GAIN_MISFIT: Final[float] = 0.5
