"""Where over the sun's direction detection fails and the pose leaves the envelope.

A dataset whose variants set the ``sun`` effect from a grid of directions (read from its own
experiment, ``experiment_yaml``; ``experiments/orbital_lighting.yaml``) is reduced per direction
over every visible item (tag, p, theta) and repeat (:func:`summarize_sun`): the detection rate, the
largest absolute error per axis (mm, mrad) and the share of detections outside the paper's
high-precision envelope (:data:`~simgap.analysis.paper.TRANSLATION_THRESHOLD_M`,
:data:`~simgap.analysis.paper.ROTATION_THRESHOLD_RAD`). :func:`plot_sun_polar` draws them as polar
heatmaps over the sky: the sun's azimuth around (0 at the top: the rail's +Y, towards the node;
90 to the right: +X) and its zenith angle outwards (the centre is straight up, the outer ring
the horizon). :func:`envelope_rows` lists the detections that leave the envelope and
:func:`worst_directions` the directions where the camera fares worst, whose frames
:func:`plot_frames` shows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from simgap.analysis.paper import (
    ROTATION_THRESHOLD_RAD,
    THRESHOLD_BY_UNIT,
    TRANSLATION_THRESHOLD_M,
)
from simgap.analysis.report._summaries import as_bool
from simgap.core.axes import AXES, AXIS_UNITS

__all__ = [
    "SunSweep",
    "envelope_rows",
    "plot_frames",
    "plot_sun_polar",
    "sun_variants",
    "summarize_sun",
    "sun_markdown",
    "worst_directions",
    "worst_frames",
]

#: Display scale of an error per SI unit: translations in mm, rotations in mrad.
DISPLAY = {"m": (1e3, "mm"), "rad": (1e3, "mrad")}
#: Chords per azimuth cell of the polar maps (a cell 30 deg wide is drawn in 2 deg steps).
ARC_STEPS = 16
#: Envelope per SI unit of the error: the paper's high-precision thresholds.
ENVELOPE = THRESHOLD_BY_UNIT


def _experiment(ds: xr.Dataset):
    """The experiment a dataset was made with (its ``experiment_yaml``), or None.

    None too where that experiment no longer loads (a dataset written by another version, or
    by hand): such a dataset's report has no sun section.
    """
    from simgap.core.config import ConfigError
    from simgap.pipeline.experiment import experiment_from_yaml

    text = ds.attrs.get("experiment_yaml", "")
    try:
        return experiment_from_yaml(text, source="the dataset's experiment") if text else None
    except ConfigError:
        return None


def sun_variants(ds: xr.Dataset) -> dict[str, tuple[float, float]]:
    """Variants that place a sun: name -> (azimuth in [0, 360), elevation) in degrees.

    Read from the ``sun`` light of each variant's state, rebuilt from the dataset's own
    experiment (:func:`simgap.effects.scene.sun_angles`; rail frame). Empty without a sun, or
    for a dataset whose experiment is not there or does not load.
    """
    from simgap.effects.scene import sun_angles

    exp = _experiment(ds)
    if exp is None:
        return {}
    names = {str(v) for v in ds.variant.values}
    return {
        name: sun_angles(state.scene.spec.lights["sun"].towards())
        for name, state in exp.variant_states()
        if name in names and "sun" in state.scene.spec.lights
    }


@dataclass(frozen=True)
class SunSweep:
    """Per sun direction, over every visible item and repeat of a dataset.

    Attributes
    ----------
    variants : tuple of str
        The dataset's variants that place a sun.
    azimuth_deg, elevation_deg : ndarray (V,)
        The sun's direction (deg, rail frame; :class:`simgap.effects.scene.Sun`).
    visible : ndarray of int (V,)
        Visible items (tag, p, theta) times repeats: what the rates are out of.
    detection_rate : ndarray (V,)
        Share of them detected.
    outside_rate : ndarray (V,)
        Share of the detections with some axis outside the envelope.
    max_abs_error : xarray.DataArray (variant, axis)
        Largest absolute error over the detections (m, rad); NaN where none.
    """

    variants: tuple[str, ...]
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray
    visible: np.ndarray
    detection_rate: np.ndarray
    outside_rate: np.ndarray
    max_abs_error: xr.DataArray


def _envelope_share(error: xr.DataArray) -> xr.DataArray:
    """Each axis's absolute error as a share of its envelope (1: on the threshold)."""
    limit = [ENVELOPE[AXIS_UNITS[a]] for a in AXES]
    return abs(error) / xr.DataArray(limit, dims="axis", coords={"axis": list(AXES)})


