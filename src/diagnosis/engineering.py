"""The diagnosis in an engineer's units: per axis, near / mid / far, real vs simulated vs fitted.

What a robotics engineer reads first: how large the real pose error is on each axis, in mm and
mrad, at the near, middle and far thirds of the carriage; how large the simulated one is; the gap
between them before and after the fitted effects; which axes get worse; how many poses are planar
flips (the IPPE ambiguity of a square marker: the two poses whose normals mirror each other about
the line of sight, a rotation error of tens to hundreds of mrad that no effect explains); and the
paper's figure, absolute error against distance with the mission thresholds.

Inputs are per comparable item (a tag at a configuration): real, simulated and fitted errors (m,
rad) and the camera-to-tag distance (m). Robust statistics throughout: a median is called a median.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from simgap.analysis.gap import distance_thirds
from simgap.analysis.paper import THRESHOLD_BY_UNIT
from simgap.analysis.thresholds import FLIP_RAD, PRACTICAL_FLOOR
from simgap.core.axes import AXES, ROTATION_AXES, axis_unit, display_unit
from simgap.core.distance import DISTANCE_LABEL
from simgap.diagnosis.diagnosis_files import ItemEvidence

#: A pose whose rotation error is larger than :data:`~simgap.analysis.thresholds.FLIP_RAD`
#: (0.15 rad) while its translation error on every axis stays within the mission threshold
#: (5 mm) is a planar flip: the square marker's other IPPE solution, whose rotation is wrong by
#: about twice the angle between the tag's normal and the line of sight, at the right position.
FLIP_TRANSLATION_M = THRESHOLD_BY_UNIT["m"]
#: A region's gap counts as worse after the fit when its median |gap| grows by more than this
#: share of the practical floor (a tenth of the mission threshold) and by more than 10 %.
WORSE_FLOOR_SHARE = 0.5
WORSE_RELATIVE = 0.1


def planar_flips(errors: np.ndarray) -> np.ndarray:
    """Which poses are planar flips (see :data:`FLIP_RAD`), per item (N,) bool.

    ``errors`` is (N, 6): tx, ty, tz (m), rx, ry, rz (rad); NaN rows are no flips.
    """
    e = np.asarray(errors, float)
    with np.errstate(invalid="ignore"):
        rotation = np.linalg.norm(e[:, 3:], axis=1)
        translation = np.max(np.abs(e[:, :3]), axis=1)
        return (rotation > FLIP_RAD) & (translation <= FLIP_TRANSLATION_M)


@dataclass(frozen=True)
class RegionRow:
    """One axis in one distance third: median absolute errors and the median signed gap.

    Attributes
    ----------
    axis : str
        Pose axis.
    region : str
        ``near``, ``mid`` or ``far`` with its pin holes (``near (p 0-4)``).
    distance_m : tuple of float
        Camera-to-tag distance range of the region's items (m).
    n : int
        Items (tags detected in both, planar flips left out).
    real_abs, sim_abs, fitted_abs : float
        Median absolute error of the real data, the simulation and the simulation with the
        fitted effects (m or rad; NaN without a fit).
    gap_before, gap_after : float
        Median signed gap real - simulated, before and after the fitted effects (m or rad).
    worse : bool
        The gap grows after the fit (:data:`WORSE_FLOOR_SHARE`, :data:`WORSE_RELATIVE`).
    """

    axis: str
    region: str
    distance_m: tuple[float, float]
    n: int
    real_abs: float
    sim_abs: float
    fitted_abs: float
    gap_before: float
    gap_after: float
    worse: bool


def _median(values: np.ndarray) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return float(np.nanmedian(values)) if values.size else float("nan")


def region_rows(
    p: np.ndarray,
    distance_m: np.ndarray,
    real: np.ndarray,
    sim: np.ndarray,
    fitted: np.ndarray | None = None,
    practical_floor: dict[str, float] | None = None,
) -> list[RegionRow]:
    """Per axis and distance third, the errors and the gap before and after the fit.

    Parameters
    ----------
    p : ndarray of int (N,)
        Pin hole of each item.
    distance_m : ndarray (N,)
        Camera-to-tag distance of each item (m).
    real, sim : ndarray (N, 6)
        Real and simulated errors (m, rad).
    fitted : ndarray (N, 6), optional
        Simulated errors with the fitted effects.
    practical_floor : dict, optional
        Smallest gap that matters per unit (m, rad); default
        :data:`~simgap.analysis.thresholds.PRACTICAL_FLOOR` (a tenth of the mission thresholds).
    """
    floor = practical_floor or PRACTICAL_FLOOR
    fitted = np.full_like(sim, np.nan) if fitted is None else fitted
    keep = ~(planar_flips(real) | planar_flips(sim) | planar_flips(fitted))
    rows = []
    for name, pins in distance_thirds(np.unique(p)).items():
        member = np.isin(p, pins) & keep
        d = distance_m[member]
        span = (float(d.min()), float(d.max())) if d.size else (np.nan, np.nan)
        for k, axis in enumerate(AXES):
            r, s, f = real[member, k], sim[member, k], fitted[member, k]
            before, after = _median(r - s), _median(r - f)
            grow = abs(after) - abs(before)
            worse = bool(
                np.isfinite(grow)
                and grow > WORSE_FLOOR_SHARE * floor[axis_unit(axis)]
                and grow > WORSE_RELATIVE * abs(before)
            )
            rows.append(
                RegionRow(
                    axis,
                    name,
                    span,
                    int(np.isfinite(r - s).sum()),
                    _median(np.abs(r)),
                    _median(np.abs(s)),
                    _median(np.abs(f)),
                    before,
                    after,
                    worse,
                )
            )
    return rows


def _show(value: float, axis: str, signed: bool = False) -> str:
    unit, k = display_unit(axis)
    if not np.isfinite(value):
        return "-"
    return f"{value * k:+.2f} {unit}" if signed else f"{value * k:.2f} {unit}"


def region_table(rows: list[RegionRow]) -> list[str]:
    """Markdown table of :func:`region_rows`: one line per axis and third, worse ones marked."""
    lines = [
        "| axis | region | distance | real | simulated | fitted | gap before -> after |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lo, hi = r.distance_m
        gap = f"{_show(r.gap_before, r.axis, True)} -> {_show(r.gap_after, r.axis, True)}"
        lines.append(
            f"| {r.axis} | {r.region} | {lo:.2f}-{hi:.2f} m | {_show(r.real_abs, r.axis)} | "
            f"{_show(r.sim_abs, r.axis)} | {_show(r.fitted_abs, r.axis)} | "
            f"{gap}{' **worse**' if r.worse else ''} |"
        )
    return lines


def flip_sentence(real: np.ndarray, sim: np.ndarray, fitted: np.ndarray | None = None) -> str:
    """How many poses are planar flips: real, simulated and (if given) with the fitted effects."""
    counts = {"real": real, "simulated": sim}
    if fitted is not None:
        counts["with the fitted effects"] = fitted
    n = {k: int(planar_flips(v).sum()) for k, v in counts.items()}
    if not any(n.values()):
        return "No planar-pose flips (the square marker's mirrored IPPE solution)."
    return (
        f"Planar-pose flips (the square marker's mirrored IPPE solution: rotation off by more "
        f"than {FLIP_RAD * 1e3:.0f} mrad at the right position): "
        + ", ".join(f"{k} {v}" for k, v in n.items())
        + f" of {len(real)} poses; left out of the table above, and no effect is fitted to them."
    )


def plot_abs_error_vs_distance(
    distance_m: np.ndarray,
    real: np.ndarray,
    sim: np.ndarray,
    fitted: np.ndarray | None = None,
) -> Figure:
    """The paper's figure: absolute error per axis against distance, with the mission thresholds.

    Points per item (real, simulated, fitted), planar flips drawn as crosses (they would stretch
    the scale; their count is in the legend), the 5 mm / 87.3 mrad thresholds as dashed lines.
    """
    fig = Figure(figsize=(13, 7), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    series = [("real", real, "tab:red"), ("simulated", sim, "tab:blue")]
    if fitted is not None:
        series.append(("simulated + fitted effects", fitted, "tab:green"))
    for ax, (k, axis) in zip(axes.flat, enumerate(AXES), strict=True):
        unit, scale = display_unit(axis)
        threshold = THRESHOLD_BY_UNIT[axis_unit(axis)] * scale
        for label, errors, colour in series:
            flip = planar_flips(errors)
            y = np.abs(errors[:, k]) * scale
            ax.scatter(distance_m[~flip], y[~flip], s=10, color=colour, alpha=0.7, label=label)
            if flip.any() and axis in ROTATION_AXES:
                ax.scatter(
                    distance_m[flip],
                    np.minimum(y[flip], 1.5 * threshold),
                    marker="x",
                    color=colour,
                    label=f"{label}: planar flips ({int(flip.sum())}, clipped)",
                )
        ax.axhline(threshold, color="k", ls="--", lw=0.8, label="mission threshold")
        ax.set_title(f"|{axis} error| [{unit}]")
        ax.set_xlabel(DISTANCE_LABEL)
        ax.set_ylim(0, None)
        ax.grid(alpha=0.3)
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 4))
    fig.suptitle("Absolute pose error against distance (the paper's figure), mission thresholds")
    return fig


def gap_by_distance_title(has_fit: bool) -> str:
    """Title of ``gap_by_distance.png`` (:func:`plot_gap_by_distance`), naming its sign."""
    after = " -> after the fitted effects (dashed)" if has_fit else ""
    return (
        "Signed gap, real − simulated error, against camera-to-tag distance (positive: the real "
        "error lies further in + than the simulated one)\nlines: median per distance third, "
        f"the table's gap before{after}"
    )


def plot_gap_by_distance(
    p: np.ndarray,
    distance_m: np.ndarray,
    real: np.ndarray,
    sim: np.ndarray,
    fitted: np.ndarray | None = None,
) -> Figure:
    """The signed gap per axis against camera-to-tag distance, the same gap as the region table.

    Parameters
    ----------
    p : ndarray of int (N,)
        Pin hole of each item (the distance thirds of :func:`region_rows`).
    distance_m : ndarray (N,)
        Camera-to-tag distance of each item (m).
    real, sim : ndarray (N, 6)
        Real and simulated errors (m, rad).
    fitted : ndarray (N, 6), optional
        Simulated errors with the fitted effects (all NaN or None: no fit).

    Returns
    -------
    matplotlib.figure.Figure
        2x3 panels (tx, ty, tz / rx, ry, rz): per item ``real - sim`` in mm or mrad (points,
        planar flips left out as in the table), and per distance third the median signed gap
        before (solid) and after the fit (dashed) over the third's distance span: the
        ``gap before -> after`` column of :func:`region_table`.
    """
    fig = Figure(figsize=(13, 7), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    has_fit = fitted is not None and bool(np.isfinite(fitted).any())
    keep = ~(planar_flips(real) | planar_flips(sim))
    rows = region_rows(p, distance_m, real, sim, fitted if has_fit else None)
    for ax, (k, axis) in zip(axes.flat, enumerate(AXES), strict=True):
        unit, scale = display_unit(axis)
        gap = (real[keep, k] - sim[keep, k]) * scale
        ax.scatter(distance_m[keep], gap, s=14, color="tab:purple", alpha=0.7, label="item")
        for r in (r for r in rows if r.axis == axis and np.isfinite(r.gap_before)):
            ax.plot(r.distance_m, [r.gap_before * scale] * 2, color="k", lw=2.5)
            if has_fit:
                ax.plot(r.distance_m, [r.gap_after * scale] * 2, color="tab:green", lw=2, ls="--")
        ax.axhline(0.0, color="0.4", lw=0.8)
        ax.set_title(f"{axis}: real − simulated error [{unit}]")
        ax.set_xlabel(DISTANCE_LABEL)
        ax.grid(alpha=0.3)
    handles = [
        Line2D([], [], color="tab:purple", marker="o", ls="none", label="one item"),
        Line2D([], [], color="k", lw=2.5, label="median per distance third (the table's gap)"),
    ]
    if has_fit:
        handles.append(
            Line2D([], [], color="tab:green", lw=2, ls="--", label="median after the fit")
        )
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles))
    fig.suptitle(gap_by_distance_title(has_fit))
    return fig


def verdict(rows: list[RegionRow], selected: str, fitted_on: str) -> list[str]:
    """The diagnosis in three sentences of mm and mrad: the largest gap, the answer, what worsens.

    Parameters
    ----------
    rows : list of RegionRow
        :func:`region_rows` of the diagnosis.
    selected : str
        The selected effects in words (``-`` for none).
    fitted_on : str
        Which items the "after" values come from (e.g. "the measure split, re-rendered").
    """
    floor = PRACTICAL_FLOOR
    finite = [r for r in rows if np.isfinite(r.gap_before)]
    if not finite:
        return ["No comparable poses."]
    worst = max(finite, key=lambda r: abs(r.gap_before) / floor[axis_unit(r.axis)])
    lines = [
        f"Largest gap: **{worst.axis} {worst.region.split()[0]}** "
        f"({worst.distance_m[0]:.2f}-{worst.distance_m[1]:.2f} m from the camera): real - "
        f"simulated {_show(worst.gap_before, worst.axis, True)} (median; real "
        f"|error| {_show(worst.real_abs, worst.axis)}, simulated "
        f"{_show(worst.sim_abs, worst.axis)}; practical floor "
        f"{_show(floor[axis_unit(worst.axis)], worst.axis)})."
    ]
    if selected == "-":
        lines.append("No effect of the catalogue is selected.")
        return lines
    lines.append(
        f"Selected: {selected}. With it the gap there is "
        f"{_show(worst.gap_after, worst.axis, True)} ({fitted_on})."
    )
    worse = [r for r in rows if r.worse]
    if worse:
        lines.append(
            "**Worse after the fit**: "
            + "; ".join(
                f"{r.axis} {r.region.split()[0]} {_show(r.gap_before, r.axis, True)} -> "
                f"{_show(r.gap_after, r.axis, True)}"
                for r in worse
            )
            + "."
        )
    else:
        lines.append("No axis or distance third gets worse with it.")
    return lines


def engineering_markdown(items: ItemEvidence, selected: str) -> list[str]:
    """The verdict in mm and mrad, the per-axis near / mid / far table and the planar flips.

    Parameters
    ----------
    items : ItemEvidence
        The diagnosis's comparable items: pin holes, distances (m), real, simulated and, with the
        selected effects, fitted or confirmed errors (m, rad;
        :attr:`~simgap.diagnosis.diagnosis_files.ItemEvidence.with_fitted_effects`).
    selected : str
        The selected effects in words.
    """
    fitted = items.with_fitted_effects
    rows = region_rows(items.p, items.distance_m, items.real_error, items.simulated_error, fitted)
    fitted_on = (
        "every item re-rendered with the fitted effects; the "
        f"{items.measure_items} of the measure split neither fitted nor chose them"
        if items.confirmed_error is not None
        else f"fast model, the {items.measure_items} measure-split items"
    )
    lines = ["## In mm and mrad", ""]
    lines += verdict(rows, selected, fitted_on)
    lines += [
        "",
        "Median |error| per axis and distance third over every comparable item (real, "
        f"simulated; fitted: {fitted_on}), and the median gap real - simulated before -> after "
        "the fitted effects. Planar flips are left out.",
        "",
    ]
    lines += region_table(rows)
    lines += ["", flip_sentence(items.real_error, items.simulated_error, fitted), ""]
    return lines
