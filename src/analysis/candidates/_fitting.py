"""Fit catalogue effects to a sim-to-real gap, each at the cheapest stage that models it.

Two kinds of candidate:

:class:`ProjectionCandidate`
    Effects that only move where the tag's corners project: the true camera (``focal_length``,
    ``principal_point``, ``lens_distortion``) and the true geometry (``camera_mount``,
    ``turntable_offset``, ``carriage_pitch``, ``tag_scale``, ``tag_offset``). The simulated
    detected corners are moved by the exact change of the projected corners and the pose is solved
    again, so the simulated detector's own bias is kept. Parameters are fitted by robust least
    squares on the *real* detected corners (px). Several are fitted jointly
    (:class:`simgap.analysis.candidates.ProjectionSet`).
:class:`SimulationCandidate`
    Effects whose change of the evidence comes from running the pipeline with them (cached renders
    are reused; only the stages the effect touches are recomputed): the appearance effects of
    :mod:`simgap.analysis.candidates._appearance`, fitted continuously on the image evidence.

The candidates of the diagnosis, keyed by effect name, are
:data:`simgap.analysis.candidates.CANDIDATES`.

Every candidate predicts the simulated error *with* the effect as the baseline simulated error
plus the effect's change; model choice is ``simgap.analysis.search._selection``.
"""

from __future__ import annotations

import abc
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from simgap.analysis.candidates._runner import Runner
from simgap.analysis.candidates._size_signature import size_change
from simgap.analysis.gap import ImageTest, Items, clearly_lower, item_residuals_px2
from simgap.analysis.thresholds import AT_BOUND_SHARE
from simgap.core import transforms as tf
from simgap.core.rig import Rig
from simgap.effects import make_effect
from simgap.effects.state import VariantState
from simgap.pose.estimate import estimate_pose, marker_object_points, pose_error


@dataclass
class Fit:
    """A fitted candidate: its effect parameters and what the solver left (no predictions).

    Attributes
    ----------
    effect : str
        Registered effect name (:data:`simgap.effects.EFFECTS`).
    params : dict
        Fitted effect parameters, in the units the effect's params declare.
    seconds : float
        Wall time of the fit (s).
    extra : dict
        Solver by-products: ``x`` (the solver's parameter vector, for joint fits and
        projections), ``corner_rms_px`` (corner residual on the fit split, px), ``train_misfit``,
        ``size_changes`` (per print-scale-like effect of a projection fit, the size change it has
        to explain, :func:`simgap.analysis.candidates.size_change`).
    """

    effect: str
    params: dict[str, Any]
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


def project_items(rig: Rig, camera, errors, tag_scale: float, items: Items) -> np.ndarray:
    """Image corners (N, 4, 2) of the items' tags with a true camera, geometry and print scale.

    Parameters
    ----------
    rig : Rig
        The fixture.
    camera : CameraModel
        The true camera (intrinsics and distortion).
    errors : FixtureErrors
        The true geometry.
    tag_scale : float
        Printed size over nominal size.
    items : Items
        Items (tag, p, theta).

    Returns
    -------
    ndarray (N, 4, 2)
        Corners TL, TR, BR, BL (px).
    """
    eye_from_tag = rig.eyepoints_from_tags(items.tag, items.p, items.theta, errors)
    cv_from_tag = tf.make(tf.GLOBAL_FROM_CV.T)[None] @ eye_from_tag
    obj = marker_object_points(rig.tags.size * tag_scale)
    pts = np.einsum("nij,kj->nki", cv_from_tag[:, :3, :3], obj) + cv_from_tag[:, None, :3, 3]
    return camera.project(pts).reshape(len(items), 4, 2)


def base_corners(rig: Rig, base: VariantState, items: Items) -> np.ndarray:
    """Image corners (N, 4, 2) of the items' tags as the simulation ``base`` projects them (px)."""
    s0 = base.scene
    return project_items(rig, s0.camera, s0.errors, s0.tag_scale, items)


#: Scale of the robust (soft L1) loss of the corner fits (px): corner residuals beyond it count
#: linearly (a tag detected with a corner off by a pixel does not lead the fit).
CORNER_LOSS_SCALE_PX = 0.5


def on_bound(value: float, low: float, high: float) -> bool:
    """Whether a fitted ``value`` lies on an end of its searched range ``[low, high]``.

    Within :data:`~simgap.analysis.thresholds.AT_BOUND_SHARE` of the range's largest magnitude
    from either end.
    """
    tolerance = AT_BOUND_SHARE * max(abs(low), abs(high))
    return bool(value <= low + tolerance or value >= high - tolerance)


