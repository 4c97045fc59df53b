"""Image evidence of result datasets: tag distance and view angle, and figures of the statistics.

The statistics themselves are measured per tag and frame by :mod:`simgap.pose.image_stats` and
stored in a result dataset as ``image_stats`` (variant, repeat, tag, p, theta, stat). Here they are
put against the tag's distance and view angle, both computed from the dataset's ``expected`` pose
(the dataset contract, docs/conventions.md §3), so no rig is needed.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np
import xarray as xr
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.spatial.transform import Rotation

from simgap.core.distance import DISTANCE_LABEL, camera_to_tag_distance
from simgap.pose.image_stats import STAT_NAMES
from simgap.pose.stat_labels import stat_label

#: Statistics shown in the figures (the others are kept in the dataset and result.json).
PLOTTED_STATS: tuple[str, ...] = (
    "ink_linear",
    "paper_linear",
    "contrast",
    "edge_width_x_px",
    "edge_width_y_px",
    "noise_ink_linear",
    "noise_paper_linear",
    "clipped_fraction",
    "highlight_fraction",
    "rejected_candidates",
    "blockiness",
)


#: Axis label of a view angle: between the line of sight and the tag's normal (0 deg facing the
#: camera, 90 deg edge-on), the angle the report's heatmaps count from facing too.
VIEW_ANGLE_LABEL = "view angle from facing [deg] (0: facing the camera)"


def tag_distance_and_view_angle(ds: xr.Dataset) -> tuple[xr.DataArray, xr.DataArray]:
    """Camera-to-tag distance (m) and view angle (deg) of each tag, (tag, p, theta).

    The distance is :func:`simgap.core.distance.camera_to_tag_distance` of ``expected``.

    The view angle is the angle between the line of sight and the tag plane: 90 deg when the
    tag faces the camera, 0 deg when seen edge-on, negative when it faces away.
    """
    pose = ds.expected.transpose("tag", "p", "theta", "axis").values
    t = pose[..., :3]
    distance = camera_to_tag_distance(t)
    normal = Rotation.from_rotvec(pose[..., 3:].reshape(-1, 3)).as_matrix()[:, :, 2]
    to_camera = -t.reshape(-1, 3) / np.maximum(distance.reshape(-1, 1), 1e-12)
    angle = np.degrees(np.arcsin(np.clip(np.sum(to_camera * normal, axis=1), -1, 1)))
    dims = ("tag", "p", "theta")
    coords = {d: ds[d] for d in dims}
    angle = angle.reshape(distance.shape)
    return (
        xr.DataArray(distance, dims=dims, coords=coords, attrs={"units": "m"}),
        xr.DataArray(angle, dims=dims, coords=coords, attrs={"units": "deg"}),
    )


def repeat_median_stats(ds: xr.Dataset, variant: str | None = None) -> xr.DataArray:
    """Image statistics of one variant, the median over repeats (tag, p, theta, stat).

    The ``stat`` axis is that of :data:`simgap.pose.image_stats.STAT_NAMES` (statistics a
    dataset written by another simgap version lacks are NaN).
    """
    stats = ds.image_stats.sel(variant=variant) if variant else ds.image_stats.isel(variant=0)
    with warnings.catch_warnings():  # tags never measured are all-NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        median = stats.median("repeat", skipna=True)
    return median.reindex(stat=list(STAT_NAMES))


def image_stat_view(ds: xr.Dataset) -> xr.Dataset:
    """What :func:`plot_image_stats` draws of one dataset, per (tag, p, theta).

    Parameters
    ----------
    ds : xarray.Dataset
        A result dataset with ``image_stats`` and ``expected``; its first variant is read.

    Returns
    -------
    xarray.Dataset
        ``distance_m`` (m) and ``sight_elevation_deg`` (deg: 90 facing the camera, 0 edge-on) of
        :func:`tag_distance_and_view_angle`, ``visible`` (bool) and ``image_stat_median`` (tag, p,
        theta, stat): :func:`repeat_median_stats` over the statistics of
        :data:`~simgap.pose.image_stats.STAT_NAMES` that ``ds`` has, in that order.
    """
    distance, elevation = tag_distance_and_view_angle(ds)
    visible = ds.visible if "variant" not in ds.visible.dims else ds.visible.isel(variant=0)
    own = [s for s in STAT_NAMES if s in ds.stat.values]
    median = repeat_median_stats(ds).sel(stat=own).transpose("tag", "p", "theta", "stat")
    view = xr.Dataset(
        {
            "distance_m": distance,
            "sight_elevation_deg": elevation,
            "visible": visible.astype(bool),
            "image_stat_median": median,
        }
    )
    return view.reset_coords(drop=True)  # the scalar variant, the stat's units and meanings


def plot_image_stats(
    datasets: Mapping[str, xr.Dataset],
    against: str = "distance",
    stats: Sequence[str] = PLOTTED_STATS,
    title: str = "",
) -> Figure:
    """Each image statistic against camera-to-tag distance (m) or view angle (deg), one colour each.

    The view angle is counted from facing (:data:`VIEW_ANGLE_LABEL`): ``90 -`` the elevation of
    :func:`tag_distance_and_view_angle`. A panel whose values are all one number says so instead
    of drawing an axis around it.

    Panels are named and scaled by :data:`simgap.pose.stat_labels.STAT_LABELS`.

    Parameters
    ----------
    datasets : mapping of label to dataset
        Datasets with ``image_stats`` (e.g. ``{"real": real, "simulation": sim}``; the first
        variant of each, median over repeats), or their :func:`image_stat_view`; visible tags
        only are drawn.
    against : {"distance", "view_angle"}
        The x axis.
    stats : sequence of str
        Statistics to plot, one panel each (those every dataset has).
    title : str
        Figure title.
    """
    views = {
        label: ds if "image_stat_median" in ds else image_stat_view(ds)
        for label, ds in datasets.items()
    }
    stats = [s for s in stats if all(s in view.stat.values for view in views.values())]
    cols = 3
    rows = max(1, int(np.ceil(len(stats) / cols)))
    fig = Figure(figsize=(4.6 * cols, 3.2 * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    markers = "o^sDv<>"
    shown: dict[str, list[np.ndarray]] = {stat: [] for stat in stats}
    for k, (label, view) in enumerate(views.items()):
        # x: the distance (m), or the view angle from facing (deg, 0 facing)
        x = view.distance_m if against == "distance" else 90.0 - view.sight_elevation_deg
        for ax, stat in zip(axes, stats, strict=False):
            y = view.image_stat_median.sel(stat=stat).where(view.visible)
            for tag in view.tag.values:
                xs, ys = x.sel(tag=tag).values.ravel(), y.sel(tag=tag).values.ravel()
                ok = np.isfinite(ys)
                shown[stat].append(ys[ok])
                ax.plot(
                    xs[ok],
                    ys[ok],
                    markers[int(tag) % len(markers)],
                    color=f"C{k}",
                    alpha=0.6,
                    ms=4,
                    label=f"{label}, tag {int(tag)}",
                )
    for ax, stat in zip(axes, stats, strict=False):
        panel = stat_label(stat)
        ax.set_title(panel.name, fontsize=10)
        ax.set_ylabel(panel.unit)
        ax.set_xlabel(DISTANCE_LABEL if against == "distance" else VIEW_ANGLE_LABEL)
        ax.grid(alpha=0.3)
        plotted = np.concatenate(shown[stat]) if shown[stat] else np.array([])
        if plotted.size and np.all(plotted == plotted[0]):  # one value: say so, no invented scale
            ax.set_yticks([plotted[0]])
            ax.text(0.5, 0.75, f"every tag: {plotted[0]:g}", transform=ax.transAxes,
                    ha="center", fontsize=9, color="0.3")  # fmt: skip
    for ax in axes[len(stats) :]:
        ax.set_visible(False)
    if stats:
        axes[0].legend(fontsize=7)
    x_name = "camera-to-tag distance" if against == "distance" else "view angle from facing"
    fig.suptitle(title or f"Image evidence against {x_name}")
    return fig
