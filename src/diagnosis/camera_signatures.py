"""The capture's own image pipeline, read from its signatures: the camera's properties.

A real camera's pipeline (black level, sharpening, denoising, demosaicing, lateral colour, gain
changes; :mod:`simgap.effects.camera_pipeline`) is a property of the camera, not a cause of the
gap: the diagnosis reports what the capture shows of each stage beside what the simulation shows,
in the engineer's units, measured by the image statistics of :mod:`simgap.pose.image_stats`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
import xarray as xr

from simgap.analysis.candidates import size_change
from simgap.analysis.gap import Items, repeat_median_stats
from simgap.diagnosis.result import EdgeOffset, PipelineSignature


def _finite(values: np.ndarray) -> np.ndarray:
    """The finite values of an array, flattened."""
    values = np.asarray(values, float).ravel()
    return values[np.isfinite(values)]


def _values(ds: xr.Dataset, stat: str) -> np.ndarray:
    """Every finite value of one statistic over the dataset's tags, poses and repeats."""
    if "image_stats" not in ds or stat not in ds.stat.values:
        return np.array([])
    return _finite(ds.image_stats.isel(variant=0).sel(stat=stat).values)


def _per_item(ds: xr.Dataset, stat: str) -> np.ndarray:
    """The repeat-median of one statistic per tag and pose, finite values only."""
    if "image_stats" not in ds:
        return np.array([])
    return _finite(repeat_median_stats(ds).sel(stat=stat).values)


def _noise_ratio(ds: xr.Dataset) -> np.ndarray:
    """Per tag and pose: spatial over temporal noise of the flat paper (first frames only)."""
    spatial = _first_frames(ds, "noise_paper_linear")
    temporal = _first_frames(ds, "temporal_noise_paper_linear")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = spatial / temporal
    return ratio[np.isfinite(ratio) & (temporal > 0)]


def _first_frames(ds: xr.Dataset, stat: str) -> np.ndarray:
    if "image_stats" not in ds or stat not in ds.stat.values:
        return np.array([])
    return np.asarray(ds.image_stats.isel(variant=0, repeat=0).sel(stat=stat).values, float).ravel()


def _summary(values: np.ndarray, how: Callable[[np.ndarray], float]) -> float | None:
    if values.size == 0:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return float(how(values))


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))


#: The signatures reported: stage, what is measured (with its unit), how it is read from a
#: dataset, and how it is summarised over the capture.
_SIGNATURES: tuple[tuple[str, str, Callable[[xr.Dataset], np.ndarray], Callable], ...] = (
    (
        "black level",
        "largest share of a tag's sticker at 0 DN (%)",
        lambda ds: 100.0 * _values(ds, "black_clipped_fraction"),
        np.max,
    ),
    (
        "sharpening",
        "median edge overshoot beyond ink and paper (% of the edge step)",
        lambda ds: 100.0 * _per_item(ds, "edge_overshoot"),
        np.median,
    ),
    (
        "demosaicing, lateral colour",
        "median colour fringe at the markers' edges (DN)",
        lambda ds: _per_item(ds, "colour_fringe_dn"),
        np.median,
    ),
    (
        "denoising",
        "median spatial over temporal noise of flat paper (1: white noise; below: smoothed)",
        _noise_ratio,
        np.median,
    ),
    (
        "gain changes",
        "RMS gain change between two frames of a pose (EV)",
        lambda ds: _finite(_first_frames(ds, "repeat_gain_ev")),
        _rms,
    ),
)


def pipeline_signatures(real: xr.Dataset, sim: xr.Dataset) -> list[PipelineSignature]:
    """What the capture and its simulation show of each stage of a camera's own pipeline.

    Parameters
    ----------
    real, sim : xarray.Dataset
        The capture and its simulation (result datasets with ``image_stats``).

    Returns
    -------
    list of PipelineSignature
        One per stage, the capture's and the simulation's value (None where not measurable:
        a grey capture has no colour fringe, one frame a pose no temporal noise or gain change).
    """
    return [
        PipelineSignature(
            stage=stage,
            measure=measure,
            real=_summary(read(real), how),
            simulated=_summary(read(sim), how),
        )
        for stage, measure, read, how in _SIGNATURES
    ]


def edge_offset(items: Items) -> EdgeOffset | None:
    """The marker sizes' change real - simulated, split into a share and an edge offset.

    :func:`simgap.analysis.candidates.size_change` over every comparable item (detected
    corners, px); None with fewer than four tags or no spread of sizes.
    """
    change = size_change(items.real_corners, items.sim_corners)
    if not np.isfinite(change.slope):
        return None
    return EdgeOffset(
        tags=change.n,
        offset_px=change.offset_px,
        scale_share=change.slope,
        scale_z=change.slope_z,
    )


def pipeline_markdown(
    signatures: list[PipelineSignature], edge: EdgeOffset | None = None
) -> list[str]:
    """The report's section on the camera's own image pipeline (a table; none without rows).

    ``edge``: the marker sizes' edge offset, stated after the table where given.
    """
    rows = [s for s in signatures if s.real is not None or s.simulated is not None]
    if not rows:
        return []

    def cell(v: float | None) -> str:
        return "n/a" if v is None else f"{v:.3g}"

    lines = [
        "## The camera's own image pipeline",
        "",
        "What the capture shows of each stage a camera's pipeline adds, beside the simulation "
        "(properties of the camera, reported, not causes of the gap):",
        "",
        "| stage | measured as | capture | simulation |",
        "|---|---|---|---|",
    ]
    lines += [f"| {s.stage} | {s.measure} | {cell(s.real)} | {cell(s.simulated)} |" for s in rows]
    if edge is not None:
        lines += [
            "",
            f"Marker edges: over {edge.tags} tags, the corners' distance from each marker's "
            f"centre differs from the simulated one by {edge.offset_px:+.2f} px at every size "
            f"(an edge offset) and by {edge.scale_share:+.2%} of the size ({edge.scale_z:+.1f} "
            "standard errors). A scale (print, focal length) changes it by a share; a pipeline "
            "the simulation lacks (black level, tone curve, demosaicing on soft edges) or a "
            "softness by the same pixels.",
        ]
    return lines + [""]


__all__ = ["edge_offset", "pipeline_markdown", "pipeline_signatures"]
