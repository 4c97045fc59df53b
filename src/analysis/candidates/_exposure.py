"""The exposure candidate: least squares on the paper levels, a median where they cannot decide.

An exposure change multiplies the linear signal by ``2 ** ev`` before the frame is encoded, and a
median commutes with that scale and with the clipping at full scale: a tag's paper level (the
median of its paper pixels, :mod:`simgap.pose.image_stats`) becomes
``min(1, 2 ** ev * paper)``. Each tag therefore reads its own exposure change,
``log2(real paper / simulated paper)``, and where the real paper is clipped only a lower bound.

The fit is the least-squares scan of the other one-parameter candidates
(:class:`~simgap.analysis.candidates.AppearanceCandidate`) wherever its minimum is one value.
Where the capped misfit is flat over several scanned exposures (:data:`PLATEAU_REL`), clipped
tags have made every exposure beyond some value look alike and the search would return an
arbitrary point of the plateau. The fit is then the median over the tags of their own exposure
changes, the clipped ones right-censored (Kaplan-Meier), or, where more than half are clipped
and that median is not determined, the median with the clipped tags at their lower bounds: the
least exposure the evidence calls for (:func:`censored_median_ev`). The validation's truth is also a
median over the tags (of the light ratio, :func:`simgap.diagnosis.camera_truth.exposure_truth`).

Measured on development captures: where the scan had a plateau it returned exposures up to
1.9 EV too high, where this rule reads them at most 0.6 EV off; where the scan's minimum was one
value the tags' median was no better than least squares (a spot light's cone leaving part of the
tags in ambient light), so the scan is kept there (docs/results/design_evidence.md#exposure).

Where at least half of the readable tags are clipped, the paper says little beyond lower bounds
and both ways read low (by 0.6-0.8 EV on validation captures, enough for a camera mount to take
the place of true geometric effects in the chosen model). The black ink, some 20 times darker
than the paper, is not clipped there, and it reads the exposure of a clipped tag
(:func:`ink_exposures`), once calibrated on the unclipped tags: its exposure change is read
against theirs by paper, so a print or a light that makes the other camera's ink relatively
brighter (a different ink, flare, the glint of a laminate) is taken out. That calibration is
trusted only where the unclipped tags' ink follows their paper within the ink level's floor
(:data:`INK_AGREEMENT_EV`); a laminate's glint does not (its calibration read +0.87 to +1.20 EV on
five development captures with a hidden laminate, where the ink would have read up to +3.5 EV
for +1.05), and the rule above applies. Measured on the validation captures with a clipped
majority and agreeing ink, the ink brought errors of 0.6-0.8 EV down to 0.04-0.37 EV and left
the two the paper had read within 0.2 EV at 0.21-0.23 EV
(docs/results/design_evidence.md#exposure).
"""

from __future__ import annotations

import time

import numpy as np
from scipy import stats

from simgap.analysis.candidates._appearance import AppearanceCandidate, measuring_only
from simgap.analysis.candidates._fitting import Fit
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.gap import Items
from simgap.analysis.thresholds import image_floor
from simgap.effects.state import VariantState
from simgap.pose.image_stats import STAT_INDEX, linearise

#: A paper level above this (linear) is clipped: the median of the tag's paper pixels is at full
#: scale (255 DN; the median only reaches it when half the pixels are clipped), so the tag's
#: exposure change is a lower bound. 254 DN itself is a measured level.
CLIPPED_PAPER_LINEAR = float(linearise(254))
#: Fewest tags with a readable paper level for the censored median.
MIN_TAGS = 3
#: Scanned misfits within this share of the smallest are one plateau: the same predictions
#: (every simulated tag clipped) give the same misfit; measured on a development capture, eight
#: scanned exposures from +2.0 to +4.0 EV read one misfit and the next below 6 % more
#: (docs/results/design_evidence.md#exposure).
PLATEAU_REL = 1e-3
#: Share of the readable tags clipped from which the ink reads the clipped ones
#: (:func:`ink_exposures`): the paper's censored median is then no longer determined.
CLIPPED_MAJORITY = 0.5
#: The unclipped tags' ink must follow their paper within this (EV) for the ink to read the
#: clipped ones: the ink level's floor (:data:`~simgap.analysis.thresholds.IMAGE_FLOORS`), the
#: smallest change of it that matters.
INK_AGREEMENT_EV = image_floor("ink_linear")


def readable(real: np.ndarray, sim: np.ndarray) -> np.ndarray:
    """Tags whose paper levels read an exposure change: both positive, the simulated unclipped."""
    ok = np.isfinite(real) & np.isfinite(sim) & (real > 0) & (sim > 0)
    return ok & (sim <= CLIPPED_PAPER_LINEAR)


