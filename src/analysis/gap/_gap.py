"""Where the sim-to-real gap lies: the gap field, its noise, and its significant regions.

The gap field is ``real error - simulated error`` per item (tag, configuration) and axis
(docs/conventions.md §5), on items where the tag is visible and both the real and the
simulated estimator returned a pose. Its noise is taken from repeats when there are any (the
spread of the repeat means) and otherwise from the roughness of each error field along the
carriage axis (a robust scale of its second differences), which is what a single-repeat capture
offers.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import cast

import numpy as np
import xarray as xr

from simgap.analysis.thresholds import DEFAULT_NOISE, PRACTICAL_FLOOR, Z_SIGNIFICANT
from simgap.core.axes import AXES, axis_unit
from simgap.core.robust import (
    MAD_TO_SIGMA,
    MEDIAN_SE_FACTOR,
    Z95_WIDTH,
    mad_sigma,
    median_standard_error,
)


def mean_error(ds: xr.Dataset, variant: str | None = None) -> xr.DataArray:
    """Error averaged over repeats (tag, p, theta, axis), NaN where never detected."""
    err = ds.error.sel(variant=variant) if variant else ds.error.isel(variant=0)
    return err.mean("repeat", skipna=True)


def _roughness(field: np.ndarray) -> float:
    """Robust noise scale of a (..., p) field from second differences along p."""
    d2 = np.diff(field, n=2, axis=-1)
    d2 = d2[np.isfinite(d2)]
    if d2.size < 8:
        return np.nan
    # a second difference of white noise has variance 6 sigma^2
    return float(MAD_TO_SIGMA * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def frame_noise(ds: xr.Dataset, variant: str | None = None) -> xr.DataArray:
    """Noise of one frame's error at each item (tag, p, theta, axis) (m, rad).

    The standard deviation over repeats (one degree of freedom less than the repeats that
    detected the tag); NaN with fewer than two.
    """
    err = ds.error.sel(variant=variant) if variant else ds.error.isel(variant=0)
    n = err.notnull().sum("repeat")
    with warnings.catch_warnings():  # items detected once or never
        warnings.simplefilter("ignore", RuntimeWarning)
        return err.std("repeat", ddof=1, skipna=True).where(n >= 2)


def noise_scale(ds: xr.Dataset, variant: str | None = None) -> xr.DataArray:
    """Per-axis noise (m, rad) of one dataset's repeat-mean error at a single item.

    With repeats: the median over items of their frame noise (:func:`frame_noise`)
    over the square root of the repeats; with one, the error field's roughness along p.
    """
    err = ds.error.sel(variant=variant) if variant else ds.error.isel(variant=0)
    repeats = err.sizes["repeat"]
    frame = frame_noise(ds, variant) if repeats > 1 else None
    out = []
    for axis in AXES:
        if frame is not None:
            sd = frame.sel(axis=axis).values
            s = float(np.nanmedian(sd) / np.sqrt(repeats)) if np.isfinite(sd).any() else np.nan
        else:
            e = err.sel(axis=axis).values  # (repeat, tag, p, theta)
            with warnings.catch_warnings():  # items never detected are all-NaN
                warnings.simplefilter("ignore", RuntimeWarning)
                s = _roughness(np.moveaxis(np.nanmean(e, axis=0), 1, -1))  # p last
        out.append(s if np.isfinite(s) else DEFAULT_NOISE[axis_unit(axis)])
    return xr.DataArray(out, coords={"axis": list(AXES)}, dims="axis", attrs={"units": "m or rad"})


def item_noise(
    real: xr.Dataset, sim: xr.Dataset, sim_variant: str | None = None
) -> xr.DataArray:
    """Noise of the gap of each item (tag, p, theta, axis) (m, rad), from repeats.

    Each side's repeat mean carries its frame noise (:func:`frame_noise`) over the square root
    of its repeats. A side with one frame is taken to be as noisy as one frame of the other: a
    capture's single frame at a pose is assumed no quieter than one simulated frame there. The
    noise differs much between items (a far, oblique tag's depth and rotation move
    several millimetres with a tenth of a pixel of corner noise, a near one's do not), which a
    per-axis noise level does not show. NaN where neither side has repeats. ``sim`` is aligned
    to ``real`` (:func:`align`).
    """
    real, sim = align(real, sim)
    s_frame = frame_noise(sim, sim_variant)
    r_frame = frame_noise(real)
    r_frame = r_frame.fillna(s_frame) if real.sizes["repeat"] < 2 else r_frame
    s_frame = s_frame.fillna(r_frame) if sim.sizes["repeat"] < 2 else s_frame
    var = r_frame**2 / real.sizes["repeat"] + s_frame**2 / sim.sizes["repeat"]
    return cast(xr.DataArray, np.sqrt(var))  # a ufunc keeps a DataArray (numpy's stubs: ndarray)


@dataclass(frozen=True)
class GapField:
    """The gap field and what it is computed on.

    Attributes
    ----------
    gap : xarray.DataArray
        real - simulated error (tag, p, theta, axis); NaN where not comparable (m, rad).
    sigma : xarray.DataArray
        Noise of one gap value per axis (m, rad).
    comparable : xarray.DataArray
        Tag visible and detected in both (tag, p, theta).
    real_detection, sim_detection : xarray.DataArray
        Detection rate over repeats (tag, p, theta), NaN where not visible.
    """

    gap: xr.DataArray
    sigma: xr.DataArray
    comparable: xr.DataArray
    real_detection: xr.DataArray
    sim_detection: xr.DataArray


def align(real: xr.Dataset, sim: xr.Dataset) -> tuple[xr.Dataset, xr.Dataset]:
    """Select the simulated configurations that the real dataset has (p, theta matched to 1e-6)."""
    thetas = []
    for t in real.theta.values:
        hit = np.flatnonzero(np.isclose(sim.theta.values, t, atol=1e-6))
        if hit.size == 0:
            raise ValueError(f"simulation lacks the turntable angle {np.rad2deg(t):.1f} deg")
        thetas.append(sim.theta.values[hit[0]])
    missing = sorted(set(real.p.values.tolist()) - set(sim.p.values.tolist()))
    if missing:
        raise ValueError(f"simulation lacks pin holes {missing} of the real data")
    sim = sim.sel(p=real.p.values, theta=thetas, tag=real.tag.values)
    return real, sim.assign_coords(theta=real.theta.values)


def gap_field(real: xr.Dataset, sim: xr.Dataset, sim_variant: str | None = None) -> GapField:
    """Compute the gap field of ``real`` against ``sim`` (aligned to the real configurations)."""
    real, sim = align(real, sim)
    visible = real.visible if "variant" not in real.visible.dims else real.visible.isel(variant=0)
    real_err, sim_err = mean_error(real), mean_error(sim, sim_variant)
    comparable = visible & real_err.notnull().all("axis") & sim_err.notnull().all("axis")
    gap = (real_err - sim_err).where(comparable)
    sigma = cast(xr.DataArray, np.sqrt(noise_scale(real) ** 2 + noise_scale(sim, sim_variant) ** 2))
    det_r = real.detected.isel(variant=0).mean("repeat").where(visible)
    sim_det = sim.detected.sel(variant=sim_variant) if sim_variant else sim.detected.isel(variant=0)
    det_s = sim_det.mean("repeat").where(visible)
    return GapField(gap, sigma, comparable, det_r, det_s)


@dataclass(frozen=True, kw_only=True)
class AxisGap:
    """The gap on one pose axis (m for tx, ty, tz; rad for rx, ry, rz): :func:`axis_summary`.

    Attributes
    ----------
    n : int
        Comparable items; the other values are None without any.
    unit : str
        ``"m"`` or ``"rad"``.
    significant : bool
        The gap on this axis is significant (:func:`axis_summary`).
    mean, median, rms : float
        Plain mean, median (the location tested) and RMS of the gap.
    slope_per_pin : float
        Theil-Sen trend of the gap per pin hole.
    z_median, z_slope : float
        z-scores of the median and of the trend.
    noise : float
        Noise of one gap value.
    systematic : float
        The larger of the median and the trend over half the distance range.
    """

    n: int
    unit: str
    significant: bool
    mean: float | None = None
    median: float | None = None
    rms: float | None = None
    slope_per_pin: float | None = None
    z_median: float | None = None
    z_slope: float | None = None
    noise: float | None = None
    systematic: float | None = None


@dataclass(frozen=True, kw_only=True)
class RegionGap:
    """The median gap of one axis in one distance region (:func:`region_summary`).

    Attributes
    ----------
    axis, region : str
        Pose axis and region (``"near (p 0-4)"`` and so on).
    n : int
        Comparable items in the region.
    median : float
        Median gap (m or rad).
    z : float
        Its z-score.
    significant : bool
        Beyond :data:`~simgap.analysis.thresholds.Z_SIGNIFICANT` and the practical floor.
    """

    axis: str
    region: str
    n: int
    median: float
    z: float
    significant: bool


@dataclass(frozen=True, kw_only=True)
class DetectionRates:
    """Detection rate of the real data and of the simulation over the visible items."""

    real: float
    sim: float
    visible_items: int


def axis_summary(field: GapField) -> dict[str, AxisGap]:
    """Per axis: robust location and trend of the gap with distance, z-scores, significance.

    Rotation estimates of a square marker are heavy-tailed (planar pose ambiguity), so the
    location is the median (standard error :func:`simgap.core.robust.median_standard_error`) and
    the trend with the pin hole is the Theil-Sen slope (its 95 % interval gives the z-score). The
    gap on an axis is significant when its median or its trend is more than
    :data:`~simgap.analysis.thresholds.Z_SIGNIFICANT` standard errors from zero *and* its
    systematic part (median and trend over the distance range) exceeds
    :data:`~simgap.analysis.thresholds.PRACTICAL_FLOOR`.
    """
    from scipy.stats import theilslopes

    out = {}
    ps = field.gap.p.values.astype(float)
    for axis in AXES:
        g = field.gap.sel(axis=axis).values  # tag, p, theta
        dist = np.broadcast_to(ps[None, :, None], g.shape)
        ok = np.isfinite(g)
        n = int(ok.sum())
        sigma = float(field.sigma.sel(axis=axis))
        unit = axis_unit(axis)
        if n == 0:
            out[axis] = AxisGap(n=0, unit=unit, significant=False)
            continue
        x, y = dist[ok], g[ok]
        median = float(np.median(y))
        scatter = max(mad_sigma(y), sigma)
        z_median = median / median_standard_error(scatter, n)
        slope = z_slope = 0.0
        if n >= 3 and np.ptp(x) > 0:
            slope, _, lo, hi = theilslopes(y, x)
            half = max(
                (hi - lo) / Z95_WIDTH,
                MEDIAN_SE_FACTOR * scatter / np.sqrt(np.sum((x - x.mean()) ** 2)),
            )
            z_slope = slope / half if half > 0 else 0.0
        trend = abs(slope) * np.ptp(x) / 2.0
        systematic = float(max(abs(median), trend))
        significant = (abs(z_median) > Z_SIGNIFICANT or abs(z_slope) > Z_SIGNIFICANT) and (
            systematic > PRACTICAL_FLOOR[unit]
        )
        out[axis] = AxisGap(
            n=n,
            unit=unit,
            significant=bool(significant),
            mean=float(np.mean(y)),
            median=median,
            rms=float(np.sqrt(np.mean(y**2))),
            slope_per_pin=float(slope),
            z_median=float(z_median),
            z_slope=float(z_slope),
            noise=sigma,
            systematic=systematic,
        )
    return out


def distance_thirds(pins: np.ndarray) -> dict[str, np.ndarray]:
    """Pin holes split into near, mid and far thirds, labelled ``"near (p 0-4)"`` and so on.

    Parameters
    ----------
    pins : array of int
        Pin holes, nearest first.

    Returns
    -------
    dict of str to ndarray
        Label -> the pin holes of that third (empty thirds left out).
    """
    pins = np.asarray(pins)
    thirds = np.array_split(np.arange(pins.size), 3)
    return {
        f"{name} (p {pins[idx].min()}-{pins[idx].max()})": pins[idx]
        for name, idx in zip(("near", "mid", "far"), thirds, strict=True)
        if idx.size
    }


def region_summary(field: GapField) -> list[RegionGap]:
    """Median gap per axis in near / mid / far thirds of the pin holes, with z-scores."""
    dist_bins = distance_thirds(field.gap.p.values)
    rows = []
    for axis in AXES:
        g = field.gap.sel(axis=axis)
        sigma = float(field.sigma.sel(axis=axis))
        for name, members in dist_bins.items():
            vals = g.sel(p=members).values
            vals = vals[np.isfinite(vals)]
            if vals.size == 0:
                continue
            med = float(np.median(vals))
            scatter = max(mad_sigma(vals), sigma)
            z = med / median_standard_error(scatter, vals.size)
            rows.append(
                RegionGap(
                    axis=axis,
                    region=name,
                    n=int(vals.size),
                    median=med,
                    z=float(z),
                    significant=bool(
                        abs(z) > Z_SIGNIFICANT and abs(med) > PRACTICAL_FLOOR[axis_unit(axis)]
                    ),
                )
            )
    return rows


def detection_summary(field: GapField) -> DetectionRates:
    """Detection rate of the real data and of the simulation over visible items."""
    r = field.real_detection.values
    s = field.sim_detection.values
    ok = np.isfinite(r) & np.isfinite(s)
    return DetectionRates(
        real=float(np.mean(r[ok])) if ok.any() else float("nan"),
        sim=float(np.mean(s[ok])) if ok.any() else float("nan"),
        visible_items=int(ok.sum()),
    )
