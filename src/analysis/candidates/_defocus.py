"""Thin-lens defocus fitted on edge width against tag depth.

The appearance candidate ``defocus`` (:class:`DefocusCandidate`): aperture radius and focus
distance of a thin lens from how the edges widen with depth, beyond the simulation's own edge
width; rendered once with the fitted lens for scoring.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from simgap.analysis.candidates._appearance import (
    AppearanceCandidate,
    capped_rms,
    signature_supported,
)
from simgap.analysis.candidates._fitting import Fit, on_bound
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.gap import Items
from simgap.analysis.thresholds import IMAGE_FLOORS, SIGNATURE_MIN_GAIN
from simgap.effects.state import VariantState
from simgap.pose.image_stats import STAT_INDEX

#: 10-90 % width of the edge-spread function of a uniform disk of radius R, in units of R
#: (the area of a disk left of a chord at -u R is 10 % of the disk for u = 0.68705).
DISK_10_90_PER_RADIUS = 2 * 0.68705
#: Searched ranges of the thin lens: aperture radius (mm) and focus (dioptres, 1/m; a focus
#: distance of 0.1 m to 100 m). The far end is no bound: a lens focused at infinity is a lens
#: as it is (a fixed-focus module), and at the fixture's depths (at most about 2 m, 0.5
#: dioptres) 100 m differs from infinity by 2 % of the nearest term. A far end of 5 m left a lens
#: fitted on a blind capture out as on its bound (docs/results/design_evidence.md#defocus).
APERTURE_MM: tuple[float, float] = (0.0, 5.0)
FOCUS_DIOPTRES: tuple[float, float] = (0.01, 10.0)


class DefocusCandidate(AppearanceCandidate):
    """Thin-lens defocus: aperture radius and focus distance from edge width against depth.

    A point at depth ``z`` is imaged as a disk of radius ``R = f A |1/z - 1/z_f|`` (px; ``f`` the
    simulated camera's focal length in px, :attr:`simgap.analysis.candidates.Runner.focal_px`; ``A``
    the aperture radius; ``z_f`` the focus distance; the model of
    :class:`simgap.render.camera.OpenCVCamera`). The real edge width is modelled as the
    simulation's combined in quadrature with the disk's edge-spread width
    (:data:`DISK_10_90_PER_RADIUS` ``* R``); ``A`` and ``1 / z_f`` are fitted by bounded robust
    least squares over the fit split's tags.
    """

    n_params = 2
    #: Samples per pixel of its renders: the thin lens adds Monte Carlo noise that a 16-spp
    #: render turns into corner noise the real camera does not have (a square, 8 x 8, as the
    #: multijitter sampler takes it). At 36 spp that noise decided against a correctly fitted lens
    #: on development captures: its choose-split corners were worse than a blur's although it
    #: lowered the pose gap more (docs/results/design_evidence.md#defocus). Path tracing only:
    #: a converged render's thin-lens stickers carry no such noise (their footprints are clipped
    #: per aperture point, docs/results/converged_render_step8.md#step-5), so it keeps the
    #: simulation's samples.
    SPP = 64

    def __init__(self) -> None:
        stats = ("edge_width_x_px", "edge_width_y_px")
        super().__init__("defocus", stats, "aperture_radius_m", (0.0, 0.005), 0.0)

    def apply(self, base: VariantState, params: dict[str, Any]) -> VariantState:
        """The state with the thin lens, path traced at :data:`SPP` samples per pixel."""
        state = super().apply(base, params)
        if state.scene.quality.mode != "path":
            return state
        quality = dataclasses.replace(
            state.scene.quality, spp=max(state.scene.quality.spp, self.SPP)
        )
        return dataclasses.replace(state, scene=dataclasses.replace(state.scene, quality=quality))

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """Least squares of the thin-lens edge-width model."""
        t0 = time.perf_counter()
        i = STAT_INDEX["edge_width_px"]
        w_real, w_sim = items.required("real_stats")[:, i], items.required("sim_stats")[:, i]
        depth, focal_px = runner.depths(items), runner.focal_px
        ok = np.isfinite(w_real) & np.isfinite(w_sim) & np.isfinite(depth)
        w_real, w_sim, depth = w_real[ok], w_sim[ok], depth[ok]
        floor = IMAGE_FLOORS["edge_width_x_px"][1]

        def residual(x: np.ndarray) -> np.ndarray:
            radius = focal_px * x[0] * 1e-3 * np.abs(1.0 / depth - x[1])
            pred = np.sqrt(w_sim**2 + (DISK_10_90_PER_RADIUS * radius) ** 2)
            return (pred - w_real) / floor

        if depth.size < 3:
            return Fit(self.effect, {"aperture_radius_m": 0.0, "focus_distance_m": 1.0}, 0.0, {})
        starts = [(0.5, 1.0 / zf) for zf in (0.15, 0.4, 1.0, 3.0, 30.0)]
        lens_bounds = tuple(zip(APERTURE_MM, FOCUS_DIOPTRES, strict=True))  # (lower, upper)
        best = min(
            (least_squares(residual, x0=x0, bounds=lens_bounds, loss="soft_l1") for x0 in starts),
            key=lambda s: s.cost,
        )
        rms_before = capped_rms(residual(np.array([0.0, best.x[1]])))
        rms_after = capped_rms(residual(best.x))

        def constant(c: np.ndarray) -> np.ndarray:  # the same widening at every depth
            return (np.sqrt(w_sim**2 + c[0] ** 2) - w_real) / floor

        flat = least_squares(constant, x0=[0.5], bounds=([0.0], [20.0]), loss="soft_l1")
        rms_constant = capped_rms(constant(flat.x))
        depth_dependent = rms_constant - rms_after >= SIGNATURE_MIN_GAIN
        # on a bound: an aperture too small to widen an edge, or the near end of the focus;
        # a far focus (down to 0.01 dioptres) is a value (see FOCUS_DIOPTRES)
        at_bound = tuple(
            name
            for name, hit in (
                ("aperture_radius_m", on_bound(best.x[0], *APERTURE_MM)),
                ("focus_distance_m", on_bound(best.x[1], -FOCUS_DIOPTRES[1], FOCUS_DIOPTRES[1])),
            )
            if hit
        )
        return Fit(
            self.effect,
            {
                "aperture_radius_m": float(best.x[0] * 1e-3),
                "focus_distance_m": float(1.0 / best.x[1]),
            },
            time.perf_counter() - t0,
            {
                "train_cost": float(best.cost),
                # the edge widths must call for a lens, as for every appearance effect: without
                # this gate a lens too small to widen any edge was credited for the lower
                # render noise of its 36-spp renders (the pose scatter), not for defocus; and
                # the widening must change with depth, the lens's own signature: one widening
                # at every depth is softness, which the blur names more simply (a far focus
                # otherwise fits a soft camera with no hidden effect:
                # docs/results/design_evidence.md#defocus)
                "supported": signature_supported(rms_before, rms_after) and depth_dependent,
                "edge_width_rms_constant": rms_constant,
                "edge_width_rms_lens": rms_after,
                # a lens's signature is a widening that changes with depth: where it does,
                # beyond what one widening at every depth explains, a depth-independent blur
                # is not the explanation (measured on a development capture: a true lens tied
                # with a blur on the choose split's evidence and parsimony chose the blur;
                # docs/results/design_evidence.md#defocus)
                "excludes": ("blur",) if depth_dependent else (),
                "at_bound": at_bound,
            },
        )
