"""The diagnosis' items: the real dataset's visible tags at its configurations, simulated, split.

An item is one visible (tag, p, theta) with the real and simulated errors, corners, image
statistics and detection outcomes (:class:`simgap.analysis.gap.Items`). Candidates are fitted
on one split of the items, chosen on a second and the reduction is reported on a third.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr
import yaml

from simgap.analysis import gap as gapmod
from simgap.analysis.gap import (
    Items,
    frame_corner_noise,
    noise_shift,
    propagated_pose_noise,
    repeat_median_stats,
)
from simgap.analysis.thresholds import FLIP_RAD, PRACTICAL_FLOOR
from simgap.core.axes import AXES, axis_unit
from simgap.core.config import to_mapping
from simgap.core.distance import camera_to_tag_distance
from simgap.core.rig import CameraModel, Rig
from simgap.effects.state import VariantState
from simgap.pipeline.experiment import Configurations, Experiment
from simgap.pose.cfa import CfaVerdict
from simgap.pose.image_stats import STAT_NAMES


def calibration_from_attrs(real: xr.Dataset) -> CameraModel | None:
    """The calibration a capture was ingested with (``calibration_yaml`` attr), or None."""
    text = real.attrs.get("calibration_yaml")
    if not text:
        return None
    data = yaml.safe_load(text)
    keys = ("width", "height", "fx", "fy", "cx", "cy", "distortion")
    model: dict[str, Any] = {k: (tuple(data[k]) if k == "distortion" else data[k]) for k in keys}
    if "distortion_model" in data:  # written only for a model other than plumb_bob
        model["distortion_model"] = data["distortion_model"]
    return CameraModel(**model)


def demosaicing_from_attrs(real: xr.Dataset) -> CfaVerdict | None:
    """The demosaicing a capture's colour frames show (``camera_demosaicing`` attr), or None.

    None where the dataset has no such attr (a simulation, or a capture ingested before it
    existed) or its frames show no colour filter array.
    """
    text = real.attrs.get("camera_demosaicing")
    if not text:
        return None
    verdict = CfaVerdict(**json.loads(text))
    return verdict if verdict.layout is not None else None


def response_from_attrs(real: xr.Dataset) -> tuple[float, ...] | None:
    """The camera's measured response a capture was ingested with (``camera_response``), or None.

    The relative exposure at each 8-bit code (:class:`simgap.pose.camera_response.CameraResponse`).
    """
    text = real.attrs.get("camera_response")
    return None if not text else tuple(float(v) for v in json.loads(text))


def simulation_experiment(real: xr.Dataset, exp: Experiment) -> Experiment:
    """``exp`` restricted to the real dataset's configurations, imaging as its camera does.

    With the capture's calibration (:func:`calibration_from_attrs`), its camera's measured
    response where it was ingested with one (:func:`response_from_attrs`: the simulation images
    and reads its levels through it, ``camera_response`` effect) and, where its colour
    frames show a Bayer colour filter array (:func:`demosaicing_from_attrs`), its layout
    demosaiced with the nearest method of the catalogue (``bayer`` effect): demosaicing moves
    the corners of a frame's grey image by a fraction of a pixel, which a simulation without it
    would read as a geometric gap. An experiment that names its own ``bayer`` or
    ``camera_response`` keeps it.
    """
    rig = dict(exp.rig)
    cal = calibration_from_attrs(real)
    if cal is not None:
        rig["camera"] = to_mapping(cal)
    conf = Configurations(
        tuple(int(p) for p in real.p.values),
        tuple(round(float(np.rad2deg(t)), 6) for t in real.theta.values),
        tuple(int(t) for t in real.tag.values),
    )
    effects = dict(exp.effects)
    response = response_from_attrs(real)
    if response is not None and "camera_response" not in effects:
        effects["camera_response"] = {"linear_at_dn": response}
    cfa = demosaicing_from_attrs(real)
    if cfa is not None and "bayer" not in effects:
        effects["bayer"] = {"pattern": cfa.layout, "method": cfa.method}
    return dataclasses.replace(
        exp, rig=rig, configurations=conf, variants=(), grid={}, effects=effects
    )


def with_render_seeds(exp: Experiment, seeds: int) -> Experiment:
    """``exp`` with at least ``seeds`` repeats, each rendered with its own seed (one: unchanged).

    Path traced, the simulation's render noise at each item is then measured by its
    repeats (:func:`simgap.analysis.gap.item_noise`), and their mean carries less of
    it; converged, its repeats differ little, and the capture keeps as many frames a pose
    (:func:`repeats_of_simulation`).
    """
    if seeds <= 1:
        return exp
    reseeded = exp.with_render(reseed_repeats=True)
    return dataclasses.replace(reseeded, repeats=max(exp.repeats, seeds))


def repeats_of_simulation(real: xr.Dataset, sim: xr.Dataset) -> xr.Dataset:
    """``real`` with no more repeats than ``sim`` has, so that like is compared with like.

    A capture with two frames per pose against a simulation with one (a deterministic image
    pipeline) would compare the real repeats' spread with the simulation's neighbour residuals
    (:mod:`simgap.analysis.gap._evidence`); its first frames are compared instead. The temporal
    noise, measured across a pose's frames at ingest, is kept (on the first repeat).
    """
    n = sim.sizes["repeat"]
    if real.sizes["repeat"] <= n:
        return real
    out = real.isel(repeat=slice(0, n))
    if "image_stats" in real:
        temporal = [s for s in real.stat.values if str(s).startswith("temporal_")]
        with warnings.catch_warnings():  # poses with one readable frame are all-NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            kept = real.image_stats.sel(stat=temporal).median("repeat", skipna=True)
        stats = out.image_stats.copy()
        stats.loc[{"repeat": out.repeat.values[0], "stat": temporal}] = kept
        out = out.assign(image_stats=stats)
    return out


def repeat_mean_corners(ds: xr.Dataset) -> xr.DataArray:
    """Detected corners of the first variant, averaged over repeats (px).

    Dimensions (tag, p, theta, corner, uv); NaN where never detected.
    """
    with warnings.catch_warnings():  # never-detected items are all-NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        corners = ds.corners.isel(variant=0).mean("repeat", skipna=True)
    return corners.transpose("tag", "p", "theta", "corner", "uv")


def build_items(real: xr.Dataset, sim: xr.Dataset, field: gapmod.GapField) -> Items:
    """The visible (tag, p, theta) items with their errors, corners, image statistics, detection.

    Errors (m, rad) and corners (px) are NaN where a side did not detect the tag, and errors
    where either side's pose is a flip of the planar ambiguity (a rotation error beyond
    :data:`~simgap.analysis.thresholds.FLIP_RAD`); such items still carry corners, image
    statistics and detection outcomes. Each item's scale (N, 6) is the per-axis gap noise, at
    least :data:`simgap.analysis.thresholds.PRACTICAL_FLOOR`, or the item's own noise measured by
    the repeats when larger (:func:`simgap.analysis.gap.item_noise`).
    """
    real, sim = gapmod.align(real, sim)
    visible = field.real_detection.notnull()
    idx = np.argwhere(visible.values)
    tags, ps, thetas = real.tag.values, real.p.values, real.theta.values
    at = (idx[:, 0], idx[:, 1], idx[:, 2])
    r_err = gapmod.mean_error(real).values
    s_err = gapmod.mean_error(sim).values
    # a pose on the other branch of the planar ambiguity on either side compares nothing: no
    # effect of the catalogue turns a rotation by this much (a noise-driven flip of one far
    # tag in a 9-item capture decided which effect "explained" the pose)
    flipped = np.maximum(np.abs(r_err[..., 3:]), np.abs(s_err[..., 3:])).max(-1) > FLIP_RAD
    r_err = np.where(flipped[..., None], np.nan, r_err)
    s_err = np.where(flipped[..., None], np.nan, s_err)
    r_c, s_c = repeat_mean_corners(real).values, repeat_mean_corners(sim).values
    floors = np.array([PRACTICAL_FLOOR[axis_unit(a)] for a in AXES])
    scale = np.maximum(field.sigma.values, floors)
    # an item whose repeats show more noise than the per-axis level gets its own
    noise = gapmod.item_noise(real, sim).transpose("tag", "p", "theta", "axis").values
    scale = np.fmax(scale, noise[at])
    stats = {}
    for name, ds in (("real", real), ("sim", sim)):
        if "image_stats" in ds:
            stats[name] = repeat_median_stats(ds).values[at]
        else:
            stats[name] = np.full((len(idx), len(STAT_NAMES)), np.nan)
    return Items(
        tag=tags[idx[:, 0]],
        p=ps[idx[:, 1]],
        theta=thetas[idx[:, 2]],
        real_err=r_err[at],
        sim_err=s_err[at],
        real_corners=r_c[at],
        sim_corners=s_c[at],
        scale=scale,
        real_stats=stats["real"],
        sim_stats=stats["sim"],
        real_detected=field.real_detection.values[at],
        sim_detected=field.sim_detection.values[at],
    )


def item_distances(items: Items, rig: Rig) -> np.ndarray:
    """Camera-to-tag distance of each item in the rig's nominal pose (N,) (m)."""
    poses = rig.eyepoints_from_tags(items.tag, items.p, items.theta)
    return camera_to_tag_distance(poses[:, :3, 3])


