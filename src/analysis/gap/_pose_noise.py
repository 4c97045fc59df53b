"""Each item's pose noise from its corners' noise, propagated through PnP.

How far a tag's pose moves with a tenth of a pixel of corner noise differs much between
items: a far, oblique tag's depth and rotation move millimetres, a near, frontal one's
do not. A simulation rendered at several render seeds measures it by its repeats
(:func:`simgap.analysis.gap.item_noise`): their spread is the pose's response to the
render's Monte Carlo noise. A converged render (``render.mode: converged``) has almost none
(two render seeds of the baseline differ by 0.09 mm in ty, docs/results/
converged_render_step8.md#step-4), so its repeats measure next to nothing, and the far, oblique tags
of a small capture weighed as much as the near ones and decided the choice between effects (the
public ``sample-focal`` simulated converged: camera_mount chosen over focal_length,
docs/results/converged_render_step8.md#step-5). Here the response is propagated instead: the pose is
solved again from the corners plus :data:`DRAWS` Gaussian draws of the capture's corner noise
(the same solver and calibration as the pipeline's), and the spread of the poses is that
item's noise.

The same draws also move the pose's centre: at a far, oblique tag PnP turns corner noise into a
one-sided error in depth and height (ty +10 mm at 16 spp where the 1024-spp reference is within
1 mm, benchmarks/far_tag_noise_bias.py). A capture's pose there carries that shift, a converged
simulation's does not, and the public ``sample-focal``'s ty gap fell below significance (3.7
standard errors; path traced 5.3). :func:`noise_shift` is the median of the pose under the
capture's corner noise minus the undisturbed pose: the pose a noise-free simulation would read
with the capture's noise (:func:`simgap.diagnosis.items.with_noise_shift`).
"""

from __future__ import annotations

import warnings

import numpy as np

from simgap.analysis.thresholds import FLIP_RAD
from simgap.core.rig import Rig
from simgap.effects.state import VariantState
from simgap.pose.estimate import estimate_pose, pose_error

#: Draws of the corner noise per item: the standard deviation of 32 draws is within
#: 13 % of the true one (one standard error, sqrt(1 / (2 (n - 1)))), small beside the factor of
#: 10-100 between near and far items.
DRAWS = 32
#: Seed of the draws (any fixed value: same capture, same noise).
SEED = 28
#: Draws of the corner noise per item for :func:`noise_shift`: the median of 64 draws
#: has a standard error of about 0.16 of the pose's spread (1.25 / sqrt(64)), 0.5 mm in ty at a
#: far, oblique tag whose shift is 2 mm (sample-focal, tag 1 at p 14).
SHIFT_DRAWS = 64
#: Seed of :func:`noise_shift`'s draws.
SHIFT_SEED = 29


def pose_draws(
    corners: np.ndarray,
    sigma_px: float,
    rig: Rig,
    base: VariantState,
    draws: int,
    seed: int,
    frames: int = 1,
) -> np.ndarray:
    """The pose minus the undisturbed pose under ``draws`` draws of corner noise (N, draws, 6).

    Parameters
    ----------
    corners : ndarray (N, 4, 2)
        Detected corners of each item (px); NaN where none (the result is NaN there).
    sigma_px : float
        Standard deviation of each corner coordinate in one frame (px).
    rig : Rig
        The fixture (the tag's size, m).
    base : VariantState
        The simulation's state: its assumed calibration and PnP settings solve the poses.
    draws : int
        Draws per item.
    seed : int
        Seed of the draws.
    frames : int
        Frames averaged in each draw (a capture's repeat mean over its frames at a pose).

    Returns
    -------
    ndarray (N, draws, 6)
        Pose differences (m, rad), the mean over the frames of a draw; NaN where no frame
        solved.

    Notes
    -----
    A frame whose pose turns by more than :data:`~simgap.analysis.thresholds.FLIP_RAD` from the
    undisturbed one took the other branch of the square marker's planar ambiguity; it is left
    out, as such poses are out of the comparison itself (:func:`simgap.diagnosis.items.
    build_items`).
    """
    cal, pnp = base.estimation.calibration, base.estimation.pnp
    rng = np.random.default_rng(seed)
    out = np.full((len(corners), draws, 6), np.nan)
    for i, c in enumerate(np.asarray(corners, float)):
        noise = rng.normal(0.0, sigma_px, (draws, frames, 4, 2))
        if not np.isfinite(c).all():
            continue
        nominal = estimate_pose(c, rig.tags.size, cal, pnp)
        if nominal is None:
            continue
        for j, draw in enumerate(noise):
            moved = []
            for d in draw:
                est = estimate_pose(c + d, rig.tags.size, cal, pnp)
                if est is None:
                    continue
                delta = pose_error(est.pose, nominal.pose)
                if np.abs(delta[3:]).max() <= FLIP_RAD:
                    moved.append(delta)
            if moved:
                out[i, j] = np.mean(moved, axis=0)
    return out


def propagated_pose_noise(
    corners: np.ndarray, sigma_px: float, rig: Rig, base: VariantState
) -> np.ndarray:
    """Standard deviation of the pose under corner noise of ``sigma_px``.

    Over :data:`DRAWS` draws of one frame (:func:`pose_draws`, flips left out), ``ddof=1``.

    Parameters
    ----------
    corners, sigma_px, rig, base
        As :func:`pose_draws` (px, px, the fixture, the simulation's state).

    Returns
    -------
    ndarray (N, 6)
        The standard deviation per axis (m, rad); NaN where fewer than two draws solved.
    """
    moved = pose_draws(corners, sigma_px, rig, base, DRAWS, SEED)
    n = np.isfinite(moved).all(-1).sum(-1)
    with warnings.catch_warnings():  # items with no corners are all-NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        std = np.nanstd(moved, axis=1, ddof=1)
    return np.where((n >= 2)[:, None], std, np.nan)


def noise_shift(
    corners: np.ndarray, sigma_px: float, rig: Rig, base: VariantState, frames: int = 1
) -> np.ndarray:
    """Median of the pose under corner noise minus the undisturbed pose.

    Over :data:`SHIFT_DRAWS` draws, each the mean of ``frames`` frames (:func:`pose_draws`).

    Parameters
    ----------
    corners, sigma_px, rig, base, frames
        As :func:`pose_draws` (px, px a coordinate of one frame, the fixture, the simulation's
        state, frames averaged in each draw).

    Returns
    -------
    ndarray (N, 6)
        The shift per axis (m, rad): 0 where ``sigma_px`` is 0, NaN where the corners are.
    """
    corners = np.asarray(corners, float)
    if sigma_px <= 0.0:
        return np.where(np.isfinite(corners).all(axis=(1, 2))[:, None], 0.0, np.full(6, np.nan))
    moved = pose_draws(corners, sigma_px, rig, base, SHIFT_DRAWS, SHIFT_SEED, frames)
    with warnings.catch_warnings():  # items with no corners are all-NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(moved, axis=1)
