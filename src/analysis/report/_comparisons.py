"""Paired comparison of a result dataset's variants with a reference variant.

A *variant* is one rendering or estimation option (``baseline``, ``distortion``, ``glossy_tags``,
``defocus``, ``noise``, ...). The *reference* is the variant named ``baseline``, or the first
variant if none is, unless another is named. Every other variant is compared with it,
item by item:

1. each variant is reduced by :func:`simgap.analysis.report.summarize_variant` (errors
   averaged over repeats with NaN skipped, visible items only);
2. an item ``(tag, p, theta)`` is *paired* when both the variant and the reference have an
   estimate of every axis there; all error statistics use paired items only, so a change
   of detection does not masquerade as a change of error (detection rates are reported apart);
3. the spread over repeats (sample standard deviation, ``ddof=1``) is the noise level.

:func:`compare_variants` returns all of this as one :class:`xarray.Dataset` in SI units (m, rad);
the tables (:mod:`simgap.analysis.report._tables`) and figures convert to mm and mrad. Where each
tag faces the camera and which pin holes exist are read from the dataset's rig
(:func:`simgap.analysis.report.dataset_rig`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

import numpy as np
import xarray as xr

from simgap.analysis.report._summaries import (
    as_bool,
    check_report_dataset,
    dataset_distance_m,
    dataset_rig,
    summarize_variant,
)
from simgap.core.axes import display_unit
from simgap.core.rig import Rig
from simgap.results.cf import ERROR_UNITS

REFERENCE_NAME: Final[str] = "baseline"
"""Variant used as the reference when none is named (else the first variant)."""

_CHANGE_VARIABLES: Final[tuple[str, ...]] = (
    "reference_abs_error",
    "abs_error",
    "abs_change",
    "signed_shift",
    "reference_noise",
    "noise",
)


def to_display(da: xr.DataArray) -> xr.DataArray:
    """``da`` (with an ``axis`` dim, m or rad) in display units: mm (``t*``), mrad (``r*``)."""
    factors = [display_unit(str(a))[1] for a in da["axis"].values]
    return da * xr.DataArray(factors, coords={"axis": da["axis"].values}, dims="axis")


def variant_names(ds: xr.Dataset) -> list[str]:
    """Return the variant names of a result dataset, in dataset order."""
    return [str(v) for v in np.atleast_1d(ds["variant"].values)]


def resolve_baseline(ds: xr.Dataset, baseline: str | None = None) -> str:
    """Return the reference variant of a comparison.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset with a ``variant`` coordinate.
    baseline : str, optional
        Reference variant; default: ``"baseline"`` if present, else the first variant.

    Returns
    -------
    str
        Name of the reference variant.

    Raises
    ------
    ValueError
        If the dataset has fewer than two variants, or `baseline` is not one of them (the message
        lists the variants).
    """
    names = variant_names(ds)
    if len(names) < 2:
        raise ValueError(f"needs at least two variants; dataset has: {names}")
    if baseline is None:
        return REFERENCE_NAME if REFERENCE_NAME in names else names[0]
    if baseline not in names:
        raise ValueError(
            f"baseline {baseline!r} is not a variant of the dataset; variants: {names}"
        )
    return baseline


def view_angle_deg(theta_rad: xr.DataArray, facing_theta_rad: Mapping[int, float]) -> xr.DataArray:
    """Return each tag's view angle: turntable angle relative to where the tag faces the camera.

    Parameters
    ----------
    theta_rad : xarray.DataArray
        Turntable angles (rad), dim ``theta``.
    facing_theta_rad : mapping of int to float
        Turntable angle (rad) at which each tag faces the camera, e.g.
        :func:`rig_facing_theta_rad` of the dataset's rig.

    Returns
    -------
    xarray.DataArray
        Dims ``(tag, theta)``: ``theta - facing`` wrapped to [-180, 180] deg (rounded to 1e-6 deg
        so that bin edges such as 20 deg are exact); 0 where the tag faces the camera.
    """
    tags = list(facing_theta_rad)
    facing = xr.DataArray([float(facing_theta_rad[t]) for t in tags], coords={"tag": tags})
    wrapped = np.angle(np.exp(1j * (theta_rad - facing).transpose("tag", "theta").values))
    return xr.DataArray(
        np.round(np.degrees(wrapped), 6),
        coords={"tag": tags, "theta": theta_rad["theta"].values},
        dims=("tag", "theta"),
        attrs={"units": "deg", "long_name": "turntable angle relative to facing the camera"},
    )


def rig_facing_theta_rad(rig: Rig) -> dict[int, float]:
    """Turntable angle (rad) at which each of the rig's tags faces the camera.

    A tag faces the camera when its outward normal, turned with the turntable, points along the
    global -Y axis (towards the eyepoint): 0 for a tag on the node's outer face, pi for one on
    the inner face (docs/conventions.md §1). Angles in [0, 2 pi).
    """
    out = {}
    for tag in rig.tags.ids:
        nx, ny = rig.turntable_from_tag(tag)[:2, 2]
        out[int(tag)] = float((-np.pi / 2 - np.arctan2(ny, nx)) % (2 * np.pi))
    return out


def _facing_theta(
    ds: xr.Dataset, facing: Mapping[int, float] | None, rig: Rig
) -> dict[int, float]:
    """Facing angle per tag of `ds` (rad).

    From `facing` (default: the rig's), else the circular mean of the angles where it is visible.
    """
    facing = rig_facing_theta_rad(rig) if facing is None else facing
    theta = ds["theta"].values.astype(float)
    out = {}
    for tag in (int(t) for t in ds["tag"].values):
        if tag in facing:
            out[tag] = float(facing[tag])
            continue
        visible = as_bool(ds["visible"].sel(tag=tag))
        seen = visible.any([d for d in visible.dims if d != "theta"]).values
        out[tag] = float(np.angle(np.exp(1j * theta[seen]).sum())) if seen.any() else 0.0
    return out


def _repeat_spread(ds_variant: xr.Dataset) -> xr.DataArray:
    """Sample std (ddof=1) over repeats of visible, detected errors; NaN with < 2 estimates."""
    usable = as_bool(ds_variant["detected"]) & as_bool(ds_variant["visible"])
    error = ds_variant["error"].where(usable)
    with np.errstate(invalid="ignore", divide="ignore"):
        spread = error.std("repeat", ddof=1, skipna=True)
    return spread.where(error.count("repeat") >= 2).transpose("tag", "p", "theta", "axis")


def _compare_one(ds: xr.Dataset, reference: str, variant: str, pitch_m: float) -> xr.Dataset:
    """Paired per-item comparison of one variant with the reference (SI units)."""
    ref = summarize_variant(ds.sel(variant=reference), pitch_m)
    var = summarize_variant(ds.sel(variant=variant), pitch_m)
    paired = (ref.abs_error.notnull() & var.abs_error.notnull()).all("axis")
    variables = {
        "reference_abs_error": ref.abs_error.where(paired),
        "abs_error": var.abs_error.where(paired),
        "abs_change": (var.abs_error - ref.abs_error).where(paired),
        "signed_shift": (var.signed_error - ref.signed_error).where(paired),
        "reference_noise": _repeat_spread(ds.sel(variant=reference)).where(paired),
        "noise": _repeat_spread(ds.sel(variant=variant)).where(paired),
        "paired": paired,
        "reference_n_detected": ref.n_detected,
        "reference_n_attempts": ref.n_visible * ref.n_repeat,
        "n_detected": var.n_detected,
        "n_attempts": var.n_visible * var.n_repeat,
    }
    # the slices carry their scalar ``variant`` coordinate, which differs between the two
    return xr.Dataset({k: v.drop_vars("variant", errors="ignore") for k, v in variables.items()})


def compare_variants(
    ds: xr.Dataset,
    baseline: str | None = None,
    *,
    facing_theta_rad: Mapping[int, float] | None = None,
) -> xr.Dataset:
    """Compare every variant of a result dataset with the reference, item by item.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset (docs/conventions.md §3) with at least two variants; ``visible`` may have
        dims ``(tag, p, theta)`` or ``(variant, tag, p, theta)``.
    baseline : str, optional
        Reference variant (see :func:`resolve_baseline`).
    facing_theta_rad : mapping of int to float, optional
        Turntable angle (rad) at which each tag faces the camera; default
        :func:`rig_facing_theta_rad` of the dataset's rig.

    Returns
    -------
    xarray.Dataset
        Dim ``variant`` holds the compared variants (the reference excluded). Per
        ``(variant, tag, p, theta, axis)``, in m (``t*``) or rad (``r*``), NaN unless paired:
        ``reference_abs_error`` and ``abs_error`` (mean over repeats of ``|error|``),
        ``abs_change`` (their difference, variant - reference), ``signed_shift`` (repeat-mean
        signed error, variant - reference), ``reference_noise`` and ``noise`` (std over repeats).
        ``paired`` (variant, tag, p, theta): both have an estimate of every axis. Detection counts
        per ``(variant, tag)``: ``n_detected``, ``n_attempts`` (visible configurations x
        repeats), ``reference_n_detected``, ``reference_n_attempts``. Coordinate
        ``view_angle_deg`` (tag, theta), see :func:`view_angle_deg`, and ``distance_m``
        (tag, p, theta), the camera-to-tag distance
        (:func:`~simgap.analysis.report.dataset_distance_m`). Attrs ``baseline``,
        ``n_repeat``, ``pin_holes`` (the rig's, for the distance bins) and
        ``facing_theta_deg`` (tag -> turntable angle facing the camera, deg).

    Raises
    ------
    ValueError
        If the dataset lacks what the report reads, has one variant, or `baseline` is unknown.
    """
    check_report_dataset(ds)
    rig = dataset_rig(ds)
    reference = resolve_baseline(ds, baseline)
    others = [v for v in variant_names(ds) if v != reference]
    out = xr.concat(
        [_compare_one(ds, reference, v, rig.links.pin_pitch) for v in others],
        dim=xr.DataArray(np.asarray(others, dtype=str), dims="variant", name="variant"),
        coords="minimal",
        compat="override",
    )
    for name in _CHANGE_VARIABLES:
        out[name].attrs["units"] = ERROR_UNITS
    facing = _facing_theta(ds, facing_theta_rad, rig)
    angles = view_angle_deg(ds["theta"].astype(float), facing)
    out = out.assign_coords(
        view_angle_deg=angles.sel(tag=out["tag"]),
        distance_m=dataset_distance_m(ds).sel(tag=out["tag"], p=out["p"], theta=out["theta"]),
    )
    out.attrs.update(
        baseline=reference,
        n_repeat=int(ds.sizes["repeat"]),
        description="variants compared with attrs['baseline'] over paired items",
        pin_holes=[int(p) for p in rig.grid.p],
        facing_theta_deg={int(t): float(np.degrees(a)) for t, a in facing.items()},
    )
    return out


def as_comparison(data: xr.Dataset, baseline: str | None) -> xr.Dataset:
    """The comparison that the comparison tables and figures read.

    Parameters
    ----------
    data : xarray.Dataset
        A result dataset, or the output of :func:`compare_variants` (returned as it is, and then
        `baseline` is ignored).
    baseline : str or None
        Reference variant (see :func:`resolve_baseline`).
    """
    return data if "abs_change" in data.data_vars else compare_variants(data, baseline)


def change_by_p(data: xr.Dataset, baseline: str | None = None) -> xr.DataArray:
    """Return the change of mean ``|error|`` per pin hole, in display units (mm, mrad).

    Parameters
    ----------
    data, baseline
        What to compare, as in :func:`as_comparison`.

    Returns
    -------
    xarray.DataArray
        Dims ``(variant, p, axis)``: mean over paired ``(tag, theta)`` of variant - reference
        ``|error|``, mm for ``t*`` and mrad for ``r*``; NaN where no item is paired.
        Coordinate ``distance_m`` (variant, p): mean camera-to-tag distance (m) of the paired
        items averaged, the x of the change-by-distance figure.
    """
    cmp = as_comparison(data, baseline)
    with np.errstate(invalid="ignore"):
        change = to_display(cmp["abs_change"].mean(("tag", "theta")))
        distance = cmp["distance_m"].where(cmp["paired"]).mean(("tag", "theta"))
    change = change.transpose("variant", "p", "axis")
    change = change.assign_coords(distance_m=distance.transpose("variant", "p"))
    return change.rename("change_mean_abs").assign_attrs(units="mm (tx, ty, tz); mrad (rx, ry, rz)")
