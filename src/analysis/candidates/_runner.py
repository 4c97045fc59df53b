"""What the diagnosis needs of the pipeline: the simulated evidence of items under a state.

The model search (:class:`simgap.analysis.search.ModelSearch`) and the simulation-fitted
candidates (:mod:`simgap.analysis.candidates._appearance`) run variant states of the simulation
through the pipeline, which sits below analysis in the layers only as data: the pipeline itself is
reached through a :class:`Runner` the caller injects
(:class:`simgap.diagnosis.sim_runner.SimRunner`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from simgap.analysis.gap import Items
    from simgap.effects.state import VariantState


class Runner(Protocol):
    """Simulated evidence of diagnosis items under a variant state (cached, memoised).

    Attributes
    ----------
    focal_px : float
        Focal length of the simulated camera (px): the capture's calibration.
    """

    focal_px: float

    def errors(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-mean simulated pose errors (N, 6) of ``items`` under ``state`` (m, rad)."""
        ...

    def corners(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-mean detected corners (N, 4, 2) of ``items`` under ``state`` (px)."""
        ...

    def stats(self, state: VariantState, items: Items) -> np.ndarray:
        """Repeat-median image statistics (N, S) of ``items`` under ``state``."""
        ...

    def detected(self, state: VariantState, items: Items) -> np.ndarray:
        """Detection rate over repeats (N,) of ``items`` under ``state`` (0-1)."""
        ...

    def depths(self, items: Items) -> np.ndarray:
        """Depth of each item's tag along the optical axis, nominal rig (N,) (m)."""
        ...

    def eye_from_tag(self, items: Items) -> np.ndarray:
        """Pose of each item's tag in the eyepoint frame, nominal rig (N, 4, 4) (m)."""
        ...

    def rail_from_tag(self, items: Items) -> np.ndarray:
        """Pose of each item's tag in the rail frame, nominal rig (N, 4, 4) (m)."""
        ...

    def irradiance(self, items: Items) -> np.ndarray:
        """Direct irradiance of the simulation's own lights at each item's tag (N,) (W m^-2)."""
        ...