class ProjectionCandidate:
    """An effect that only changes the projection of the tag corners (see module docstring).

    Parameters
    ----------
    effect : str
        Catalogue name.
    params : list of (name, scale, bound)
        Fitted parameters: effect parameter name (``name[i]`` for an element of a vector
        parameter), typical magnitude (for conditioning) and the largest magnitude searched
        (inside the effect's valid range). Fits start from zero (no effect).
    corner_signature : bool
        The effect's pattern in the corners is its own (a lens distortion: a radial shift that
        grows with the image radius, which no pose, print or mount change makes): it may enter
        a model on corner evidence that is clearly better item by item
        (:func:`simgap.analysis.search._scoring.corners_clearly_lower`) without bringing the pose
        closer (:meth:`simgap.analysis.search.ModelSearch.select`).
    size_signature : bool
        The effect changes every tag's image size by the same share (a print scale): it may enter
        a model only where the corners' size change grows with the tag's size
        (:mod:`simgap.analysis.candidates._size_signature`), not where it is an edge offset of an
        image effect.
    nested : int
        Fit the first ``nested`` parameters alone first (0: all at once); the others are
        released only where they lower the fitted items' own corner residuals consistently, item
        by item (:func:`simgap.analysis.gap.clearly_lower`: by at least 5 % of the median
        residual and at p < 0.01; an in-sample test, so on fewer than 7 items nothing is
        released). A lens's k2 beside k1 on tags that span a small part of the image radius is
        nearly degenerate with it: fitted always, it traded k1 for k2 on a lens without
        distortion and its corners on items it was not fitted on were worse (measured on a
        development capture: docs/results/design_evidence.md#fitting). :attr:`n_params` still counts
        every parameter (parsimony charges a lens for k2 whether or not it was released).
    """

    kind = "projection"
    #: no image statistic of its own: fitted on the corners, always a candidate
    fit_stats: tuple[str, ...] = ()

    def __init__(
        self,
        effect: str,
        params: list[tuple[str, float, float]],
        corner_signature: bool = False,
        size_signature: bool = False,
        nested: int = 0,
    ) -> None:
        self.effect = effect
        self.nested = nested
        self.corner_signature = corner_signature
        self.size_signature = size_signature
        self.names = [n for n, _, _ in params]
        self.x_scale = np.array([s for _, s, _ in params], float)
        self.bound = np.array([b for _, _, b in params], float)
        self.x0 = np.zeros(len(params))

    @property
    def n_params(self) -> int:
        """Number of fitted parameters (model complexity)."""
        return len(self.names)

    def effect_params(self, x: np.ndarray) -> dict[str, Any]:
        """Effect parameter mapping for a parameter vector."""
        out: dict[str, Any] = {}
        for name, value in zip(self.names, x, strict=True):
            if "[" in name:
                base, idx = name[:-1].split("[")
                vec = list(out.get(base, (0.0, 0.0, 0.0)))
                vec[int(idx)] = float(value)
                out[base] = tuple(vec)
            else:
                out[name] = float(value)
        return out

    def apply(self, base: VariantState, params: dict[str, Any]) -> VariantState:
        """The simulation's state with the effect at ``params``."""
        return make_effect(self.effect, params).apply(base)

    def _state(self, base: VariantState, x: np.ndarray) -> VariantState:
        return self.apply(base, self.effect_params(x))

    def without(self, x: np.ndarray, effect: str) -> np.ndarray:
        """The parameter vector ``x`` with ``effect``'s parameters set to no effect (zero)."""
        return np.zeros_like(x) if effect == self.effect else np.array(x, float)

    def parts(self) -> tuple[ProjectionCandidate, ...]:
        """The single effects fitted (this one; a joint set's members)."""
        return (self,)

    def corner_shift(
        self,
        rig: Rig,
        base: VariantState,
        x: np.ndarray,
        items: Items,
        reference: np.ndarray | None = None,
    ) -> np.ndarray:
        """Change of the projected corners (N, 4, 2) caused by the effect (px).

        ``reference``: the corners projected with ``base`` (:func:`base_corners`), where the
        caller holds them already (a fit evaluates many ``x`` on the same items).
        """
        if reference is None:
            reference = base_corners(rig, base, items)
        s1 = self._state(base, x).scene
        return project_items(rig, s1.camera, s1.errors, s1.tag_scale, items) - reference

    def fit(self, rig: Rig, base: VariantState, items: Items) -> Fit:
        """Robust least squares on corners: real = sim + shift(x) (px)."""
        t0 = time.perf_counter()
        target = items.real_corners
        ok = np.isfinite(target).all(axis=(1, 2)) & np.isfinite(items.sim_corners).all(axis=(1, 2))
        if not ok.any():  # no item detected on both sides: nothing to fit, no change
            x = np.zeros(self.n_params)
            extra = {"x": x, "corner_rms_px": float("nan"), "at_bound": (), "size_changes": {}}
            return Fit(self.effect, self.effect_params(x), time.perf_counter() - t0, extra)
        sub = items.subset(np.flatnonzero(ok))
        goal = (target[ok] - sub.sim_corners).ravel()
        reference = base_corners(rig, base, sub)

        def residual(x):
            return self.corner_shift(rig, base, x * self.x_scale, sub, reference).ravel() - goal

        x, fun = self._solve(residual, np.ones(self.n_params, bool))
        low = self.low_order()
        if not low.all():
            x_low, fun_low = self._solve(residual, low)
            if not clearly_lower(item_residuals_px2(fun), item_residuals_px2(fun_low)):
                x, fun = x_low, fun_low
        x = x * self.x_scale
        rms = float(np.sqrt(np.mean(fun**2))) if fun.size else float("nan")
        at_bound = tuple(
            n for n, v, b in zip(self.names, x, self.bound, strict=True) if on_bound(v, -b, b)
        )
        # what each print-scale-like effect has to explain: the corners fitted without it
        size_changes = {
            m.effect: size_change(
                sub.real_corners,
                sub.sim_corners
                + self.corner_shift(rig, base, self.without(x, m.effect), sub, reference),
            )
            for m in self.parts()
            if m.size_signature
        }
        return Fit(
            self.effect,
            self.effect_params(x),
            time.perf_counter() - t0,
            {"x": x, "corner_rms_px": rms, "at_bound": at_bound, "size_changes": size_changes},
        )

    def low_order(self) -> np.ndarray:
        """Which parameters a nested fit frees first (bool (n_params,); all: not nested)."""
        index = np.arange(self.n_params)
        return index < self.nested if self.nested else np.ones(self.n_params, bool)

    def _solve(self, residual, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Robust least squares of the ``free`` parameters (bool mask; the others zero).

        Returns the scaled parameter vector and the residuals at the solution (px).
        """
        lim = (self.bound / self.x_scale)[free]

        def solved(x_free):
            x = np.zeros(self.n_params)
            x[free] = x_free
            return x

        sol = least_squares(
            lambda x_free: residual(solved(x_free)),
            self.x0[free],
            bounds=(-lim, lim),
            loss="soft_l1",
            f_scale=CORNER_LOSS_SCALE_PX,
            max_nfev=200,
        )
        return solved(sol.x), sol.fun

    def delta(self, rig: Rig, base: VariantState, fit: Fit, items: Items) -> np.ndarray:
        """Change of the simulated error (N, 6) when the fitted effect is added (m, rad)."""
        x = fit.extra["x"]
        shift = self.corner_shift(rig, base, x, items)
        cal = base.estimation.calibration
        out = np.full((len(items), 6), np.nan)
        for i in range(len(items)):
            c = items.sim_corners[i]
            if not np.isfinite(c).all():
                continue
            exp = rig.expected_pose(int(items.tag[i]), float(items.p[i]), float(items.theta[i]))
            a = estimate_pose(c, rig.tags.size, cal, base.estimation.pnp)
            b = estimate_pose(c + shift[i], rig.tags.size, cal, base.estimation.pnp)
            if a is not None and b is not None:
                out[i] = pose_error(b.pose, exp) - pose_error(a.pose, exp)
        return out


class SimulationCandidate(abc.ABC):
    """An effect whose change of the evidence comes from running the pipeline with it.

    Subclasses fit the parameters (:class:`simgap.analysis.candidates.AppearanceCandidate` on
    the image evidence); this class turns fitted parameters into a variant state and the change
    of the simulated errors.

    Parameters
    ----------
    effect : str
        Catalogue name.
    """

    kind = "simulation"
    n_params = 1

    def __init__(self, effect: str) -> None:
        self.effect = effect

    def apply(self, base: VariantState, params: dict[str, Any]) -> VariantState:
        """The simulation's state with the effect at ``params``."""
        return make_effect(self.effect, params).apply(base)

    @abc.abstractmethod
    def signature_shown(self, image_tests: list[ImageTest], runner: Runner, items: Items) -> bool:
        """Whether the capture shows this effect's signature, so that it is a candidate.

        ``image_tests`` are the where step's tests over every comparable tag and ``items`` those
        tags (each subclass reads what its signature is in).
        """

    @abc.abstractmethod
    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """The effect's parameters fitted on ``items`` under ``base`` (each subclass's own)."""

    def delta(self, runner: Runner, base: VariantState, fit: Fit, items: Items) -> np.ndarray:
        """Change of the simulated error (N, 6) with the fitted effect (m, rad)."""
        return runner.errors(self.apply(base, fit.params), items) - runner.errors(base, items)


#: A candidate effect of the diagnosis: fitted on the corners or by running the pipeline.
Candidate = ProjectionCandidate | SimulationCandidate