def with_propagated_noise(items: Items, sigma_px: float, rig: Rig, base: VariantState) -> Items:
    """``items`` whose scale is at least each item's propagated pose noise.

    For a simulation whose repeats measure no noise (a converged render): corner noise of
    ``sigma_px`` per coordinate (the diagnosis takes the corner channel's unit, the gap's corner
    noise of both sides, :func:`simgap.analysis.gap.corner_unit`, over sqrt 2: its two
    coordinates) is propagated through PnP at the simulated corners, or the real ones where the
    simulation found none (:func:`simgap.analysis.gap.propagated_pose_noise`).
    """
    found = np.isfinite(items.sim_corners).all(axis=(1, 2))
    corners = np.where(found[:, None, None], items.sim_corners, items.real_corners)
    noise = propagated_pose_noise(corners, sigma_px, rig, base)
    return dataclasses.replace(items, scale=np.fmax(items.scale, noise))


def split_items(
    n: int, fit_fraction: float, choose_fraction: float, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Disjoint random fit / choose / measure index sets of ``n`` items (each non-empty if n >= 3).

    Parameters
    ----------
    n : int
        Number of items.
    fit_fraction, choose_fraction : float
        Shares of the fit and choice splits; the measure split takes the rest.
    seed : int
        Seed of the permutation.
    """
    order = np.random.default_rng(seed).permutation(n)
    if n < 3:
        return np.sort(order), np.sort(order), np.sort(order)
    k_fit = min(max(int(round(fit_fraction * n)), 1), n - 2)
    k_choose = min(max(int(round(choose_fraction * n)), 1), n - k_fit - 1)
    cut = k_fit + k_choose
    return np.sort(order[:k_fit]), np.sort(order[k_fit:cut]), np.sort(order[cut:])


def subsample(index: np.ndarray, k: int, seed: int) -> np.ndarray:
    """At most ``k`` of ``index``, drawn without replacement (sorted); all when it has ``k``."""
    if index.size <= k:
        return index
    return np.sort(np.random.default_rng(seed + 1).choice(index, k, replace=False))


@dataclass(frozen=True)
class NoiseShift:
    """The pose shift a capture's corner noise gives a noise-free simulation.

    Made by :func:`with_noise_shift`.

    Attributes
    ----------
    corner_px : float
        The capture's corner noise beyond the simulation's (px, one coordinate of one frame).
    frames : int
        Frames a pose the capture's repeat mean averages.
    shift : xarray.DataArray
        Median pose under that noise minus the undisturbed pose (tag, p, theta, axis) (m, rad),
        on the real dataset's configurations; NaN where the simulation found no corners.
    """

    corner_px: float
    frames: int
    shift: xr.DataArray

    def at(self, items: Items) -> np.ndarray:
        """The shift at each of ``items``.

        Parameters
        ----------
        items : Items
            Items on the grid of :attr:`shift` (their tag, p and theta).

        Returns
        -------
        ndarray (N, 6)
            The shift per item and axis (m, rad); NaN where the simulation found no corners.
        """
        where = {
            "tag": xr.DataArray(items.tag, dims="item"),
            "p": xr.DataArray(items.p, dims="item"),
            "theta": xr.DataArray(items.theta, dims="item"),
        }
        return self.shift.sel(where).transpose("item", "axis").values


def with_noise_shift(
    real: xr.Dataset, sim: xr.Dataset, rig: Rig, base: VariantState
) -> tuple[xr.Dataset, NoiseShift]:
    """A converged ``sim`` whose errors are the poses it would read with ``real``'s corner noise.

    At a far, oblique tag PnP turns corner noise into a one-sided shift of the pose
    (:func:`simgap.analysis.gap.noise_shift`): the capture's pose there carries it, a
    noise-free simulation's does not. Each simulated item's error (every variant and
    repeat) is moved by the median shift under the capture's corner noise beyond the
    simulation's own, both from their median PnP reprojection errors (sqrt(real^2 - sim^2),
    :func:`simgap.analysis.gap.frame_corner_noise`), with as many frames a draw as the
    capture averages (``real`` has the simulation's repeats:
    :func:`repeats_of_simulation`).

    Parameters
    ----------
    real : xarray.Dataset
        The capture (its PnP reprojection errors, px, and its repeats).
    sim : xarray.Dataset
        Its converged simulation (errors, m and rad; corners and reprojection errors, px).
    rig, base : Rig, VariantState
        The fixture and the simulation's state, whose calibration and PnP settings solve the
        poses (:func:`simgap.analysis.gap._pose_noise.pose_draws`).

    Returns
    -------
    xarray.Dataset
        ``sim`` aligned to ``real`` (:func:`simgap.analysis.gap.align`), its errors shifted.
    NoiseShift
        The noise used and the shift per item.
    """
    real, sim = gapmod.align(real, sim)
    real_px = frame_corner_noise(real.reproj_px.isel(variant=0).values)
    sim_px = frame_corner_noise(sim.reproj_px.isel(variant=0).values)
    sigma = float(np.sqrt(max(real_px**2 - sim_px**2, 0.0)))
    frames = int(real.sizes["repeat"])
    corners = repeat_mean_corners(sim)
    grid = corners.shape[:3]
    shift = noise_shift(corners.values.reshape(-1, 4, 2), sigma, rig, base, frames)
    coords = {"tag": sim.tag.values, "p": sim.p.values, "theta": sim.theta.values}
    shift_da = xr.DataArray(
        shift.reshape(grid + (len(AXES),)),
        coords=coords | {"axis": list(AXES)},
        dims=("tag", "p", "theta", "axis"),
        attrs={"units": "m or rad"},
    )
    error = (sim.error + shift_da.fillna(0.0)).transpose(*sim.error.dims)
    error.attrs = dict(sim.error.attrs)  # its units and names, as the simulation's
    return sim.assign(error=error), NoiseShift(sigma, frames, shift_da)
