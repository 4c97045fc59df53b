"""The camera's black level: its crushed shadows, fitted on the share of a tag at 0 DN.

A camera whose black-level correction subtracts more than its sensor's offset (or whose
contrast setting clips the shadows) reads dark ink as 0 DN
(:class:`simgap.effects.camera_pipeline.BlackLevel`). The clipped ink moves the edges the
corners are refined on, so a simulation without it can read the shift as geometry (a focal
length answered as a camera mount along the optical axis; docs/results/camera_pipeline.md).

Which ink pixels a level crushes depends on the ink's level and noise: on a converged
simulation every ink pixel of a tag has one level, so its share at 0 DN jumps from none to all
of the ink as the level passes it, while a capture's noise spreads it. The level is therefore
matched on the simulation with the capture's own exposure and sensor noise, each fitted first
where its own statistics call for it (the nuisance fitted jointly, as JPEG's quality is matched
under the capture's noise, :class:`simgap.analysis.candidates._appearance.JpegCandidate`).
"""

from __future__ import annotations

import time

import numpy as np

from simgap.analysis.candidates._appearance import SCAN_POINTS, AppearanceCandidate
from simgap.analysis.candidates._fitting import Fit
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.gap import Items
from simgap.effects.state import VariantState

#: Levels searched (fraction of full scale): from none to a level that crushes the ink of a
#: capture exposed two stops brighter than the drawn cameras' largest (0.06, validate's
#: nuisance).
LEVEL_BOUNDS = (0.001, 0.15)


class BlackLevelCandidate(AppearanceCandidate):
    """The black level (``level``, fraction of full scale) fitted on the share at 0 DN.

    Parameters
    ----------
    nuisance : tuple of AppearanceCandidate
        The camera's own effects the share depends on (its exposure, its sensor noise), fitted
        in turn, each on the simulation with the ones before it, and applied where their fit is
        supported (module doc).
    """

    def __init__(self, nuisance: tuple[AppearanceCandidate, ...] = ()) -> None:
        super().__init__("black_level", ("black_clipped_fraction",), "level", LEVEL_BOUNDS, 0.0005)
        self.nuisance = nuisance

    def fit(self, runner: Runner, base: VariantState, items: Items) -> Fit:
        """The level whose share at 0 DN matches the capture's under its own nuisance."""
        t0 = time.perf_counter()
        state = base
        for cand in self.nuisance:
            fit = cand.fit(runner, state, items)
            if fit.extra.get("supported", False):
                state = cand.apply(state, fit.params)
        grid, values = self.scan(runner, state, items)
        return self.refine(runner, state, items, grid, values, t0)

    def scan(
        self, runner: Runner, base: VariantState, items: Items
    ) -> tuple[np.ndarray, np.ndarray]:
        """The misfit at :data:`SCAN_POINTS` log-spaced levels.

        A level's share at 0 DN changes most where it nears the ink's level: a few thousandths
        of full scale for dark ink, hundredths for bright.
        """
        grid = np.geomspace(*self.bounds, SCAN_POINTS)
        return grid, np.array([self.misfit(runner, base, items, x) for x in grid])


__all__ = ["BlackLevelCandidate", "LEVEL_BOUNDS"]
