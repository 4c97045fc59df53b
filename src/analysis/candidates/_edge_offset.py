"""The camera's pipeline moving the marker edges: :class:`EdgeOffsetCandidate`.

A real camera's pipeline (a black level, a tone curve that is not the simulation's sRGB,
demosaicing) moves the point where a soft dark-to-light edge reads as an edge by about the same
pixels on every marker, whatever its size (:class:`simgap.effects.camera_pipeline.EdgeOffset`).
The detected corners move with the sides: every marker looks larger or smaller by the same
pixels, and its pose nearer or farther by a share that grows with its distance, where a focal
length or a print scale change the size by a share, and the depth by the same share at every
distance. Left out of the model, such an offset is read as a focal length or a camera mount
(measured on blind captures through a camera's pipeline:
docs/results/design_evidence.md#edge_offset).

Its statistic is the intercept of the markers' size change real - simulated regressed on the
size (:func:`simgap.analysis.candidates.size_change`): the change at zero size, in px. It is a
candidate only where the capture's corners show one
(:meth:`EdgeOffsetCandidate.signature_shown`: at least
:data:`~simgap.analysis.thresholds.EDGE_OFFSET_Z` standard errors from zero), and is fitted by
rendering: the detector's corners move with the edges by a response that depends on the sign
(a marker that grows rounds its corners and gives up part of the move to its inner edges), so
the offset is found by a secant search on the rendered intercept, not by a corner formula. The
fitted offset moves the corners and poses as every simulation effect does, through the
pipeline. A property of the camera, reported beside its black level and softness, not a cause.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from simgap.analysis.candidates._appearance import signature_supported
from simgap.analysis.candidates._fitting import Fit, SimulationCandidate, on_bound
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.candidates._size_signature import size_change
from simgap.analysis.gap import ImageTest, Items
from simgap.analysis.thresholds import CORNER_UNIT_PX, EDGE_OFFSET_Z
from simgap.effects.state import VariantState

#: Largest edge offset searched (px): a pipeline's shift of a soft edge is a fraction of the
#: edge's width (1-3 px); the effect's valid range is 3 px.
OFFSET_BOUND_PX = 2.0
#: First offset rendered to measure the intercept's response (px): large enough that the
#: detector's corner noise does not drown the change, well inside the searched range.
PROBE_PX = 0.5
#: Secant steps after the probe (each one render of the fit items): the response is nearly
#: linear on each side of zero, so two steps leave the intercept within its noise.
SECANT_STEPS = 2
#: Halvings of a step whose render leaves too few tags detected to regress their sizes (an
#: edge moved far into small, soft markers breaks their cells apart).
BACKOFF_STEPS = 2


def _measurable(
    intercept: Callable[[float], float], start: float, offset: float
) -> tuple[float, float]:
    """``offset`` and its rendered intercept, halved back towards ``start`` while not finite.

    At most :data:`BACKOFF_STEPS` halvings; the last intercept may still be nan.
    """
    value = intercept(offset)
    for _ in range(BACKOFF_STEPS):
        if np.isfinite(value):
            break
        offset = 0.5 * (start + offset)
        value = intercept(offset)
    return offset, value


class EdgeOffsetCandidate(SimulationCandidate):
    """The camera's pipeline moving every marker edge by ``offset_px`` (module docstring)."""

    fit_stats: tuple[str, ...] = ()
    #: its evidence is the corners: it may stand in for a minor projection effect
    #: (:func:`simgap.analysis.search.corner_look_alikes`)
    moves_corners = True

    def __init__(self) -> None:
        super().__init__("edge_offset")

    def signature_shown(self, image_tests: list[ImageTest], runner: Runner, items: Items) -> bool:
        """Whether the capture's corners show an edge offset (module docstring).

        The size change real - simulated over ``items`` (every comparable tag) regressed on the
        simulated size: its intercept at least :data:`EDGE_OFFSET_Z` standard errors from zero.
        ``image_tests`` and ``runner`` are not read (the signature is in the corners); they keep
        the appearance candidates' call.
        """
        change = size_change(items.real_corners, items.sim_corners)
        return bool(np.isfinite(change.offset_z) and abs(change.offset_z) >= EDGE_OFFSET_Z)

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """The offset whose rendered intercept matches the capture's (px, module docstring).

        ``items.sim_corners`` are those of ``base`` (the simulation with the model's effects
        fitted before this one). ``extra``: ``supported`` (the offset explains its statistic:
        :func:`~simgap.analysis.candidates.signature_supported`, with the intercept in corner
        units, :data:`~simgap.analysis.thresholds.CORNER_UNIT_PX`), ``intercept_px`` (the
        capture's), ``intercept_left_px`` (what the fitted offset leaves) and ``at_bound``
        (the offset on the end of its searched range, :data:`OFFSET_BOUND_PX`).
        """
        t0 = time.perf_counter()
        target = size_change(items.real_corners, items.sim_corners).offset_px
        if not np.isfinite(target) or target == 0.0:
            nothing: dict[str, Any] = {
                "supported": False,
                "intercept_px": target,
                "intercept_left_px": target,
            }
            return Fit(self.effect, {"offset_px": 0.0}, time.perf_counter() - t0, nothing)
        reference = runner.corners(base, items)

        def intercept(offset: float) -> float:
            moved = runner.corners(self.apply(base, {"offset_px": offset}), items)
            return size_change(moved, reference).offset_px

        # secant search from no offset and a probe on the capture's side; an offset whose
        # render loses the small tags' detections (too few left to regress) is halved back
        x0, r0 = 0.0, 0.0
        x1, r1 = _measurable(intercept, x0, float(np.copysign(PROBE_PX, target)))
        for _ in range(SECANT_STEPS):
            if not np.isfinite(r1) or r1 == r0:
                break
            step = x1 + (target - r1) * (x1 - x0) / (r1 - r0)
            x2, r2 = _measurable(
                intercept, x1, float(np.clip(step, -OFFSET_BOUND_PX, OFFSET_BOUND_PX))
            )
            if not np.isfinite(r2):
                break
            x0, r0, x1, r1 = x1, r1, x2, r2
        left = target - r1 if np.isfinite(r1) else target
        supported = signature_supported(abs(target) / CORNER_UNIT_PX, abs(left) / CORNER_UNIT_PX)
        bound = ("offset_px",) if on_bound(x1, -OFFSET_BOUND_PX, OFFSET_BOUND_PX) else ()
        extra = {
            "supported": supported,
            "intercept_px": target,
            "intercept_left_px": left,
            "at_bound": bound,
        }
        return Fit(self.effect, {"offset_px": x1}, time.perf_counter() - t0, extra)


__all__ = ["EdgeOffsetCandidate"]
