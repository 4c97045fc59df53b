"""The diagnosis catalogue: every candidate effect, keyed by effect name, in one table.

Geometric and calibration effects are projection candidates
(:class:`~simgap.analysis.candidates.ProjectionCandidate`): fitted on the detected corners, with per
parameter its typical magnitude (for conditioning) and the largest magnitude searched (inside the
effect's valid range). Appearance effects are fitted on
the image statistics named with them (:mod:`simgap.analysis.candidates._appearance`,
:mod:`simgap.analysis.candidates._exposure`, :mod:`simgap.analysis.candidates._black_level`,
:mod:`simgap.analysis.candidates._sensor_noise`, :mod:`simgap.analysis.candidates._defocus`,
:mod:`simgap.analysis.candidates._gloss`, :mod:`simgap.analysis.candidates._sun`; the
camera's pipeline moving the marker edges on the corners' sizes,
:mod:`simgap.analysis.candidates._edge_offset`); those
statistics are also their signature: an appearance effect is a candidate only where the
capture shows it (:meth:`simgap.analysis.candidates.AppearanceCandidate.signature_shown`: one of
them differs significantly, for the laminate the ink-to-paper ratios call for one, for a sun the
paper levels against the way the tags face).

A new candidate is one entry here. The order of the table is the order in which candidates are
fitted and, among equally good ones, ranked.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from simgap.analysis.candidates._appearance import AppearanceCandidate, JpegCandidate
from simgap.analysis.candidates._black_level import BlackLevelCandidate
from simgap.analysis.candidates._defocus import DefocusCandidate
from simgap.analysis.candidates._edge_offset import EdgeOffsetCandidate
from simgap.analysis.candidates._exposure import ExposureCandidate
from simgap.analysis.candidates._fitting import Candidate, ProjectionCandidate
from simgap.analysis.candidates._gloss import GlossCandidate
from simgap.analysis.candidates._sensor_noise import SensorNoiseCandidate
from simgap.analysis.candidates._sun import SunCandidate

#: Edge widths along x and y (the all-sides width is reported only).
EDGE_WIDTHS = ("edge_width_x_px", "edge_width_y_px")

#: Effect name -> its candidate.
CANDIDATES: Mapping[str, Candidate] = MappingProxyType(
    {
        c.effect: c
        for c in (
            ProjectionCandidate("focal_length", [("scale", 0.01, 0.25)]),
            ProjectionCandidate("principal_point", [("dx_px", 5.0, 150.0), ("dy_px", 5.0, 150.0)]),
            ProjectionCandidate(
                "lens_distortion",
                [("k1", 0.05, 1.5), ("k2", 0.1, 1.5)],
                corner_signature=True,
                nested=1,
            ),
            ProjectionCandidate(
                "camera_mount",
                [(f"translation_m[{i}]", 0.002, 0.04) for i in range(3)]
                + [(f"rotation_rad[{i}]", 0.01, 0.25) for i in range(3)],
            ),
            ProjectionCandidate("turntable_offset", [("angle_rad", 0.01, 0.4)]),
            ProjectionCandidate("carriage_pitch", [("scale", 0.01, 0.15)]),
            ProjectionCandidate("tag_scale", [("scale", 0.01, 0.25)], size_signature=True),
            ProjectionCandidate("tag_offset", [(f"offset_m[{i}]", 0.001, 0.015) for i in range(3)]),
            AppearanceCandidate("blur", EDGE_WIDTHS, "sigma_px", (0.05, 3.0), 0.02),
            # the paper level: ink near black is flare and print, not exposure
            ExposureCandidate(),
            # the camera's own crushed shadows: its share of a tag at 0 DN
            BlackLevelCandidate((ExposureCandidate(), SensorNoiseCandidate())),
            SensorNoiseCandidate(),
            DefocusCandidate(),
            # the camera's pipeline moving the marker edges: the markers' size change at zero size
            EdgeOffsetCandidate(),
            JpegCandidate(
                "jpeg", ("blockiness",), "quality", (5.0, 100.0), 1.0, noise=SensorNoiseCandidate()
            ),
            GlossCandidate(),
            SunCandidate(),
        )
    }
)


def geometric_effects() -> set[str]:
    """Names of the geometric and calibration effects of the catalogue (projection effects)."""
    return {name for name, c in CANDIDATES.items() if isinstance(c, ProjectionCandidate)}
