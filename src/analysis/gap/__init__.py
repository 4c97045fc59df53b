"""The gap: where the sim-to-real gap lies, how large it is, and its evidence beyond pose means.

The gap field of a real dataset against its simulation, its noise and significant regions
(``_gap``); robust sizes of a gap (``_gap_size``) and the paired test of per-item residuals
(``_paired``); the scatter, detection and image-evidence tests (``_evidence``) and the image
evidence of result datasets (``_image_evidence``); each item's pose noise
(``_pose_noise``); the comparable items a fit and a score read (``_items``) and the evidence
channels that measure a prediction against them (``_channels``); the gap of a board's real photos
(``_photo_gap``) and the rig's own geometry fitted on it against an external reference
(``_rig_fit``).

The modules are private; other packages import the names of ``__all__`` from here.
"""

from __future__ import annotations

from simgap.analysis.gap._channels import (
    IMAGE_CHANNELS,
    NOISE_STATS,
    SCORED_STATS,
    Prediction,
    channel_misfits,
    corner_unit,
    detection_groups,
    detection_score,
    evidence_channels,
    frame_corner_noise,
    level_spread,
    root_sum_square,
)
from simgap.analysis.gap._evidence import (
    DetectionTest,
    ImageTest,
    ScatterTest,
    compare_stat,
    detection_pvalue,
    detection_tests,
    holm_reject,
    image_tests,
    line_residuals,
    paired_test,
    scatter_tests,
)
from simgap.analysis.gap._gap import (
    AxisGap,
    DetectionRates,
    GapField,
    RegionGap,
    align,
    axis_summary,
    detection_summary,
    distance_thirds,
    gap_field,
    item_noise,
    mean_error,
    region_summary,
)
from simgap.analysis.gap._gap_size import corner_score, gap_score, median_abs_gap
from simgap.analysis.gap._image_evidence import (
    VIEW_ANGLE_LABEL,
    image_stat_view,
    plot_image_stats,
    repeat_median_stats,
    tag_distance_and_view_angle,
)
from simgap.analysis.gap._items import Items
from simgap.analysis.gap._paired import (
    MIN_PAIRED_ITEMS,
    clearly_lower,
    item_centre_residuals_px2,
    item_residuals_px2,
)
from simgap.analysis.gap._photo_gap import (
    PHOTO_IMAGES,
    PhotoCameraFit,
    PhotoGaps,
    diagnose_photos,
    fit_photo_camera,
    photo_gaps,
    rig_corrected,
)
from simgap.analysis.gap._pose_noise import SHIFT_DRAWS, noise_shift, propagated_pose_noise
from simgap.analysis.gap._rig_fit import (
    RIG_MODELS,
    RigFit,
    RigModelFit,
    fit_rig,
    parameter_text,
    rig_error,
)

__all__ = [
    "AxisGap",
    "DetectionRates",
    "DetectionTest",
    "GapField",
    "ImageTest",
    "Items",
    "MIN_PAIRED_ITEMS",
    "NOISE_STATS",
    "PHOTO_IMAGES",
    "PhotoCameraFit",
    "PhotoGaps",
    "Prediction",
    "RIG_MODELS",
    "RegionGap",
    "RigFit",
    "RigModelFit",
    "SCORED_STATS",
    "IMAGE_CHANNELS",
    "level_spread",
    "SHIFT_DRAWS",
    "ScatterTest",
    "VIEW_ANGLE_LABEL",
    "align",
    "axis_summary",
    "channel_misfits",
    "clearly_lower",
    "compare_stat",
    "corner_score",
    "corner_unit",
    "detection_groups",
    "detection_pvalue",
    "detection_score",
    "detection_summary",
    "detection_tests",
    "diagnose_photos",
    "fit_rig",
    "distance_thirds",
    "evidence_channels",
    "fit_photo_camera",
    "photo_gaps",
    "frame_corner_noise",
    "gap_field",
    "gap_score",
    "holm_reject",
    "image_stat_view",
    "image_tests",
    "item_centre_residuals_px2",
    "item_noise",
    "item_residuals_px2",
    "line_residuals",
    "mean_error",
    "median_abs_gap",
    "noise_shift",
    "paired_test",
    "parameter_text",
    "plot_image_stats",
    "propagated_pose_noise",
    "region_summary",
    "repeat_median_stats",
    "rig_corrected",
    "root_sum_square",
    "rig_error",
    "scatter_tests",
    "tag_distance_and_view_angle",
]
