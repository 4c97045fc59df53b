"""The error model's 90 % bands drawn over the data it describes (``errormodel_bands.png``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.spatial.transform import Rotation

from simgap.analysis.errormodel import Z90, ErrorModel, TagPoses, covariates
from simgap.analysis.report._heatmaps import robust_colour_limit
from simgap.core.atomic import atomic_write
from simgap.core.axes import AXES, display_unit

FIGURE_NAME = "errormodel_bands.png"


def plot_error_model_bands(model: ErrorModel, ds: xr.Dataset, slices: int = 3) -> Figure:
    """Signed error vs obliquity, one row per tag and one column per axis.

    The data (detections of the model's variant, every repeat) are split into ``slices`` distance
    slices; each slice's points and the model's bias and 90 % band at the slice's middle distance
    share a colour. The band is drawn only where the model covers the query.
    """
    variant = str(model.ds.attrs.get("variant", ds.variant.values[0]))
    sub = ds.sel(variant=variant)
    tags = [int(t) for t in model.ds.tag.values]
    grid_d = model.ds.distance.values
    edges = np.linspace(grid_d[0], grid_d[-1], slices + 1)
    colours = colormaps["viridis"](np.linspace(0.0, 0.85, slices))
    fig = Figure(figsize=(20, 3.4 * len(tags)))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(tags), 6, squeeze=False)
    obl = np.linspace(model.ds.obliquity.values[0], model.ds.obliquity.values[-1], 121)
    points: dict[tuple[int, int], list[np.ndarray]] = {}
    bands: dict[tuple[int, int], list[np.ndarray]] = {}
    for r, tag in enumerate(tags):
        exp = sub.sel(tag=tag).expected.transpose("p", "theta", "axis").values
        det = sub.sel(tag=tag).detected.transpose("repeat", "p", "theta").values
        err = sub.sel(tag=tag).error.transpose("repeat", "p", "theta", "axis").values
        d, o = covariates(exp)
        d, o = np.broadcast_to(d, det.shape)[det], np.broadcast_to(o, det.shape)[det]
        e = err[det]
        for s in range(slices):
            in_slice = (d >= edges[s]) & (d <= edges[s + 1])
            mid = 0.5 * (edges[s] + edges[s + 1])
            q = _poses_at(mid, obl)
            mean = model.error_mean(TagPoses(np.full(len(obl), tag), q), outside="nan")
            sd = model.std(TagPoses(np.full(len(obl), tag), q), outside="nan")
            for k, axis in enumerate(AXES):
                unit, scale = display_unit(axis)
                ax = axes[r, k]
                x = np.degrees(obl)
                ax.fill_between(
                    x,
                    scale * (mean[:, k] - Z90 * sd[:, k]),
                    scale * (mean[:, k] + Z90 * sd[:, k]),
                    color=colours[s],
                    alpha=0.2,
                    lw=0,
                )
                ax.plot(x, scale * mean[:, k], color=colours[s], lw=1.2)
                points.setdefault((r, k), []).append(scale * e[in_slice, k])
                bands.setdefault((r, k), []).append(
                    scale * (np.abs(mean[:, k]) + Z90 * np.abs(sd[:, k]))
                )
                ax.plot(
                    np.degrees(o[in_slice]),
                    scale * e[in_slice, k],
                    ".",
                    ms=3,
                    color=colours[s],
                    label=f"{edges[s]:.2f}-{edges[s + 1]:.2f} m" if k == 0 else None,
                )
                ax.set_title(f"tag {tag} {axis}", fontsize=9)
                ax.set_xlabel("obliquity (deg)", fontsize=8)
                ax.set_ylabel(f"error ({unit})", fontsize=8)
                ax.tick_params(labelsize=7)
        axes[r, 0].legend(fontsize=7, title="camera-to-tag distance", title_fontsize=7)
    for (r, k), ys in points.items():
        _robust_limits(axes[r, k], np.concatenate(ys), np.concatenate(bands[(r, k)]))
    fig.suptitle(
        f"error model ({variant}): bias and 90 % band per distance slice, over the detections"
    )
    fig.tight_layout()
    return fig


def _robust_limits(ax, values: np.ndarray, band: np.ndarray) -> None:
    """Symmetric y limits that the band and all but far-out points set; those counted.

    The points' limit is :func:`simgap.analysis.report.robust_colour_limit` (Tukey's
    far-out fence of the |errors|), the band's its largest |bias| + 90 % half-width; points
    beyond the axis are counted in the panel's title.
    """
    finite_band = band[np.isfinite(band)]
    limit = max(robust_colour_limit(values), float(finite_band.max()) if finite_band.size else 0.0)
    limit *= 1.1
    ax.set_ylim(-limit, limit)
    beyond = np.abs(values) > limit
    if beyond.any():
        ax.set_title(f"{ax.get_title()} ({int(beyond.sum())} beyond the axis)", fontsize=9)


def _poses_at(distance: float, obliquity: np.ndarray) -> np.ndarray:
    """Tag poses (N, 6) straight ahead at ``distance`` (m), turned by ``obliquity`` (rad) about Z.

    Marker frame as the rig's (z = normal towards the camera at obliquity 0, y = global +Z).
    """
    base = np.column_stack([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    rot = Rotation.from_rotvec(np.outer(obliquity, [0.0, 0.0, 1.0])) * Rotation.from_matrix(base)
    t = np.tile([0.0, distance, 0.0], (len(obliquity), 1))
    return np.concatenate([t, rot.as_rotvec()], axis=1)


def write_error_model_bands(model: ErrorModel | Path, ds: xr.Dataset, out_dir: Path) -> Path:
    """Write :data:`FIGURE_NAME` into ``out_dir`` (atomically); ``model`` may be a file path."""
    if not isinstance(model, ErrorModel):
        model = ErrorModel.load(model)
    fig = plot_error_model_bands(model, ds)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return atomic_write(out / FIGURE_NAME, lambda tmp: fig.savefig(tmp, format="png", dpi=90))
