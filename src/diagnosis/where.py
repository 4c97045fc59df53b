"""Where the gap lies and what stays unexplained: the ``where`` part of ``result.json``."""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from simgap.analysis import evidence
from simgap.analysis import gap as gapmod
from simgap.analysis.channels import SCORED_STATS
from simgap.analysis.scored import Scored
from simgap.analysis.thresholds import UNEXPLAINED_MISFIT
from simgap.diagnosis.settings import DiagnoseSettings
from simgap.effects import EFFECTS


def where_summary(
    real: xr.Dataset,
    sim: xr.Dataset,
    field: gapmod.GapField,
    axes: dict[str, dict] | None = None,
) -> dict[str, Any]:
    """Per-axis gap, significant regions, detection and the scatter / detection / image tests.

    Parameters
    ----------
    real, sim : xarray.Dataset
        The real dataset and its simulation (result dataset contract).
    field : GapField
        Their gap field (:func:`simgap.analysis.gap.gap_field`).
    axes : dict, optional
        ``field``'s :func:`simgap.analysis.gap.axis_summary` when already computed.

    Returns
    -------
    dict
        ``axes`` (per-axis summary, m or rad), ``regions`` (significant ones), ``detection``,
        ``significant`` (any evidence family is), ``significant_evidence`` (those families),
        ``scatter_tests``, ``detection_tests``, ``image_tests``, ``comparable_configurations``.
    """
    axes = gapmod.axis_summary(field) if axes is None else axes
    tests = {
        "scatter": evidence.scatter_tests(real, sim),
        "detection": evidence.detection_tests(real, sim),
        "image": evidence.image_tests(real, sim),
    }
    families = {"pose": any(a["significant"] for a in axes.values())} | {
        name: any(r["significant"] for r in rows) for name, rows in tests.items()
    }
    return {
        "axes": axes,
        "regions": [r for r in gapmod.region_summary(field) if r["significant"]],
        "detection": gapmod.detection_summary(field),
        "significant": any(families.values()),
        "significant_evidence": [name for name, hit in families.items() if hit],
        "scatter_tests": tests["scatter"],
        "detection_tests": tests["detection"],
        "image_tests": tests["image"],
        "comparable_configurations": int(field.comparable.sum()),
    }


def unexplained_evidence(
    chosen: Scored | None, where: dict[str, Any], settings: DiagnoseSettings
) -> list[str]:
    """Significant evidence that the chosen model leaves unexplained on held-out data.

    ``pose``: the held-out pose gap falls by less than ``settings.explained_reduction``;
    an image statistic: its held-out misfit stays at or above its floor; ``detection``: the
    held-out detection mismatch stays at or above 5 %; ``scatter``: the model has no noise
    effect (the pose scatter of a model is not predicted otherwise). Everything significant is
    unexplained when no model was chosen.
    """
    out = []
    pose = any(a["significant"] for a in where["axes"].values())
    if pose and (chosen is None or chosen.pose_gap_reduction < settings.explained_reduction):
        out.append("pose")
    misfit = dict(zip(SCORED_STATS, chosen.image_misfit_after, strict=True)) if chosen else {}
    out += [
        r["stat"]
        for r in where["image_tests"]
        if r["significant"] and misfit.get(r["stat"], np.inf) >= UNEXPLAINED_MISFIT
    ]
    if any(r["significant"] for r in where["detection_tests"]) and (
        chosen is None or chosen.detection_mismatch_after >= UNEXPLAINED_MISFIT
    ):
        out.append("detection")
    noisy = chosen is not None and any(EFFECTS[e].stochastic for e in chosen.effects)
    if any(r["significant"] for r in where["scatter_tests"]) and not noisy:
        out.append("scatter")
    return out
