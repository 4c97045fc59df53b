"""Heatmap parts of the report and comparison figures: sampled cells, colour limits, hatching."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
import xarray as xr
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.colors import Normalize
from matplotlib.figure import Figure, SubFigure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from simgap.core.distance import DISTANCE_LABEL

NO_DATA_GREY: Final[str] = "0.75"
"""Colour of cells without data."""
SIGNED_CMAP: Final[str] = "RdBu_r"
"""Diverging colour map of signed errors and changes, centred on 0."""
FAR_OUT_IQR: Final[float] = 3.0
"""Tukey's "far out" fence, Q3 + 3 IQR (J. W. Tukey, Exploratory Data Analysis, 1977, ch. 2):
|values| beyond it do not set the colour limit of a heatmap; they are hatched and counted."""
_MIN_FENCE_VALUES: Final[int] = 4  # quartiles of fewer values say nothing: the limit is their max
SATURATION_RATIO: Final[float] = 2.0
"""The robust limit is used only where ``max |value|`` exceeds it this many times: below that the
full range still leaves the bulk of the cells readable, and heavy tails are not marked."""
BEYOND_HATCH: Final[str] = "////"
"""Hatch of heatmap cells whose |value| is beyond the colour limit."""
MAX_TICKS: Final[int] = 8
"""Most tick labels on a heatmap axis; denser samples label every k-th cell."""
ROW_DISTANCE_LABEL: Final[str] = f"{DISTANCE_LABEL}, median of the row"
"""Label of a heatmap's pin-hole rows, ticked with each row's camera-to-tag distance."""


@dataclass(frozen=True)
class SampledAxis:
    """A heatmap axis drawn on its samples only: one cell of unit width per sampled value.

    Cell ``i`` spans ``i - 0.5 .. i + 0.5`` (axis units are sample indices), so a sparse grid
    (theta every 30 deg, every seventh pin hole) shows its samples and nothing in between or
    beyond them; the ticks name the sampled values.

    Attributes
    ----------
    edges : numpy.ndarray (n + 1,)
        Cell edges, ``-0.5, 0.5, ..., n - 0.5``.
    ticks : numpy.ndarray of int
        Tick positions (cell centres): every cell, or every k-th for more than
        :data:`MAX_TICKS` samples.
    labels : list of str
        Tick labels, the sampled values at `ticks`.
    """

    edges: np.ndarray
    ticks: np.ndarray
    labels: list[str]

    def apply(self, ax: Axes, which: str) -> None:
        """Set the ticks of ``ax``'s ``which`` (``"x"`` or ``"y"``) axis to the samples."""
        if which == "x":
            ax.set_xticks(self.ticks, self.labels)
        else:
            ax.set_yticks(self.ticks, self.labels)


def sampled_axis(values: np.ndarray, fmt: str = "{:g}") -> SampledAxis:
    """The :class:`SampledAxis` of sampled values (in drawing order), labelled with ``fmt``."""
    values = np.asarray(values)
    n = values.size
    step = max(1, int(np.ceil(n / MAX_TICKS)))
    ticks = np.arange(0, n, step)
    return SampledAxis(np.arange(n + 1) - 0.5, ticks, [fmt.format(values[i]) for i in ticks])


def robust_colour_limit(values: np.ndarray, floor: float = 1e-12) -> float:
    """Symmetric colour limit of a signed heatmap that one outlier does not set.

    The limit is the largest ``|value|`` within Tukey's far-out fence (:data:`FAR_OUT_IQR`) of
    the nonzero ``|values|`` (exact zeros, unchanged configurations, carry no scale), where
    ``max |value|`` is more than :data:`SATURATION_RATIO` times that; else ``max |value|``.
    Cells beyond it are drawn at the end of the colour map and marked
    (:func:`mark_beyond_limit`). A percentile (xarray's ``robust`` 2-98 %) would not do on a
    sparse grid: with 9 cells its 98th percentile is 84 % of the way to the one outlier. With
    fewer than 4 nonzero values the limit is their maximum.

    Parameters
    ----------
    values : numpy.ndarray
        Signed values (any shape, NaN ignored), in the unit drawn.
    floor : float
        Smallest limit returned (an all-zero or empty panel), in the unit of ``values``.

    Returns
    -------
    float
        The limit, in the unit of ``values``: colours span ``-limit .. limit``.
    """
    mag = np.abs(np.asarray(values, dtype=float).ravel())
    mag = mag[np.isfinite(mag) & (mag > 0)]
    if mag.size == 0:
        return floor
    top = float(mag.max())
    if mag.size >= _MIN_FENCE_VALUES:
        q1, q3 = np.percentile(mag, [25, 75])
        inside = float(mag[mag <= q3 + FAR_OUT_IQR * (q3 - q1)].max())
        top = inside if top > SATURATION_RATIO * inside else top
    return max(top, floor)


