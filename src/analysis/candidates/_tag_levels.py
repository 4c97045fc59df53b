"""The ink and paper levels of tags that both laminate fits read (the level and the ratio model)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simgap.pose.image_stats import STAT_INDEX, linearise

#: 8-bit levels at or beyond which a real tag's paper or ink is clipped (no ratio): an ink whose
#: median is at or below the first is crushed by the camera's black level (its level is at most
#: that of the first), a paper or ink at or above the second saturated. A tag whose paper is
#: crushed too shows no level at all and is left out.
CLIPPED_DN: tuple[float, float] = (2.0, 253.0)


@dataclass(frozen=True)
class TagLevels:
    """What the level model reads of each tag (:mod:`~simgap.analysis.candidates._gloss`, step 1).

    Attributes
    ----------
    real_ink, real_paper : ndarray (N,)
        Real linear levels (medians linearised with sRGB or the camera's measured response;
        fraction of full scale).
    sim_ink, sim_paper : ndarray (N,)
        Simulated (matte, the simulation's lights) linear levels.
    clipped, ink_clipped : ndarray of bool (N,)
        Real paper, real ink at or beyond :data:`CLIPPED_DN` (a lower bound of its level, no
        more: a glint can saturate the ink too).
    ink_crushed : ndarray of bool (N,)
        Real ink at or below :data:`CLIPPED_DN` ``[0]``: its ``real_ink`` is an upper bound, the
        level of :data:`CLIPPED_DN` ``[0]`` or, through a measured response, of its own code (a
        black level crushed it; how far is what the level model's black level reads).
    eye_from_tag : ndarray (N, 4, 4)
        Each tag's pose in the eyepoint frame (m).
    """

    real_ink: np.ndarray
    real_paper: np.ndarray
    sim_ink: np.ndarray
    sim_paper: np.ndarray
    clipped: np.ndarray
    ink_clipped: np.ndarray
    ink_crushed: np.ndarray
    eye_from_tag: np.ndarray

    @classmethod
    def of(cls, real: np.ndarray, sim: np.ndarray, eye_from_tag: np.ndarray) -> TagLevels:
        """From real and simulated image statistics (N, S).

        Left out: tags missing a level, tags whose real paper is crushed (its median at or
        below :data:`CLIPPED_DN` ``[0]``: a black tag, ink and paper alike, whose log levels
        have nothing to compare), and tags whose uncrushed real ink reads no level (0: none to
        take a log of).
        """
        col = {k: STAT_INDEX[k] for k in ("ink_linear", "paper_linear", "paper_dn", "ink_dn")}
        ok = np.isfinite(real[:, [col["ink_linear"], col["paper_linear"]]]).all(1) & np.isfinite(
            sim[:, [col["ink_linear"], col["paper_linear"]]]
        ).all(1)
        ok &= (sim[:, col["paper_linear"]] > 0) & (sim[:, col["ink_linear"]] > 0)
        ok &= real[:, col["paper_dn"]] > CLIPPED_DN[0]
        crushed = real[:, col["ink_dn"]] <= CLIPPED_DN[0]
        ok &= crushed | (real[:, col["ink_linear"]] > 0)
        crushed = crushed[ok]
        # a crushed ink's level is at most that of the code it reads: linearised with sRGB
        # (0 DN reads 0) the clipping code's, through a camera's measured response its own code's
        # (the black level the response carries), whichever is higher
        own = real[ok, col["ink_linear"]]
        bound = np.maximum(own, float(linearise(CLIPPED_DN[0])))
        return cls(
            np.where(crushed, bound, own),
            real[ok, col["paper_linear"]],
            sim[ok, col["ink_linear"]],
            sim[ok, col["paper_linear"]],
            real[ok, col["paper_dn"]] >= CLIPPED_DN[1],
            real[ok, col["ink_dn"]] >= CLIPPED_DN[1],
            crushed,
            eye_from_tag[ok],
        )

    @property
    def readable(self) -> np.ndarray:
        """Tags whose real ink and paper are both levels, neither clipped nor crushed (N,)."""
        return ~self.clipped & ~self.ink_clipped & ~self.ink_crushed

    def __len__(self) -> int:
        return len(self.real_ink)
