"""Estimation-stage effects: what the pose estimator assumes and how it detects and solves."""

from __future__ import annotations

import dataclasses
from typing import ClassVar, Literal

from simgap.effects.base import Effect, EffectParams, param
from simgap.effects.state import VariantState
from simgap.pose.detect import DetectorSettings
from simgap.pose.estimate import PnPSettings


def _estimation(state: VariantState, **changes) -> VariantState:
    return dataclasses.replace(state, estimation=dataclasses.replace(state.estimation, **changes))


def _unset_or_positive(v: float | None) -> bool:
    return v is None or v > 0


class Calibration(Effect, name="calibration", stage="estimation"):
    """The calibration the estimator believes in (px; any OpenCV model, :mod:`simgap.core.lens`).

    Unset fields keep the rig's.

    Calibration errors move no pixel: they act on corners already detected.
    """

    class Params(EffectParams):
        """Assumed intrinsics and distortion."""

        fx: float | None = param(None, "> 0 px", _unset_or_positive, key="fx/fy")
        fy: float | None = param(None, "> 0 px", _unset_or_positive, key="fx/fy")
        cx: float | None = None
        cy: float | None = None
        distortion: tuple[float, ...] | None = None
        distortion_model: str | None = None

    def apply(self, state: VariantState) -> VariantState:
        """Replace the assumed calibration's set fields."""
        changes = {k: v for k, v in dataclasses.asdict(self.params).items() if v is not None}
        if "distortion" in changes:
            changes["distortion"] = tuple(changes["distortion"])
        return _estimation(state, calibration=state.estimation.calibration.replace(**changes))


class DetectorRefinement(Effect, name="detector_refinement", stage="estimation"):
    """ArUco corner refinement method (NONE, SUBPIX, CONTOUR, APRILTAG)."""

    class Params(EffectParams):
        """Refinement method."""

        method: Literal["NONE", "SUBPIX", "CONTOUR", "APRILTAG"] = "SUBPIX"

    def apply(self, state: VariantState) -> VariantState:
        """Set the corner refinement."""
        det = dataclasses.replace(state.estimation.detector, corner_refinement=self.params.method)
        return _estimation(state, detector=det)


class _Settings(Effect, stage="estimation"):
    """An estimation effect whose ``Params`` are one of the estimator's settings objects."""

    #: The field of the estimation stage (:class:`simgap.pose.tags.Estimation`) replaced.
    setting: ClassVar[str]

    def apply(self, state: VariantState) -> VariantState:
        """Replace the estimator's settings."""
        return _estimation(state, **{self.setting: self.params})


class DetectorOverride(_Settings, name="detector"):
    """All ArUco detector settings at once (see :class:`simgap.pose.detect.DetectorSettings`)."""

    Params = DetectorSettings
    setting = "detector"


class PnPMethod(_Settings, name="pnp_method"):
    """PnP solver used on the four corners (see :class:`simgap.pose.estimate.PnPSettings`)."""

    Params = PnPSettings
    setting = "pnp"
