"""The ink and paper levels of tags that both laminate fits read (the level and the ratio model)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simgap.pose.image_stats import STAT_INDEX

#: 8-bit levels at or beyond which a real tag's paper or ink is clipped (no ratio).
CLIPPED_DN: tuple[float, float] = (2.0, 253.0)


@dataclass(frozen=True)
class TagLevels:
    """What the level model reads of each tag (:mod:`~simgap.analysis.candidates._gloss`, step 1).

    Attributes
    ----------
    real_ink, real_paper : ndarray (N,)
        Real linear levels (sRGB-linearised medians; fraction of full scale).
    sim_ink, sim_paper : ndarray (N,)
        Simulated (matte, the simulation's lights) linear levels.
    clipped, ink_clipped : ndarray of bool (N,)
        Real paper, real ink at or beyond :data:`CLIPPED_DN` (a lower bound of its level, no
        more: a glint can saturate the ink too).
    eye_from_tag : ndarray (N, 4, 4)
        Each tag's pose in the eyepoint frame (m).
    """

    real_ink: np.ndarray
    real_paper: np.ndarray
    sim_ink: np.ndarray
    sim_paper: np.ndarray
    clipped: np.ndarray
    ink_clipped: np.ndarray
    eye_from_tag: np.ndarray

    @classmethod
    def of(cls, real: np.ndarray, sim: np.ndarray, eye_from_tag: np.ndarray) -> TagLevels:
        """From real and simulated image statistics (N, S); tags missing a level left out."""
        col = {k: STAT_INDEX[k] for k in ("ink_linear", "paper_linear", "paper_dn", "ink_dn")}
        ok = np.isfinite(real[:, [col["ink_linear"], col["paper_linear"]]]).all(1) & np.isfinite(
            sim[:, [col["ink_linear"], col["paper_linear"]]]
        ).all(1)
        ok &= (sim[:, col["paper_linear"]] > 0) & (sim[:, col["ink_linear"]] > 0)
        ok &= real[:, col["ink_dn"]] > CLIPPED_DN[0]
        return cls(
            real[ok, col["ink_linear"]],
            real[ok, col["paper_linear"]],
            sim[ok, col["ink_linear"]],
            sim[ok, col["paper_linear"]],
            real[ok, col["paper_dn"]] >= CLIPPED_DN[1],
            real[ok, col["ink_dn"]] >= CLIPPED_DN[1],
            eye_from_tag[ok],
        )

    def __len__(self) -> int:
        return len(self.real_ink)
