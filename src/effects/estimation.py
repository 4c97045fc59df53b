"""Estimation-stage effects: what the pose estimator assumes and how it detects and solves."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

from simgap.core.config import require
from simgap.effects.base import Effect, register
from simgap.effects.state import VariantState
from simgap.pose.detect import DetectorSettings
from simgap.pose.estimate import PnPSettings


def _estimation(state: VariantState, **changes) -> VariantState:
    return dataclasses.replace(state, estimation=dataclasses.replace(state.estimation, **changes))


@register
class Calibration(Effect):
    """The calibration the estimator believes in (px, Brown-Conrady); unset fields keep the rig's.

    Calibration errors move no pixel: they act on corners already detected.
    """

    name = "calibration"
    stage = "estimation"

    @dataclass(frozen=True)
    class Params:
        """Assumed intrinsics and distortion."""

        fx: float | None = None
        fy: float | None = None
        cx: float | None = None
        cy: float | None = None
        distortion: tuple[float, float, float, float, float] | None = None

        def __post_init__(self) -> None:
            require(all(v is None or v > 0 for v in (self.fx, self.fy)), "fx/fy: expected > 0 px")

    def apply(self, state: VariantState) -> VariantState:
        """Replace the assumed calibration's set fields."""
        changes = {k: v for k, v in dataclasses.asdict(self.params).items() if v is not None}
        if "distortion" in changes:
            changes["distortion"] = tuple(changes["distortion"])
        return _estimation(state, calibration=state.estimation.calibration.replace(**changes))


@register
class DetectorRefinement(Effect):
    """ArUco corner refinement method (NONE, SUBPIX, CONTOUR, APRILTAG)."""

    name = "detector_refinement"
    stage = "estimation"

    @dataclass(frozen=True)
    class Params:
        """Refinement method."""

        method: Literal["NONE", "SUBPIX", "CONTOUR", "APRILTAG"] = "SUBPIX"

    def apply(self, state: VariantState) -> VariantState:
        """Set the corner refinement."""
        det = dataclasses.replace(state.estimation.detector, corner_refinement=self.params.method)
        return _estimation(state, detector=det)


@register
class DetectorOverride(Effect):
    """All ArUco detector settings at once (see :class:`simgap.pose.detect.DetectorSettings`)."""

    name = "detector"
    stage = "estimation"
    Params = DetectorSettings

    def apply(self, state: VariantState) -> VariantState:
        """Replace the detector settings."""
        return _estimation(state, detector=self.params)


@register
class PnPMethod(Effect):
    """PnP solver used on the four corners (see :class:`simgap.pose.estimate.PnPSettings`)."""

    name = "pnp_method"
    stage = "estimation"
    Params = PnPSettings

    def apply(self, state: VariantState) -> VariantState:
        """Replace the PnP settings."""
        return _estimation(state, pnp=self.params)