def _outside(error: xr.DataArray) -> xr.DataArray:
    """Whether each estimate has some axis outside the envelope (NaN errors are inside)."""
    return (_envelope_share(error) > 1).any("axis")


def _detections(sub: xr.Dataset) -> tuple[xr.DataArray, xr.DataArray, xr.DataArray]:
    """Visible items (on the detections' dims), visible detections, and their errors."""
    visible = as_bool(sub.visible).broadcast_like(sub.detected)
    detected = as_bool(sub.detected) & visible
    return visible, detected, sub.error.where(detected)


def summarize_sun(ds: xr.Dataset) -> SunSweep | None:
    """Reduce a sun-direction sweep per direction; None unless two or more directions.

    ``ds`` is a result dataset in memory form (``error`` along ``axis``; docs/conventions.md §3).
    """
    directions = sun_variants(ds)
    if len(set(directions.values())) < 2:
        return None
    names = tuple(directions)
    visible, detected, error = _detections(ds.sel(variant=list(names)))
    dims = ("repeat", "tag", "p", "theta")
    n_visible = visible.sum(dims).values
    n_detected = detected.sum(dims).values
    outside = (_outside(error) & detected).sum(dims).values
    with np.errstate(invalid="ignore", divide="ignore"):
        return SunSweep(
            variants=names,
            azimuth_deg=np.array([directions[n][0] for n in names]),
            elevation_deg=np.array([directions[n][1] for n in names]),
            visible=n_visible,
            detection_rate=np.where(n_visible > 0, n_detected / n_visible, np.nan),
            outside_rate=np.where(n_detected > 0, outside / n_detected, np.nan),
            max_abs_error=abs(error).max(dims),
        )


