"""Every tag of one frame: detected corners -> pose, error against the rig, image evidence.

The per-frame step shared by the simulated sweep (:mod:`simgap.pipeline.sweep`) and the ingest of
real captures (:mod:`simgap.pipeline.capture`): both hand over the detector's markers and the
estimator's settings (:class:`Estimation`: the calibration it assumes, detector, PnP) and get a
:class:`ConfigResult` in tag order.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from simgap.core.aruco import project_tag_corners
from simgap.core.axes import AXES
from simgap.core.config import OMIT_DEFAULT
from simgap.core.rig import CameraModel, Rig
from simgap.pose.detect import DetectorSettings
from simgap.pose.estimate import PnPSettings, estimate_pose, pose_error
from simgap.pose.image_stats import EDGE_WIDTH_STATS, STATS, MarkerLayout, tag_stats

RESULT_FIELDS = (
    "detected",
    "estimated",
    "error",
    "reproj_px",
    "corners",
    "image_stats",
    "auto_exposure_ev",
)
#: Corners per marker (TL, TR, BR, BL) and pixel coordinates per corner (u, v).
CORNERS, UV = 4, 2


@dataclass(frozen=True)
class Estimation:
    """What the estimator assumes and how it detects and solves.

    Attributes
    ----------
    calibration : CameraModel
        The camera model the estimator believes in (px, its OpenCV distortion model).
    detector : DetectorSettings
        ArUco detector settings.
    pnp : PnPSettings
        PnP solver settings.
    edge_widths : tuple of str
        The edge widths measured among the image statistics (default all of
        :data:`simgap.pose.image_stats.EDGE_WIDTH_STATS`; the others are NaN). Each is an
        edge-spread fit, most of the statistics' time: a search that reads none of them (an
        appearance fit of exposure, say) leaves them out.
    response : tuple of float or None
        The camera's measured response (relative exposure at each 8-bit code,
        :class:`simgap.pose.camera_response.CameraResponse`) the frames' levels are linearised
        with; None: the sRGB curve.
    """

    calibration: CameraModel = field(default_factory=CameraModel)
    detector: DetectorSettings = field(default_factory=DetectorSettings)
    pnp: PnPSettings = field(default_factory=PnPSettings)
    edge_widths: tuple[str, ...] = EDGE_WIDTH_STATS
    response: tuple[float, ...] | None = field(default=None, metadata=OMIT_DEFAULT)


def empty_tag_arrays(shape: tuple[int, ...]) -> dict[str, np.ndarray]:
    """Result arrays of leading ``shape``: none detected, NaN poses, corners and evidence.

    Parameters
    ----------
    shape : tuple of int
        Leading dimensions, e.g. ``(T,)`` tags or ``(V, R, T, P, Θ)``.

    Returns
    -------
    dict
        :data:`RESULT_FIELDS` -> array: ``detected`` bool; ``estimated`` and ``error`` (..., 6)
        (m, rad); ``reproj_px`` (px); ``corners`` (..., 4, 2) (px); ``image_stats`` (..., S);
        ``auto_exposure_ev`` (EV, the frame's, per tag).
    """
    return {
        "detected": np.zeros(shape, bool),
        "estimated": np.full(shape + (len(AXES),), np.nan),
        "error": np.full(shape + (len(AXES),), np.nan),
        "reproj_px": np.full(shape, np.nan),
        "corners": np.full(shape + (CORNERS, UV), np.nan),
        "image_stats": np.full(shape + (len(STATS),), np.nan),
        "auto_exposure_ev": np.full(shape, np.nan),
    }


@dataclass(frozen=True)
class ConfigResult:
    """Detection and pose results of one (p, theta) for every tag of the experiment (tag order)."""

    detected: np.ndarray  # (T,) bool
    estimated: np.ndarray  # (T, 6) global pose, NaN where not detected
    error: np.ndarray  # (T, 6)
    reproj_px: np.ndarray  # (T,)
    corners: np.ndarray  # (T, 4, 2) px
    image_stats: np.ndarray  # (T, S) image evidence, see simgap.pose.image_stats.STATS
    #: (T,) EV the camera's auto exposure chose for the frame (every tag the same; NaN without
    #: one); None in a result cached before it was kept, read as NaN
    auto_exposure_ev: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.auto_exposure_ev is None:
            object.__setattr__(self, "auto_exposure_ev", np.full(self.detected.shape, np.nan))

    def arrays(self) -> dict[str, np.ndarray]:
        """As a mapping for storage."""
        return {k: getattr(self, k) for k in RESULT_FIELDS}


def estimate_tags(
    rig: Rig, estimation: Estimation, tags, found: dict, p: int, theta: float
) -> ConfigResult:
    """Pose and error of every tag from detected corners (px), with the assumed calibration.

    Parameters
    ----------
    rig : Rig
        The fixture: tag size (m) and expected poses (the nominal CAD tree).
    estimation : Estimation
        Assumed calibration and PnP settings.
    tags : sequence of int
        Tag ids, in result order.
    found : dict
        Detected markers: tag id -> corners (4, 2) (px).
    p, theta : int, float
        Pin hole and turntable angle (rad).
    """
    out = ConfigResult(**empty_tag_arrays((len(tags),)))
    cal = estimation.calibration
    for i, tag in enumerate(tags):
        if tag not in found:
            continue
        out.detected[i] = True
        out.corners[i] = found[tag]
        est = estimate_pose(found[tag], rig.tags.size, cal, estimation.pnp)
        if est is None:
            continue
        out.estimated[i] = est.pose
        out.error[i] = pose_error(est.pose, rig.expected_pose(tag, p, theta))
        out.reproj_px[i] = est.reproj_px
    return out


def add_image_stats(
    out: ConfigResult,
    rig: Rig,
    estimation: Estimation,
    tags,
    gray: np.ndarray,
    offset: tuple[int, int],
    found: dict,
    rejected: list,
    p: int,
    theta: float,
    repeat: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
) -> None:
    """Fill ``out.image_stats`` (from :func:`estimate_tags`) with every visible tag's evidence.

    The evidence is measured around the detected corners, or around the corners expected from
    the nominal rig and the assumed calibration when the tag was not detected (then without the
    edge-spread fit, which needs accurate corners).

    Parameters
    ----------
    out : ConfigResult
        The tags' detections and poses; its ``image_stats`` are filled in place.
    rig, estimation, tags
        The fixture, the estimator's assumed calibration and PnP, and the tag ids.
    gray : ndarray of uint8
        The 8-bit grey frame, or a crop of it.
    offset : tuple of int
        Full-frame pixel of ``gray``'s top-left corner (px).
    found, rejected
        The detector's markers (tag id -> corners, px) and rejected candidates (px).
    p, theta
        Pin hole and turntable angle (rad).
    repeat : ndarray of uint8, optional
        Another grey frame of the same pose (same crop and offset): the temporal noise and the
        repeat gain are measured against it (else NaN).
    rgb : ndarray of uint8 (H, W, 3), optional
        The same frame in 8-bit RGB (same crop and offset as ``gray``): the colour fringe is
        measured from it (else NaN, and NaN where it is grey).
    """
    cal = estimation.calibration
    layout = MarkerLayout(rig.marker_cells(), rig.tags.quiet_zone_cells)
    for i, tag in enumerate(tags):
        if tag in found:
            corners, edge_widths = found[tag], estimation.edge_widths
        elif rig.is_visible(tag, p, theta):
            corners = project_tag_corners(rig.eyepoint_from_tag(tag, p, theta), rig.tags.size, cal)
            edge_widths = ()
        else:
            continue
        out.image_stats[i] = tag_stats(
            gray,
            corners,
            layout,
            offset,
            rejected,
            edge_widths,
            repeat,
            rgb=rgb,
            response=estimation.response,
        )
