"""Reductions of a result dataset that the report and the comparison print and plot.

:func:`summarize_variant` reduces one variant to repeat-averaged errors and detection counts
(:class:`VariantSummary`); :func:`abs_error_envelope`, :func:`within_threshold_counts` and
:func:`fit_abs_error_slope` reduce that further. :func:`dataset_rig` is the rig a dataset was
made with, so that rig facts (the pin pitch, the tag faces, the pin holes) are read, never retyped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import xarray as xr
import yaml

from simgap.analysis.paper import threshold_for
from simgap.core.axes import AXES, AXIS_UNITS
from simgap.core.distance import camera_to_tag_distance
from simgap.core.rig import Rig, load_rig

REQUIRED_VARIABLES: Final[dict[str, tuple[str, ...]]] = {
    "error": ("variant", "repeat", "tag", "p", "theta", "axis"),
    "visible": ("tag", "p", "theta"),
    "detected": ("variant", "repeat", "tag", "p", "theta"),
}
"""Variables the report reads, with the dims each must have (``visible`` may add ``variant``)."""

REQUIRED_COORDS: Final[tuple[str, ...]] = ("tag", "p", "theta", "axis", "variant", "repeat")
"""Coordinates the report reads."""


@dataclass(frozen=True)
class VariantSummary:
    """Repeat-averaged errors and detection counts of one variant.

    Parameters
    ----------
    variant : str
        Name of the variant.
    n_repeat : int
        Number of repeats averaged.
    pin_pitch_m : float
        Carriage pin-hole pitch in metres.
    carriage_m : xarray.DataArray
        Carriage position ``pin_pitch_m * p`` in metres, dim ``p``.
    distance_m : xarray.DataArray
        Camera-to-tag distance in metres, dims ``(tag, p, theta)`` (:func:`dataset_distance_m`).
    abs_error : xarray.DataArray
        Mean over repeats of the absolute error (m for ``t*``, rad for ``r*``), dims
        ``(tag, p, theta, axis)``; NaN where the tag is not visible or was never detected.
    signed_error : xarray.DataArray
        Mean over repeats of the signed error, same dims, units and NaN pattern as `abs_error`.
    visible : xarray.DataArray
        Boolean, dims ``(tag, p, theta)``: the tag is expected to be detectable.
    detected_any : xarray.DataArray
        Boolean, dims ``(tag, p, theta)``: visible and detected in at least one repeat.
    n_visible : xarray.DataArray
        Number of visible configurations (p, theta) per tag, dim ``tag``.
    n_detected : xarray.DataArray
        Number of visible (configuration, repeat) pairs that were detected, dim ``tag``.
    n_failed : xarray.DataArray
        Number of visible (configuration, repeat) pairs that were not detected, dim ``tag``.
    n_unexpected : xarray.DataArray
        Number of (configuration, repeat) pairs detected although not visible (excluded from all
        statistics), dim ``tag``.
    """

    variant: str
    n_repeat: int
    pin_pitch_m: float
    carriage_m: xr.DataArray
    distance_m: xr.DataArray
    abs_error: xr.DataArray
    signed_error: xr.DataArray
    visible: xr.DataArray
    detected_any: xr.DataArray
    n_visible: xr.DataArray
    n_detected: xr.DataArray
    n_failed: xr.DataArray
    n_unexpected: xr.DataArray

    @property
    def tags(self) -> list[int]:
        """Tag ids, in dataset order."""
        return [int(t) for t in self.visible["tag"].values]

    @property
    def detection_rate(self) -> xr.DataArray:
        """Detected / visible (configuration, repeat) pairs per tag (dimensionless, NaN if none)."""
        attempts = self.n_visible * self.n_repeat
        return (self.n_detected / attempts.where(attempts > 0)).rename("detection_rate")


def check_report_dataset(ds: xr.Dataset) -> None:
    """Check that a result dataset has what the report reads.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset following the contract of docs/conventions.md §3.

    Raises
    ------
    ValueError
        Naming every missing variable and coordinate, a variable without its required dims, or
        missing values of the ``axis`` coordinate.
    """
    missing_vars = [name for name in REQUIRED_VARIABLES if name not in ds.data_vars]
    missing_coords = [name for name in REQUIRED_COORDS if name not in ds.coords]
    problems = []
    if missing_vars:
        problems.append(f"missing required variables: {', '.join(missing_vars)}")
    if missing_coords:
        problems.append(f"missing required coordinates: {', '.join(missing_coords)}")
    if problems:
        raise ValueError(f"result dataset cannot be reported: {'; '.join(problems)}")
    for name, dims in REQUIRED_VARIABLES.items():
        lacking = [d for d in dims if d not in ds[name].dims]
        if lacking:
            raise ValueError(
                f"variable {name!r} must have dims {dims}; it has {ds[name].dims}, "
                f"lacking {', '.join(lacking)}"
            )
    missing_axes = [a for a in AXES if a not in ds["axis"].values.tolist()]
    if missing_axes:
        raise ValueError(f"coordinate 'axis' lacks values: {', '.join(missing_axes)}")


def dataset_distance_m(ds: xr.Dataset) -> xr.DataArray:
    """Camera-to-tag distance of every item (tag, p, theta) of a result dataset (m).

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset: its ``expected`` poses are read (the dataset contract), or, for a dataset
        without them, the nominal poses of its rig (:func:`dataset_rig`).

    Returns
    -------
    xarray.DataArray
        Dims ``(tag, p, theta)``, :func:`simgap.core.distance.camera_to_tag_distance` in m.
    """
    order = ("tag", "p", "theta")
    if "expected" in ds.data_vars:
        poses = ds["expected"].transpose(*order, "axis").values
    else:
        grid = np.meshgrid(ds["tag"].values, ds["p"].values, ds["theta"].values, indexing="ij")
        flat = dataset_rig(ds).eyepoints_from_tags(*(g.ravel() for g in grid))
        poses = flat[:, :3, 3].reshape(grid[0].shape + (3,))
    return xr.DataArray(
        camera_to_tag_distance(poses),
        dims=order,
        coords={d: ds[d].values for d in order},
        name="distance_m",
        attrs={"units": "m", "long_name": "camera-to-tag distance"},
    )


def dataset_rig(ds: xr.Dataset) -> Rig:
    """The rig a result dataset was made with.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset. Its ``rig_yaml`` attr (captures: the whole rig) or the ``rig`` section
        of its ``experiment_yaml`` attr (simulations: overrides of the packaged rig) is read;
        without either, the packaged rig.

    Returns
    -------
    simgap.core.rig.Rig

    Raises
    ------
    simgap.core.config.ConfigError
        If the stored rig is not a valid rig (naming the attr and key).
    """
    for attr, section in (("rig_yaml", None), ("experiment_yaml", "rig")):
        text = ds.attrs.get(attr)
        if not text:
            continue
        data: Any = yaml.safe_load(text)
        if section is not None:
            data = data.get(section) if isinstance(data, dict) else None
        return load_rig(overrides=data if isinstance(data, dict) else {}, where=f"{attr}: ")
    return load_rig()


def as_bool(da: xr.DataArray) -> xr.DataArray:
    """Return `da` as booleans, NaN (from a netCDF fill value) read as False."""
    return da.fillna(0).astype(bool) if da.dtype.kind == "f" else da.astype(bool)


def summarize_variant(ds_variant: xr.Dataset, pin_pitch_m: float | None = None) -> VariantSummary:
    """Reduce one variant of a result dataset to repeat-averaged errors and detection counts.

    Parameters
    ----------
    ds_variant : xarray.Dataset
        Result dataset sliced to one variant, e.g. ``ds.isel(variant=0)`` (a ``variant`` dim of
        length 1 is also accepted).
    pin_pitch_m : float, optional
        Carriage pin-hole pitch in metres; carriage position is ``pin_pitch_m * p``. Default:
        the pitch of the dataset's rig (:func:`dataset_rig`).

    Returns
    -------
    VariantSummary
        Errors averaged over repeats with NaN skipped, restricted to visible items; an
        item counts as detected where its tag was detected in at least one repeat.

    Raises
    ------
    ValueError
        If the slice still holds more than one variant.
    """
    if "variant" in ds_variant.dims:
        if ds_variant.sizes["variant"] != 1:
            raise ValueError(
                "summarize_variant needs a one-variant slice; got "
                f"{ds_variant.sizes['variant']} variants"
            )
        ds_variant = ds_variant.isel(variant=0)
    if pin_pitch_m is None:
        pin_pitch_m = dataset_rig(ds_variant).links.pin_pitch
    order = ("tag", "p", "theta")
    visible = as_bool(ds_variant["visible"]).transpose(*order)
    detected = as_bool(ds_variant["detected"]).transpose("repeat", *order)
    error = ds_variant["error"].transpose("repeat", *order, "axis")
    error = error.where(detected & visible)
    with np.errstate(invalid="ignore"):
        abs_error = abs(error).mean("repeat", skipna=True)
        signed_error = error.mean("repeat", skipna=True)
    return VariantSummary(
        variant=str(ds_variant["variant"].values),
        n_repeat=int(ds_variant.sizes["repeat"]),
        pin_pitch_m=float(pin_pitch_m),
        carriage_m=(pin_pitch_m * ds_variant["p"]).astype(float).rename("carriage_m"),
        distance_m=dataset_distance_m(ds_variant),
        abs_error=abs_error.rename("abs_error"),
        signed_error=signed_error.rename("signed_error"),
        visible=visible,
        detected_any=(detected & visible).any("repeat"),
        n_visible=visible.sum(("p", "theta")),
        n_detected=(detected & visible).sum(("repeat", "p", "theta")),
        n_failed=(~detected & visible).sum(("repeat", "p", "theta")),
        n_unexpected=(detected & ~visible).sum(("repeat", "p", "theta")),
    )


def abs_error_envelope(summary: VariantSummary) -> xr.Dataset:
    """Return the max and min repeat-averaged absolute error over configurations.

    Parameters
    ----------
    summary : VariantSummary
        One variant's reduction (:func:`summarize_variant`); ``abs_error`` is read.

    Returns
    -------
    xarray.Dataset
        Variables ``max`` and ``min``, dims ``(tag, axis)``, in m (``t*``) or rad (``r*``); NaN
        where a tag has no estimate.
    """
    dims = ("p", "theta")
    return xr.Dataset(
        {
            "max": summary.abs_error.max(dims, skipna=True),
            "min": summary.abs_error.min(dims, skipna=True),
        }
    )


def thresholds() -> xr.DataArray:
    """High-precision threshold per axis (m or rad), dim ``axis``."""
    return xr.DataArray([threshold_for(a) for a in AXES], dims="axis", coords={"axis": list(AXES)})


def within_threshold_counts(summary: VariantSummary) -> xr.DataArray:
    """Count visible configurations whose absolute error is within the high-precision threshold.

    ``summary`` is one variant's reduction (:func:`summarize_variant`). Returns integer counts
    (:class:`xarray.DataArray`), dims ``(tag, axis)``. A visible configuration without an
    estimate counts as not within; divide by ``summary.n_visible`` for the fraction.
    """
    abs_error = summary.abs_error.sel(axis=list(AXES))
    return (abs_error <= thresholds()).sum(("p", "theta")).transpose("tag", "axis")


def fit_abs_error_slope(summary: VariantSummary, axis: str = "ty") -> xr.Dataset:
    """Fit a least-squares line to the absolute error of one axis against carriage position.

    All visible, detected configurations of a tag (every turntable angle) enter one fit of
    ``|error| = intercept + slope * carriage_m``.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`summarize_variant`.
    axis : str, optional
        Axis to fit, default ``"ty"``.

    Returns
    -------
    xarray.Dataset
        Dim ``tag``: ``slope`` (error unit per metre of carriage travel, i.e. m/m or rad/m),
        ``intercept`` (m or rad, at carriage position 0) and ``n_points``; NaN slope and
        intercept where fewer than two distinct carriage positions have data.
    """
    slopes, intercepts, counts = [], [], []
    for tag in summary.tags:
        y = summary.abs_error.sel(tag=tag, axis=axis).transpose("p", "theta").values
        x = np.broadcast_to(summary.carriage_m.values[:, None], y.shape)
        ok = np.isfinite(y)
        slope, intercept = line_fit(x[ok], y[ok])
        slopes.append(slope)
        intercepts.append(intercept)
        counts.append(int(ok.sum()))
    coords = {"tag": summary.tags}
    unit = AXIS_UNITS[axis]
    return xr.Dataset(
        {
            "slope": ("tag", slopes, {"units": f"{unit}/m"}),
            "intercept": ("tag", intercepts, {"units": unit}),
            "n_points": ("tag", counts),
        },
        coords=coords,
        attrs={"axis": axis},
    )


def line_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares ``y = intercept + slope * x``: ``(slope, intercept)``.

    Slope in units of y per unit of x, intercept in units of y; NaNs if x has fewer than two
    distinct values.
    """
    if np.unique(x).size < 2:
        return float("nan"), float("nan")
    design = np.column_stack([x, np.ones_like(x)])
    (slope, intercept), *_ = np.linalg.lstsq(design, y, rcond=None)
    return float(slope), float(intercept)
