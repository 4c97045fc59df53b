"""Each configuration's pose noise from its corners' noise, propagated through PnP (issue 28).

How far a tag's pose moves with a tenth of a pixel of corner noise differs much between
configurations: a far, oblique tag's depth and rotation move millimetres, a near, frontal one's
do not. A simulation rendered at several render seeds measures it by its repeats
(:func:`simgap.analysis.gap.configuration_noise`): their spread is the pose's response to the
render's Monte Carlo noise. A converged render (``render.mode: converged``) has almost none
(two render seeds of the baseline differ by 0.09 mm in ty, docs/results/
converged_render_step4.md), so its repeats measure next to nothing, and the far, oblique tags
of a small capture weighed as much as the near ones and decided the choice between effects (the
public ``sample-focal`` simulated converged: camera_mount chosen over focal_length,
docs/results/converged_render_step5.md). Here the response is propagated instead: the pose is
solved again from the corners plus :data:`DRAWS` Gaussian draws of the capture's corner noise
(the same solver and calibration as the pipeline's), and the spread of the poses is that
configuration's noise.
"""

from __future__ import annotations

import numpy as np

from simgap.analysis.thresholds import FLIP_RAD
from simgap.core.rig import Rig
from simgap.effects.state import VariantState
from simgap.pose.estimate import estimate_pose, pose_error

#: Draws of the corner noise per configuration: the standard deviation of 32 draws is within
#: 13 % of the true one (one standard error, sqrt(1 / (2 (n - 1)))), small beside the factor of
#: 10-100 between near and far configurations.
DRAWS = 32
#: Seed of the draws (any fixed value: same capture, same noise).
SEED = 28


def propagated_pose_noise(
    corners: np.ndarray, sigma_px: float, rig: Rig, base: VariantState
) -> np.ndarray:
    """Standard deviation (N, 6) of the pose under corner noise of ``sigma_px`` (m, rad).

    Parameters
    ----------
    corners : ndarray (N, 4, 2)
        Detected corners of each configuration (px); NaN where none (the result is NaN there).
    sigma_px : float
        Standard deviation of each corner coordinate (px).
    rig : Rig
        The fixture (the tag's size, m).
    base : VariantState
        The simulation's state: its assumed calibration and PnP settings solve the poses.

    Notes
    -----
    A draw whose pose turns by more than :data:`~simgap.analysis.thresholds.FLIP_RAD` from the
    undisturbed one took the other branch of the square marker's planar ambiguity; it is left
    out, as such poses are out of the comparison itself (:func:`simgap.diagnosis.items.
    build_items`). The standard deviation uses ``ddof=1``.
    """
    cal, pnp = base.estimation.calibration, base.estimation.pnp
    rng = np.random.default_rng(SEED)
    out = np.full((len(corners), 6), np.nan)
    for i, c in enumerate(np.asarray(corners, float)):
        noise = rng.normal(0.0, sigma_px, (DRAWS, 4, 2))
        if not np.isfinite(c).all():
            continue
        nominal = estimate_pose(c, rig.tags.size, cal.matrix, cal.dist_coeffs, pnp)
        if nominal is None:
            continue
        moved = []
        for d in noise:
            est = estimate_pose(c + d, rig.tags.size, cal.matrix, cal.dist_coeffs, pnp)
            if est is None:
                continue
            delta = pose_error(est.pose, nominal.pose)
            if np.abs(delta[3:]).max() <= FLIP_RAD:
                moved.append(delta)
        if len(moved) >= 2:
            out[i] = np.std(moved, axis=0, ddof=1)
    return out
