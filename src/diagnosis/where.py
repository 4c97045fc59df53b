"""Where the gap lies and what stays unexplained: the ``where`` part of ``result.json``."""

from __future__ import annotations

import numpy as np
import xarray as xr

from simgap.analysis import gap as gapmod
from simgap.analysis.gap import IMAGE_CHANNELS
from simgap.analysis.search import Scored
from simgap.analysis.thresholds import UNEXPLAINED_MISFIT
from simgap.diagnosis.result import Where
from simgap.diagnosis.settings import DiagnoseSettings
from simgap.effects import EFFECTS


def where_summary(
    real: xr.Dataset,
    sim: xr.Dataset,
    field: gapmod.GapField,
    axis_gaps: dict[str, gapmod.AxisGap] | None = None,
) -> Where:
    """Per-axis gap, significant regions, detection and the scatter / detection / image tests.

    Parameters
    ----------
    real, sim : xarray.Dataset
        The real dataset and its simulation (result dataset contract).
    field : GapField
        Their gap field (:func:`simgap.analysis.gap.gap_field`).
    axis_gaps : dict, optional
        ``field``'s :func:`simgap.analysis.gap.axis_summary` when already computed.
    """
    axis_gaps = gapmod.axis_summary(field) if axis_gaps is None else axis_gaps
    scatter = gapmod.scatter_tests(real, sim)
    detection = gapmod.detection_tests(real, sim)
    image = gapmod.image_tests(real, sim)
    families = {
        "pose": any(a.significant for a in axis_gaps.values()),
        "scatter": any(t.significant for t in scatter),
        "detection": any(t.significant for t in detection),
        "image": any(t.significant for t in image),
    }
    return Where(
        significant=any(families.values()),
        significant_evidence=[name for name, hit in families.items() if hit],
        axis_gaps=axis_gaps,
        regions=[r for r in gapmod.region_summary(field) if r.significant],
        detection=gapmod.detection_summary(field),
        scatter_tests=scatter,
        detection_tests=detection,
        image_tests=image,
        comparable_items=int(field.comparable.sum()),
    )


def unexplained_evidence(
    chosen: Scored | None, where: Where, settings: DiagnoseSettings
) -> list[str]:
    """Significant evidence that the chosen model leaves unexplained on the choose split.

    ``pose``: the pose gap falls by less than ``settings.explained_reduction``; an image
    statistic: its misfit stays at or above its floor; ``detection``: the detection mismatch
    stays at or above 5 % (misfits at or above
    :data:`~simgap.analysis.thresholds.UNEXPLAINED_MISFIT` channel units); ``scatter``: the model
    has no noise effect (the pose scatter of a model is not predicted otherwise). Everything
    significant is unexplained when no model was chosen.
    """
    out = []
    pose = any(a.significant for a in where.axis_gaps.values())
    if pose and (chosen is None or chosen.pose_gap_reduction < settings.explained_reduction):
        out.append("pose")
    misfit = dict(zip(IMAGE_CHANNELS, chosen.image_misfit_after, strict=True)) if chosen else {}
    out += [
        t.stat
        for t in where.image_tests
        if t.significant and misfit.get(t.stat, np.inf) >= UNEXPLAINED_MISFIT
    ]
    if any(t.significant for t in where.detection_tests) and (
        chosen is None or chosen.detection_mismatch_after >= UNEXPLAINED_MISFIT
    ):
        out.append("detection")
    noisy = chosen is not None and any(EFFECTS[e].stochastic for e in chosen.effects)
    if any(t.significant for t in where.scatter_tests) and not noisy:
        out.append("scatter")
    return out
