"""Readable names and units of the image statistics, as figures and tables label them."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class StatLabel:
    """How a figure or table names one statistic: a readable name and its unit.

    Attributes
    ----------
    name : str
        Readable name (no underscores), e.g. ``"paper noise σ, linear"``.
    unit : str
        Unit as a reader says it: ``"DN"`` (8-bit digital number), ``"px"``, ``"fraction of full
        scale"`` (linearised level, 0 black to 1 white), ``"ratio"``, ``"count"`` or ``"EV"``
        (a ratio of linear levels in stops, ``log2``); never ``"1"``.
    """

    name: str
    unit: str

    @property
    def text(self) -> str:
        """``"name [unit]"``, the axis label."""
        return f"{self.name} [{self.unit}]"


_FULL_SCALE = "fraction of full scale"
_STICKER = "fraction of sticker pixels"
#: Readable name and unit of every statistic of :data:`~simgap.pose.image_stats.STATS`.
STAT_LABELS: dict[str, StatLabel] = {
    "ink_dn": StatLabel("ink level", "DN"),
    "paper_dn": StatLabel("paper level", "DN"),
    "ink_linear": StatLabel("ink level, linear", _FULL_SCALE),
    "paper_linear": StatLabel("paper level, linear", _FULL_SCALE),
    "contrast": StatLabel("Michelson contrast", "ratio"),
    "edge_width_px": StatLabel("edge width 10-90 %", "px"),
    "edge_width_x_px": StatLabel("edge width 10-90 %, left/right sides", "px"),
    "edge_width_y_px": StatLabel("edge width 10-90 %, top/bottom sides", "px"),
    "noise_ink_dn": StatLabel("ink noise σ", "DN"),
    "noise_paper_dn": StatLabel("paper noise σ", "DN"),
    "noise_ink_linear": StatLabel("ink noise σ, linear", _FULL_SCALE),
    "noise_paper_linear": StatLabel("paper noise σ, linear", _FULL_SCALE),
    "temporal_noise_ink_linear": StatLabel("temporal ink noise σ, linear", _FULL_SCALE),
    "temporal_noise_paper_linear": StatLabel("temporal paper noise σ, linear", _FULL_SCALE),
    "clipped_fraction": StatLabel("clipped pixels (0 or 255 DN)", _STICKER),
    "highlight_fraction": StatLabel("highlight pixels", _STICKER),
    "rejected_candidates": StatLabel("rejected detector candidates", "count"),
    "blockiness": StatLabel("JPEG blockiness (1 = none)", "ratio"),
    "jpeg_dc_step_dn": StatLabel("JPEG DC quantisation step (none: uncompressed)", "DN"),
    "black_clipped_fraction": StatLabel("black-clipped pixels (0 DN)", _STICKER),
    "edge_overshoot": StatLabel("edge overshoot over the edge step (sharpening halo)", "ratio"),
    "colour_fringe_dn": StatLabel("colour fringe at edges (off the ink-paper colour line)", "DN"),
    "repeat_gain_ev": StatLabel("gain over the repeat frame's (paper level)", "EV"),
}


def stat_label(name: str) -> StatLabel:
    """The :class:`StatLabel` of statistic ``name``; the raw name and ``"?"`` for an unknown one.

    A dataset written by another simgap version may hold statistics this one does not name.
    """
    return STAT_LABELS.get(name, StatLabel(name, "?"))
