"""A photo dataset read in the engineer's units: errors per axis, near / mid / far.

The dataset is :func:`simgap.pipeline.photos.measure_photos`'s: single-marker pose errors
against the board's reference in the OpenCV camera frame (x right, y down, z depth).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass

import numpy as np
import xarray as xr

from simgap.core.distance import BAND_NAMES, distance_thirds


@dataclass(frozen=True)
class DistanceBandErrors:
    """Median single-marker errors of the markers in one distance band.

    Attributes
    ----------
    band : str
        ``near``, ``mid`` or ``far`` (thirds of the set's distances).
    distance_min_m, distance_max_m : float
        The band's range of camera-to-marker distances (m).
    markers : int
        Marker sightings (marker x photo) in the band.
    translation_median_mm : tuple of float
        Median signed position error along x, y, z (mm; z is depth, + farther than the board
        says).
    rotation_median_abs_mrad : tuple of float
        Median absolute rotation error about x, y, z (mrad).
    """

    band: str
    distance_min_m: float
    distance_max_m: float
    markers: int
    translation_median_mm: tuple[float, float, float]
    rotation_median_abs_mrad: tuple[float, float, float]


def _sightings(ds: xr.Dataset, name: str) -> np.ndarray:
    """A per-axis error of a photo dataset, one row per sighting (frame x marker), (n, 3)."""
    return ds[name].transpose("frame", "marker", "camera_axis").values.reshape(-1, 3)


def _bands(dist: np.ndarray) -> list[tuple[str, np.ndarray, float, float]]:
    """Each non-empty distance third: its name, its sightings (mask) and its range (m)."""
    band = distance_thirds(dist)
    return [
        (name, band == k, float(dist[band == k].min()), float(dist[band == k].max()))
        for k, name in enumerate(BAND_NAMES)
        if (band == k).any()
    ]


def errors_by_distance(ds: xr.Dataset) -> list[DistanceBandErrors]:
    """The photo dataset's errors in the near, mid and far thirds of its distances."""
    dist = ds["distance"].values.ravel()
    dt, dr = _sightings(ds, "error_translation"), _sightings(ds, "error_rotation")
    out = []
    for name, sel, lo, hi in _bands(dist):
        out.append(
            DistanceBandErrors(
                band=name,
                distance_min_m=lo,
                distance_max_m=hi,
                markers=int(sel.sum()),
                translation_median_mm=tuple(1e3 * np.median(dt[sel], axis=0)),  # type: ignore[arg-type]
                rotation_median_abs_mrad=tuple(1e3 * np.median(np.abs(dr[sel]), axis=0)),  # type: ignore[arg-type]
            )
        )
    return out


def errors_table(bands: list[DistanceBandErrors]) -> str:
    """The bands as a plain-text table (mm, mrad), one line a band."""
    lines = [
        "band  distance (m)   n    x (mm)   y (mm)   z/depth (mm)   |rx| |ry| |rz| (mrad)",
    ]
    for b in bands:
        x, y, z = b.translation_median_mm
        rx, ry, rz = b.rotation_median_abs_mrad
        lines.append(
            f"{b.band:<5} {b.distance_min_m:.3f}-{b.distance_max_m:.3f}  {b.markers:>4} "
            f"{x:>8.2f} {y:>8.2f} {z:>12.2f}     {rx:5.1f} {ry:5.1f} {rz:5.1f}"
        )
    return "\n".join(lines)


#: Where a gap is read: covariate -> (unit, names of its thirds, low to high). The distance
#: from the camera (m), the view angle from facing (deg) and the marker centre's distance from
#: the principal point in the image (px).
COVARIATES = {
    "distance": ("m", ("near", "mid", "far")),
    "view_angle": ("deg", ("facing", "mid", "oblique")),
    "image_radius": ("px", ("centre", "mid", "edge")),
}


@dataclass(frozen=True)
class BandGap:
    """Real against simulated single-marker errors in one third of a covariate (real values).

    Attributes
    ----------
    covariate : str
        A key of :data:`COVARIATES`.
    band : str
        The third's name (``near`` ... ``far``, ``facing`` ... ``oblique``, ``centre`` ...
        ``edge``).
    low, high : float
        The third's range of the covariate (its unit).
    markers : int
        Sightings (marker x photo) seen in both.
    real_median_mm, simulated_median_mm : tuple of float
        Median signed position error along x, y, z (mm) of the photos and of their simulation.
    gap_median_mm : tuple of float
        Median over the sightings of real - simulated (mm): what the simulation leaves out.
    """

    covariate: str
    band: str
    low: float
    high: float
    markers: int
    real_median_mm: tuple[float, float, float]
    simulated_median_mm: tuple[float, float, float]
    gap_median_mm: tuple[float, float, float]


def _covariate(ds: xr.Dataset, name: str) -> np.ndarray:
    """Per sighting (frame x marker), the covariate ``name`` of :data:`COVARIATES`."""
    if name != "image_radius":
        return ds[name].transpose("frame", "marker").values.ravel()
    camera = ast.literal_eval(ds.attrs["calibration"])
    du = ds["centre_u"].transpose("frame", "marker").values.ravel() - camera["cx"]
    dv = ds["centre_v"].transpose("frame", "marker").values.ravel() - camera["cy"]
    return np.hypot(du, dv)


def gap_by(real: xr.Dataset, simulated: xr.Dataset, covariate: str = "distance") -> list[BandGap]:
    """Real photos against their simulation (:func:`simgap.pipeline.photos.simulate_photos`).

    Sightings seen in both, in thirds of the real ``covariate`` (:data:`COVARIATES`).
    """
    dt_real = _sightings(real, "error_translation")
    dt_sim = _sightings(simulated, "error_translation")
    both = np.isfinite(dt_real).all(axis=1) & np.isfinite(dt_sim).all(axis=1)
    values = np.where(both, _covariate(real, covariate), np.nan)
    names = COVARIATES[covariate][1]
    out = []
    for name, sel, lo, hi in _bands(values):
        out.append(
            BandGap(
                covariate=covariate,
                band=names[BAND_NAMES.index(name)],
                low=lo,
                high=hi,
                markers=int(sel.sum()),
                real_median_mm=tuple(1e3 * np.median(dt_real[sel], axis=0)),  # type: ignore[arg-type]
                simulated_median_mm=tuple(1e3 * np.median(dt_sim[sel], axis=0)),  # type: ignore[arg-type]
                gap_median_mm=tuple(1e3 * np.median(dt_real[sel] - dt_sim[sel], axis=0)),  # type: ignore[arg-type]
            )
        )
    return out


def gap_table(bands: list[BandGap]) -> str:
    """The bands as a plain-text table: depth (z) real, simulated and their gap, x and y gap."""
    if not bands:
        return "(no sighting seen in both)"
    covariate = bands[0].covariate
    unit = COVARIATES[covariate][0]
    head = f"{covariate} ({unit})"
    lines = [f"band     {head:<18} n   depth real  simulated   gap (mm)   gap x, y (mm)"]
    for b in bands:
        span = f"{b.low:.3g}-{b.high:.3g}"
        lines.append(
            f"{b.band:<8} {span:<18} {b.markers:>3} "
            f"{b.real_median_mm[2]:>10.2f} {b.simulated_median_mm[2]:>10.2f} "
            f"{b.gap_median_mm[2]:>10.2f}   {b.gap_median_mm[0]:6.2f} {b.gap_median_mm[1]:6.2f}"
        )
    return "\n".join(lines)


__all__ = [
    "COVARIATES",
    "BandGap",
    "DistanceBandErrors",
    "errors_by_distance",
    "errors_table",
    "gap_by",
    "gap_table",
]