def _grid(values: np.ndarray, period: float | None = None) -> np.ndarray:
    """Cell edges around sorted distinct grid values (wrapping with ``period``)."""
    v = np.unique(values)
    if len(v) == 1:
        return np.array([v[0] - 5.0, v[0] + 5.0])
    mid = (v[1:] + v[:-1]) / 2
    if period is not None:
        gap = (v[0] + period - v[-1]) / 2
        return np.concatenate([[v[0] - gap], mid, [v[-1] + gap]])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _on_sky(sweep: SunSweep, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth edges (rad), zenith-angle edges (deg) and values on the (zenith, azimuth) grid."""
    az, el = np.unique(sweep.azimuth_deg), np.unique(sweep.elevation_deg)
    grid = np.full((len(el), len(az)), np.nan)
    for a, e, v in zip(sweep.azimuth_deg, sweep.elevation_deg, values, strict=True):
        grid[np.searchsorted(el, e), np.searchsorted(az, a)] = v
    zenith_edges = np.clip(90.0 - _grid(el), 0.0, 180.0)[::-1]  # increasing: the zenith first
    # each azimuth cell split in ARC_STEPS: a polar mesh joins its corners by straight chords
    edges = _grid(az, 360.0)
    fine = np.concatenate(
        [
            np.linspace(a, b, ARC_STEPS, endpoint=False)
            for a, b in zip(edges[:-1], edges[1:], strict=True)
        ]
        + [edges[-1:]]
    )
    return np.radians(fine), zenith_edges, np.repeat(grid[::-1], ARC_STEPS, axis=1)


def plot_sun_polar(sweep: SunSweep, title: str) -> Figure:
    """Polar heatmaps over the sun's direction: detection, envelope, largest error per axis.

    Eight panels: detection rate, share of detections outside the envelope, then the largest
    absolute error of each axis (tx, ty, tz in mm; rx, ry, rz in mrad) with the envelope marked
    on its colour bar. Azimuth 0 (the rail's +Y, from the camera towards the node) is at the top,
    90 (+X) to the right; the centre is the zenith, rings every 30 deg of elevation.
    """
    fig = Figure(figsize=(18, 9.5), layout="constrained")
    axes = fig.subplots(2, 4, subplot_kw={"projection": "polar"})
    panels: list[tuple[str, np.ndarray, str, tuple[float, float], float | None]] = [
        ("detection rate", sweep.detection_rate, "viridis", (0.0, 1.0), None),
        ("detections outside the envelope", sweep.outside_rate, "magma_r", (0.0, 1.0), None),
    ]
    for axis in AXES:
        scale, unit = DISPLAY[AXIS_UNITS[axis]]
        values = sweep.max_abs_error.sel(axis=axis).values * scale
        envelope = ENVELOPE[AXIS_UNITS[axis]] * scale
        top = float(np.nanmax(values, initial=envelope)) if np.isfinite(values).any() else envelope
        panels.append((f"largest |{axis}| ({unit})", values, "magma_r", (0.0, top), envelope))
    for ax, (name, values, cmap, (lo, hi), limit) in zip(axes.ravel(), panels, strict=True):
        theta, zenith, grid = _on_sky(sweep, values)
        mesh = ax.pcolormesh(theta, zenith, np.ma.masked_invalid(grid), cmap=cmap, vmin=lo,
                             vmax=hi, shading="flat")  # fmt: skip
        ax.set_theta_zero_location("N")
        ax.set_theta_direction(-1)
        ax.set_ylim(0, max(90.0, float(zenith.max())))
        ax.set_yticks([30, 60, 90])
        ax.set_yticklabels(["60°", "30°", "0°"], fontsize=7)
        ax.set_title(name, fontsize=10)
        bar = fig.colorbar(mesh, ax=ax, shrink=0.7)
        if limit is not None and lo <= limit <= hi:
            bar.ax.axhline(limit, color="cyan", lw=2)
            bar.ax.text(1.05, limit, " envelope", color="teal", fontsize=7,
                        transform=bar.ax.get_yaxis_transform())  # fmt: skip
    fig.suptitle(f"{title}: by the sun's direction (azimuth round, elevation from the edge in)")
    return fig


@dataclass(frozen=True)
class EnvelopeRow:
    """One detection (item and repeat) whose estimate leaves the envelope."""

    variant: str
    azimuth_deg: float
    elevation_deg: float
    tag: int
    p: int
    theta_deg: float
    repeat: int
    axis: str
    value: float
    unit: str
    #: the absolute error as a share of its axis's envelope (above 1)
    share: float


def envelope_rows(ds: xr.Dataset, sweep: SunSweep) -> list[EnvelopeRow]:
    """Every detection with an axis outside the envelope, its worst axis first, worst first.

    ``value`` is that axis's signed error in display units (mm, mrad).
    """
    rows = []
    for k, name in enumerate(sweep.variants):
        sub = ds.sel(variant=name)
        detected = as_bool(sub.detected)
        error = sub.error.where(detected)
        ratio = _envelope_share(error)
        worst = ratio.fillna(0.0).argmax(dim="axis")
        over = (ratio.max("axis") > 1).values
        for index in zip(*np.nonzero(over), strict=True):
            at = dict(zip(worst.dims, index, strict=True))
            a = AXES[int(worst.isel(at))]
            scale, unit = DISPLAY[AXIS_UNITS[a]]
            rows.append(
                EnvelopeRow(
                    name, float(sweep.azimuth_deg[k]), float(sweep.elevation_deg[k]),
                    int(sub.tag.values[at["tag"]]), int(sub.p.values[at["p"]]),
                    float(np.degrees(sub.theta.values[at["theta"]])),
                    int(sub.repeat.values[at["repeat"]]), a,
                    float(error.isel(at).sel(axis=a)) * scale, unit,
                    float(ratio.isel(at).sel(axis=a)),
                )
            )  # fmt: skip
    rows.sort(key=lambda r: -r.share)
    return rows


def worst_directions(sweep: SunSweep, count: int = 3) -> list[int]:
    """Indices of the ``count`` directions where the camera fares worst.

    Ordered by detection rate (lowest first), then by the share outside the envelope.
    """
    key = np.lexsort((-np.nan_to_num(sweep.outside_rate), np.nan_to_num(sweep.detection_rate)))
    return [int(k) for k in key[:count]]


def plot_frames(frames: list[tuple[str, np.ndarray]], title: str) -> Figure:
    """The given frames (caption, RGB uint8 crop) side by side."""
    fig = Figure(figsize=(4.2 * max(len(frames), 1), 4.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, max(len(frames), 1)))
    for ax, (caption, rgb) in zip(axes, frames, strict=False):
        ax.imshow(rgb)
        ax.set_title(caption, fontsize=9)
        ax.set_axis_off()
    fig.suptitle(title)
    return fig


def _worst_item(ds: xr.Dataset, name: str) -> tuple[int, int, float, str]:
    """(tag, p, theta rad, what) of a variant's worst visible item in repeat 0.

    A lost tag first, then the detection whose error is the largest share of the envelope.
    """
    sub = ds.sel(variant=name).isel(repeat=0)
    visible = as_bool(sub.visible).broadcast_like(sub.detected)
    detected = as_bool(sub.detected)
    ratio = _envelope_share(sub.error).max("axis").where(detected, np.inf).where(visible, -1.0)
    flat = int(np.argmax(ratio.values))
    at = {d: int(i) for d, i in zip(ratio.dims, np.unravel_index(flat, ratio.shape), strict=True)}
    tag, p = int(sub.tag.values[at["tag"]]), int(sub.p.values[at["p"]])
    theta = float(sub.theta.values[at["theta"]])
    if not bool(detected.isel(at)):
        return tag, p, theta, f"tag {tag} lost"
    err = sub.error.isel(at)
    a = str(err.axis.values[int(np.argmax(_envelope_share(err).values))])
    scale, unit = DISPLAY[AXIS_UNITS[a]]
    return tag, p, theta, f"tag {tag} {a} {float(err.sel(axis=a)) * scale:+.1f} {unit}"


def worst_frames(
    ds: xr.Dataset, sweep: SunSweep, cache_dir, count: int = 3
) -> list[tuple[str, np.ndarray]]:
    """The frames of the worst directions' worst items: (caption, RGB crop).

    Rebuilt from the dataset's own experiment (its ``experiment_yaml`` attribute) through the
    cached pipeline in ``cache_dir`` (the frames of the run that wrote the dataset are read
    back; missing ones are rendered).
    """
    from simgap.pipeline.simulator import Simulator

    exp = _experiment(ds)
    if exp is None:
        return []
    states = dict(exp.variant_states())
    simulator = Simulator(cache_dir, show_progress=False)
    out = []
    for k in worst_directions(sweep, count):
        name = sweep.variants[k]
        tag, p, theta, what = _worst_item(ds, name)
        frame = simulator.frame(exp, states[name], p, theta, 0)
        if frame is None:
            continue
        ev = frame.record.get("auto_exposure_ev")
        caption = (
            f"sun az {sweep.azimuth_deg[k]:g}° el {sweep.elevation_deg[k]:g}°\n"
            f"p {p}, θ {np.degrees(theta):.0f}°: {what}"
            + ("" if ev is None else f", exposure {ev:+.1f} EV")
        )
        out.append((caption, frame.crop))
    return out


def _by_carriage(ds: xr.Dataset, sweep: SunSweep) -> list[str]:
    """Markdown table per carriage position over every sun direction: detection, envelope."""
    from simgap.analysis.report._summaries import dataset_distance_m

    sub = ds.sel(variant=list(sweep.variants))
    visible, detected, error = _detections(sub)
    outside = _outside(error) & detected
    seen = as_bool(ds.visible.isel(variant=0, missing_dims="ignore"))
    distance = dataset_distance_m(ds).where(seen)
    lines = [
        "## By carriage position (every sun direction)",
        "",
        "| p | camera-to-tag distance (m) | detection rate | outside the envelope "
        "| median abs ty (mm) | largest abs ty (mm) | median abs rotation, worst axis (mrad) |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in sub.p.values:
        at = {"p": p}
        n_vis, n_det = int(visible.sel(at).sum()), int(detected.sel(at).sum())
        ty = abs(error.sel(at).sel(axis="ty")) * 1e3
        rotation = abs(error.sel(at).sel(axis=["rx", "ry", "rz"])) * 1e3
        rot = rotation.median([d for d in rotation.dims if d != "axis"])
        d = distance.sel(p=p)
        lines.append(
            f"| {int(p)} | {float(d.min()):.2f}-{float(d.max()):.2f} "
            f"| {n_det / max(n_vis, 1):.0%} | {int(outside.sel(at).sum()) / max(n_det, 1):.0%} "
            f"| {float(ty.median()):.1f} | {float(ty.max()):.1f} | {float(rot.max()):.1f} |"
        )
    return lines


def sun_markdown(
    ds: xr.Dataset, sweep: SunSweep, figures: list[str], rows: list[EnvelopeRow]
) -> str:
    """The sun section: what the figures show, read from the data, and the envelope's rows."""
    title = ds.attrs.get("experiment", "result")
    n_dir = len(sweep.variants)
    rate = sweep.detection_rate
    lo = int(np.nanargmin(rate))
    all_found = int(np.sum(rate == 1.0))
    inside = int(np.sum(np.nan_to_num(sweep.outside_rate) == 0.0))
    trans = sweep.max_abs_error.sel(axis=["tx", "ty", "tz"]) * 1e3
    worst = trans.where(np.isfinite(trans), -np.inf).argmax(dim=["variant", "axis"])
    w_dir, w_axis = int(worst["variant"]), str(trans.axis.values[int(worst["axis"])])
    lines = [
        f"# By the sun's direction: {title}",
        "",
        f"{n_dir} sun directions, each over {int(sweep.visible[0])} visible items "
        "(tag x configuration) x repeats. Envelope: the paper's high-precision thresholds, "
        f"{TRANSLATION_THRESHOLD_M * 1e3:g} mm and {ROTATION_THRESHOLD_RAD * 1e3:g} mrad per axis.",
        "",
        *(f"![{f}]({f})" for f in figures[:1]),
        "",
        "Read from the data:",
        f"- detection: every visible tag found with the sun in {all_found} of {n_dir} directions; "
        f"lowest {rate[lo]:.0%} with the sun at azimuth {sweep.azimuth_deg[lo]:g}°, elevation "
        f"{sweep.elevation_deg[lo]:g}°;",
        f"- envelope: every detection inside it in {inside} of {n_dir} directions; the largest "
        f"translation error is |{w_axis}| {float(trans.isel(variant=w_dir).sel(axis=w_axis)):.1f} "
        f"mm, with the sun at azimuth {sweep.azimuth_deg[w_dir]:g}°, elevation "
        f"{sweep.elevation_deg[w_dir]:g}°;",
    ]
    if "auto_exposure_ev" in ds:
        ev = ds.auto_exposure_ev.sel(variant=list(sweep.variants)).values
        lines.append(
            f"- auto exposure chose {np.nanmin(ev):+.1f} to {np.nanmax(ev):+.1f} EV from the "
            "experiment's base exposure."
        )
    lines += [
        "",
        "## By elevation",
        "",
        "| elevation | detection rate (lowest, mean) | outside the envelope (largest share) "
        "| largest abs translation (mm) | largest abs rotation (mrad) |",
        "|---|---|---|---|---|",
    ]
    for el in np.unique(sweep.elevation_deg):
        ring = sweep.elevation_deg == el
        err = sweep.max_abs_error.isel(variant=np.flatnonzero(ring)) * 1e3
        lines.append(
            f"| {el:g}° | {np.nanmin(rate[ring]):.0%}, {np.nanmean(rate[ring]):.0%} "
            f"| {np.nanmax(sweep.outside_rate[ring], initial=0.0):.0%} "
            f"| {float(err.sel(axis=['tx', 'ty', 'tz']).max()):.1f} "
            f"| {float(err.sel(axis=['rx', 'ry', 'rz']).max()):.1f} |"
        )
    lines += ["", *_by_carriage(ds, sweep)]
    shown = rows[:20]
    lines += [
        "",
        f"## Detections outside the envelope: {len(rows)}"
        + (f" (the {len(shown)} worst)" if len(rows) > len(shown) else ""),
        "",
    ]
    if shown:
        lines += [
            "| sun azimuth | sun elevation | tag | p | theta | repeat | worst axis | error |",
            "|---|---|---|---|---|---|---|---|",
            *(
                f"| {r.azimuth_deg:g}° | {r.elevation_deg:g}° | {r.tag} | {r.p} "
                f"| {r.theta_deg:.0f}° | {r.repeat} | {r.axis} | {r.value:+.1f} {r.unit} |"
                for r in shown
            ),
        ]
    if len(figures) > 1:
        lines += ["", "## The worst directions' frames", "", f"![{figures[1]}]({figures[1]})"]
    return "\n".join(lines) + "\n"