def tag_exposures(real: np.ndarray, sim: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each readable tag's exposure change ``log2(real / sim)`` (EV) and whether it is clipped.

    Parameters
    ----------
    real, sim : ndarray (N,)
        Real and simulated paper levels of the same tags (linear, fraction of full scale); the
        simulated ones without exposure change. Tags whose simulated level is clipped read no
        ratio and are left out.
    """
    ok = readable(real, sim)
    return np.log2(real[ok] / sim[ok]), real[ok] > CLIPPED_PAPER_LINEAR


def censored_median_ev(ev: np.ndarray, clipped: np.ndarray) -> float:
    """Median of per-tag exposure changes (EV), the ``clipped`` ones lower bounds.

    The Kaplan-Meier median (:func:`scipy.stats.ecdf` on :class:`scipy.stats.CensoredData`)
    where it is determined, else (more than half the tags clipped) the median with the clipped
    tags at their bounds: a lower bound of the median, the least exposure the tags call for. NaN
    with fewer than :data:`MIN_TAGS` tags.

    A normal distribution fitted to the censored sample (the Tobit model) reads a clipped
    majority from the spread of the unclipped tags, and did so better on synthetic tags with
    evenly spread ratios, but not on development captures, whose ratios are far from normal
    (spot-light cones, vignetting): +1.40 EV for a true +1.06 (this rule: +1.10), +1.84 for +1.58
    (+1.48), +1.66 for +1.38 (+1.21); better only for +1.91 (+2.03 against +1.31).
    """
    if ev.size < MIN_TAGS:
        return float("nan")
    if not clipped.any():
        return float(np.median(ev))
    sf = stats.ecdf(stats.CensoredData(uncensored=ev[~clipped], right=ev[clipped])).sf
    below = np.flatnonzero(sf.probabilities <= 0.5)
    return float(sf.quantiles[below[0]]) if below.size else float(np.median(ev))


def ink_exposures(
    real_paper: np.ndarray, sim_paper: np.ndarray, real_ink: np.ndarray, sim_ink: np.ndarray
) -> np.ndarray | None:
    """Per-tag exposure changes (EV) with the clipped tags read from their ink, or None.

    Each readable tag's exposure change is ``log2(real / sim)`` of its paper level; a clipped
    tag's is instead that of its ink level, less the calibration (the median over the unclipped
    tags of their ink's change minus their paper's), and never below its paper's lower bound.
    None where fewer than :data:`CLIPPED_MAJORITY` of the readable tags are clipped, fewer than
    :data:`MIN_TAGS` are unclipped to calibrate the ink on, or the calibration exceeds
    :data:`INK_AGREEMENT_EV` (module doc).

    Parameters
    ----------
    real_paper, sim_paper, real_ink, sim_ink : ndarray (N,)
        Paper and ink levels of the same tags (linear, fraction of full scale); the simulated
        ones without exposure change.
    """
    ok = readable(real_paper, sim_paper) & readable(real_ink, sim_ink)
    clipped = real_paper[ok] > CLIPPED_PAPER_LINEAR
    if ok.sum() < MIN_TAGS or clipped.mean() < CLIPPED_MAJORITY or (~clipped).sum() < MIN_TAGS:
        return None
    paper_ev = np.log2(real_paper[ok] / sim_paper[ok])
    ink_ev = np.log2(real_ink[ok] / sim_ink[ok])
    calibration = float(np.median(ink_ev[~clipped] - paper_ev[~clipped]))
    if abs(calibration) > INK_AGREEMENT_EV:
        return None
    return np.where(clipped, np.maximum(paper_ev, ink_ev - calibration), paper_ev)


class ExposureCandidate(AppearanceCandidate):
    """Exposure (``ev``, stops) fitted on the tags' paper levels (module doc)."""

    def __init__(self) -> None:
        super().__init__("exposure", ("paper_linear",), "ev", (-4.0, 4.0), 0.02)

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """The exposure that matches the tags' paper levels (module doc).

        The tags' median with a clipped majority read from their ink (:func:`ink_exposures`);
        else least squares or, where its misfit has a plateau, the tags' censored median.
        """
        t0 = time.perf_counter()
        paper, ink = STAT_INDEX["paper_linear"], STAT_INDEX["ink_linear"]
        # the scan's state at 0 EV (levels need no edge fits; the ink is measured with the paper)
        reference = measuring_only(self.apply(base, self.params(0.0)), self.fit_stats)
        sim = runner.stats(reference, items)
        real = items.required("real_stats")
        tags = ink_exposures(real[:, paper], sim[:, paper], real[:, ink], sim[:, ink])
        if tags is not None:
            ev = float(np.clip(np.median(tags), *self.bounds))
            misfit = self.misfit(runner, base, items, ev)
            return self.fitted(items, ev, misfit, t0, clipped_majority=True)
        grid, values = self.scan(runner, base, items)
        finite = values[np.isfinite(values)]
        if np.sum(finite <= finite.min(initial=np.inf) * (1.0 + PLATEAU_REL)) < 2:
            return self.refine(runner, base, items, grid, values, t0)
        ev = censored_median_ev(*tag_exposures(real[:, paper], sim[:, paper]))
        if not np.isfinite(ev):
            return self.refine(runner, base, items, grid, values, t0)
        ev = float(np.clip(ev, *self.bounds))
        return self.fitted(items, ev, self.misfit(runner, base, items, ev), t0, plateau=True)