def mark_beyond_limit(ax: Axes, values: np.ndarray, limit: float) -> str:
    """Hatch the cells of a ``(rows, cols)`` heatmap whose ``|value|`` exceeds ``limit``.

    Cells are those of :class:`SampledAxis` (unit squares at index positions).

    Returns
    -------
    str
        For the panel's title: ``"hatched: n beyond ±limit, largest |value| v"`` (in the unit
        of `values`); empty where no cell is beyond.
    """
    with np.errstate(invalid="ignore"):
        rows, cols = np.nonzero(np.abs(values) > limit)
    for r, c in zip(rows, cols, strict=True):
        ax.add_patch(
            Rectangle((c - 0.5, r - 0.5), 1.0, 1.0, fill=False, hatch=BEYOND_HATCH, lw=0, ec="k")
        )
    if not rows.size:
        return ""
    top = float(np.max(np.abs(values[rows, cols])))
    return f"hatched: {rows.size} beyond ±{limit:.3g}, largest |value| {top:.3g}"


def heatmap_legend_handles(
    grey: str = "no estimate", undetected: bool = True
) -> list[Patch | Line2D]:
    """Legend entries of the heatmaps: ``grey`` cells, ``x`` (if `undetected`), beyond the limit."""
    handles: list[Patch | Line2D] = [Patch(fc=NO_DATA_GREY, label=grey)]
    if undetected:
        handles.append(
            Line2D([], [], color="k", marker="x", ls="none", label="visible, not detected")
        )
    return handles + [
        Patch(
            fc="white",
            ec="k",
            hatch=BEYOND_HATCH,
            label="outlier beyond the colour limit (Tukey's far-out fence); count in the title",
        ),
    ]


def row_distance_labels(distance_m: xr.DataArray, shown: xr.DataArray) -> SampledAxis:
    """Pin-hole rows ticked with their median camera-to-tag distance (m).

    ``distance_m`` and ``shown`` are ``(p, theta)`` in drawing order; the median is over the
    shown (visible) cells of a row, over all of them where none is shown.
    """
    d = distance_m.transpose("p", "theta").values
    seen = shown.transpose("p", "theta").values.astype(bool)
    rows = np.where(seen.any(axis=1, keepdims=True), np.where(seen, d, np.nan), d)
    return sampled_axis(np.nanmedian(rows, axis=1), "{:.3f}")


def signed_mesh(
    fig: Figure | SubFigure, ax: Axes, values: np.ndarray, limit: float, label: str
) -> str:
    """Draw ``values[row, col]`` on unit cells with colours ``-limit .. limit``, mark the rest.

    Returns what :func:`mark_beyond_limit` returns, for the panel's title.
    """
    rows, cols = values.shape
    mesh = ax.pcolormesh(
        np.arange(cols + 1) - 0.5,
        np.arange(rows + 1) - 0.5,
        np.ma.masked_invalid(values),
        cmap=colormaps[SIGNED_CMAP].with_extremes(bad=NO_DATA_GREY),
        norm=Normalize(-limit, limit),
    )
    beyond = mark_beyond_limit(ax, values, limit)
    fig.colorbar(mesh, ax=ax, extend="both" if beyond else "neither", label=label)
    return beyond


def shown_columns(shown: np.ndarray) -> slice:
    """Columns of a ``(rows, cols)`` mask with a shown cell, plus one on each side."""
    columns = np.flatnonzero(shown.any(axis=0))
    if not columns.size:
        return slice(None)
    return slice(max(columns[0] - 1, 0), min(columns[-1] + 1, shown.shape[1] - 1) + 1)
