"""The honest check of an error model: fit on half the configurations, predict the check half."""

from __future__ import annotations

import numpy as np
import xarray as xr

from simgap.analysis.errormodel._fit import FitSettings, fit_error_model
from simgap.analysis.errormodel._geometry import covariates
from simgap.analysis.errormodel._model import ErrorModel, TagPoses
from simgap.core.axes import AXES


def split_configurations(ds: xr.Dataset, seed: int = 0) -> np.ndarray:
    """A random half of the (p, theta) configurations: bool (p, theta), True = the fit half."""
    rng = np.random.default_rng(seed)
    n = ds.sizes["p"] * ds.sizes["theta"]
    fit_half = np.zeros(n, bool)
    fit_half[rng.permutation(n)[: n // 2]] = True
    return fit_half.reshape(ds.sizes["p"], ds.sizes["theta"])


def evaluate_check_half(
    model: ErrorModel, ds: xr.Dataset, check_half: np.ndarray, variant: str | None = None
) -> dict:
    """Coverage of the 90 % intervals and detection calibration on the check half.

    Parameters
    ----------
    model : ErrorModel
        Fitted on the other configurations (or variants): the fit half.
    ds : xarray.Dataset
        The result dataset.
    check_half : ndarray of bool (p, theta)
        The configurations to predict.
    variant : str, optional
        Default: the model's variant.

    Returns
    -------
    dict
        ``coverage`` (per axis: fraction of the check half's detected errors inside the 90 %
        interval), ``coverage_by_tag``, ``n_errors`` (its detections inside the model's range),
        ``n_outside`` (its detections outside it: not predicted, counted),
        ``detection`` (``bins``: predicted-probability bins with mean predicted, observed rate
        and count; ``brier``; ``n``; ``n_outside``).
    """
    variant = variant or str(model.ds.attrs.get("variant", ds.variant.values[0]))
    sub = ds.sel(variant=variant)
    inside_all, hits, probs = [], [], []
    cover: dict[int, np.ndarray] = {}
    n_outside = n_det_outside = 0
    for tag in model.tags:
        exp = sub.sel(tag=tag).expected.transpose("p", "theta", "axis").values
        det = sub.sel(tag=tag).detected.transpose("repeat", "p", "theta").values
        errs = sub.sel(tag=tag).error.transpose("repeat", "p", "theta", "axis").values
        poses = np.broadcast_to(exp, det.shape + (6,))
        _, o = covariates(exp)
        trials = np.broadcast_to(check_half & (np.abs(o) < np.pi / 2), det.shape)
        q = TagPoses(np.full(int(trials.sum()), tag), poses[trials])
        p = model.detection_probability(q, outside="nan")
        ok = np.isfinite(p)
        n_det_outside += int((~ok).sum())
        probs.append(p[ok])
        hits.append(det[trials][ok])
        found = det & trials & np.all(np.isfinite(errs), axis=-1)
        qe = TagPoses(np.full(int(found.sum()), tag), poses[found])
        lo, hi = model.interval(qe, outside="nan")
        e = errs[found]
        inside = np.all(np.isfinite(lo), axis=1)
        n_outside += int((~inside).sum())
        cover[tag] = ((e >= lo) & (e <= hi))[inside]
        inside_all.append(cover[tag])
    allc = np.concatenate(inside_all)
    probs_all, hits_all = np.concatenate(probs), np.concatenate(hits).astype(float)
    edges = np.array([0.0, 0.5, 0.8, 0.9, 0.95, 0.99, 1.0])
    bins = []
    for lo_, hi_ in zip(edges[:-1], edges[1:], strict=True):
        m = (probs_all >= lo_) & ((probs_all < hi_) if hi_ < 1 else (probs_all <= hi_))
        if m.any():
            bins.append(
                {
                    "bin": [float(lo_), float(hi_)],
                    "predicted": float(probs_all[m].mean()),
                    "observed": float(hits_all[m].mean()),
                    "n": int(m.sum()),
                }
            )
    return {
        "coverage": {a: float(allc[:, k].mean()) for k, a in enumerate(AXES)},
        "coverage_by_tag": {
            int(t): {a: float(c[:, k].mean()) for k, a in enumerate(AXES)}
            for t, c in cover.items()
            if len(c)  # a tag with no check-half error in range has no coverage
        },
        "n_errors": int(len(allc)),
        "n_outside": n_outside,
        "detection": {
            "bins": bins,
            "brier": float(np.mean((probs_all - hits_all) ** 2)),
            "predicted_rate": float(probs_all.mean()),
            "observed_rate": float(hits_all.mean()),
            "n": int(len(probs_all)),
            "n_outside": n_det_outside,
        },
    }


def check_error_model(
    ds: xr.Dataset,
    settings: FitSettings | None = None,
    seed: int = 0,
    variant: str | None = None,
) -> dict:
    """Fit on a random half of the configurations, evaluate on the other: the check half.

    Returns :func:`evaluate_check_half`'s mapping; ``settings`` default to :class:`FitSettings`.
    """
    fit_half = split_configurations(ds, seed)
    model = fit_error_model(ds, settings, variant, config_mask=fit_half)
    return evaluate_check_half(model, ds, ~fit_half, variant)


def check_pooled_model(ds: xr.Dataset, settings: FitSettings | None = None) -> dict:
    """Fit on every other variant pooled, evaluate on the others at every configuration.

    The check of a model pooled over variants, whose check half is the variants it was not
    fitted on
    (:func:`simgap.results.dataset.pooled_variants`): its draws are the variants (the sun's
    directions of an orbital sweep), so the question is whether the intervals fitted on some
    draws cover the errors of others at the same poses. Returns :func:`evaluate_check_half`'s
    mapping.
    """
    from simgap.results.dataset import POOLED, pooled_variants

    names = [str(v) for v in ds.variant.values]
    if len(names) < 2:
        raise ValueError(f"a pooled check needs two variants or more, got {len(names)}")
    model = fit_error_model(pooled_variants(ds.sel(variant=names[0::2])), settings)
    check = pooled_variants(ds.sel(variant=names[1::2]))
    every = np.ones((ds.sizes["p"], ds.sizes["theta"]), bool)
    return evaluate_check_half(model, check, every, POOLED)
