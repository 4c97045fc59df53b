"""A photo dataset read in the engineer's units: errors per axis, near / mid / far.

The dataset is :func:`simgap.pipeline.photos.measure_photos`'s: single-marker pose errors
against the board's reference in the OpenCV camera frame (x right, y down, z depth).
"""

from __future__ import annotations

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


def errors_by_distance(ds: xr.Dataset) -> list[DistanceBandErrors]:
    """The photo dataset's errors in the near, mid and far thirds of its distances."""
    dist = ds["distance"].values.ravel()
    dt = ds["error_translation"].transpose("frame", "marker", "camera_axis").values.reshape(-1, 3)
    dr = ds["error_rotation"].transpose("frame", "marker", "camera_axis").values.reshape(-1, 3)
    band = distance_thirds(dist)
    out = []
    for k, name in enumerate(BAND_NAMES):
        sel = band == k
        if not sel.any():
            continue
        out.append(
            DistanceBandErrors(
                band=name,
                distance_min_m=float(dist[sel].min()),
                distance_max_m=float(dist[sel].max()),
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


__all__ = ["DistanceBandErrors", "errors_by_distance", "errors_table"]
