"""Fitting an error model to a result dataset (see :mod:`simgap.analysis.errormodel`)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr
from scipy import stats

from simgap.analysis.errormodel import _smoothing as smoothing
from simgap.analysis.errormodel._geometry import covariates
from simgap.analysis.errormodel._io import FIT_METHODS, SCHEMA, with_attrs
from simgap.analysis.errormodel._model import Z90, ErrorModel
from simgap.core.axes import AXES
from simgap.core.robust import MAD_TO_SIGMA


@dataclass(frozen=True)
class FitSettings:
    """Settings of :func:`fit_error_model`.

    Attributes
    ----------
    h_distance : float
        Kernel bandwidth along distance (m); default about three pin pitches.
    h_obliquity : float
        Kernel bandwidth along obliquity (rad); default 15 deg (1.5 turntable stops).
    h_obliquity_det : float
        Bandwidth along obliquity of the detection probability (rad); default 7.5 deg, narrower
        because detection falls off sharply at grazing angles.
    step_distance, step_obliquity : float
        Grid spacing (m, rad).
    min_support : float
        Kernel mass (about the number of configurations within one bandwidth) a node needs to be
        covered.
    min_detections : int
        Fewest detections of a tag for the local fit; a tag with fewer is pooled.
    min_pooled : int
        Fewest detections of a tag for the pooled fit (:func:`_pooled_tag`); a tag with fewer is
        not fitted. 3: the pooled spread needs two degrees of freedom to be finite in practice
        (t(0.95, 1) = 6.31, t(0.95, 2) = 2.92), and a node needs ``min_support`` (3) behind it.
    robust_iterations : int
        Bisquare robustness iterations of the local-linear fit.
    """

    h_distance: float = 0.08
    h_obliquity: float = math.radians(15.0)
    h_obliquity_det: float = math.radians(7.5)
    step_distance: float = 0.0254
    step_obliquity: float = math.radians(5.0)
    min_support: float = 3.0
    min_detections: int = 12
    min_pooled: int = 3
    robust_iterations: int = 3

    def __post_init__(self) -> None:
        for name in ("h_distance", "h_obliquity", "h_obliquity_det", "step_distance"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: expected a positive value, got {getattr(self, name)}")
        if self.min_support <= 0 or self.min_detections < 4:
            raise ValueError("min_support: expected > 0; min_detections: expected >= 4")
        if not 2 <= self.min_pooled <= self.min_detections:
            raise ValueError("min_pooled: expected 2 <= min_pooled <= min_detections")


def _samples(
    ds: xr.Dataset, tag: int, config_mask: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Covariates (N, 2), errors (N, 6) of detections; covariates (M, 2), flags (M,) of trials."""
    sub = ds.sel(tag=tag)
    x = np.stack(covariates(sub.expected.transpose("p", "theta", "axis").values), axis=-1)
    det = sub.detected.transpose("repeat", "p", "theta").values
    err = sub.error.transpose("repeat", "p", "theta", "axis").values
    use = np.ones(x.shape[:2], bool) if config_mask is None else np.asarray(config_mask, bool)
    facing = np.abs(x[..., 1]) < np.pi / 2
    trials = np.broadcast_to(use & facing, det.shape)
    ok = det & trials & np.all(np.isfinite(err), axis=-1)
    xr_ = np.broadcast_to(x, det.shape + (2,))
    return xr_[ok], err[ok], xr_[trials], det[trials]


def _grid(lo: float, hi: float, step: float) -> np.ndarray:
    n = max(int(math.ceil((hi - lo) / step - 1e-9)), 1)
    return np.linspace(lo, hi, n + 1)


def _inside(nodes: np.ndarray, x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Nodes within the bounding box of ``x`` widened by half a bandwidth on every side."""
    if not len(x):
        return np.zeros(len(nodes), bool)
    lo, hi = x.min(axis=0) - h / 2, x.max(axis=0) + h / 2
    return np.all((nodes >= lo) & (nodes <= hi), axis=1)


def _pooled_tag(x, err, xd, flags, settings: FitSettings, nodes, shape, out: dict) -> dict:
    """A tag with too few detections for the local fit: one constant per axis, t intervals.

    Bias: the mean of the ``n`` errors; spread and ``bias_se`` are scaled so that the model's
    90 % interval, ``bias +- Z90 sqrt(spread**2 + bias_se**2)``, is the exact 90 % prediction
    interval of a new normal error, ``mean +- t(0.95, n-1) s sqrt(1 + 1/n)`` (``s`` the sample
    standard deviation). No correlation is estimated (identity). The values hold only within the
    detections' (distance, obliquity) span widened by half a bandwidth: there ``support_error``
    is ``n``, elsewhere 0 (not covered). Detection: the Jeffreys rate of the facing trials,
    Beta(hits + 1/2, misses + 1/2), its 5 % and 95 % quantiles, over their widened span.
    """
    h = np.array([settings.h_distance, settings.h_obliquity])
    n = len(x)
    t90 = float(stats.t.ppf(0.95, n - 1))
    s = np.std(err, axis=0, ddof=1)
    inside = _inside(nodes, x, h).reshape(shape)
    factor = t90 / Z90
    for key, value in (
        ("bias", err.mean(axis=0)),
        ("spread", factor * s),
        ("bias_se", factor * s / math.sqrt(n)),
    ):
        out[key][inside] = value
    out["calibration"][:] = factor
    out["support_error"] = np.where(inside, float(n), 0.0)
    trials = _inside(nodes, xd, h).reshape(shape)
    a, b = float(flags.sum()) + 0.5, float(len(flags) - flags.sum()) + 0.5
    for key, value in (
        ("p_detect", a / (a + b)),
        ("p_detect_lo", stats.beta.ppf(0.05, a, b)),
        ("p_detect_hi", stats.beta.ppf(0.95, a, b)),
    ):
        out[key] = np.where(trials, value, np.nan)
    out["support_detection"] = np.where(trials, float(len(flags)), 0.0)
    out["fit"] = FIT_METHODS.index("pooled")
    return out


def _fit_tag(x, err, xd, flags, settings: FitSettings, grid_d, grid_o, tag: int):
    h = np.array([settings.h_distance, settings.h_obliquity])
    nodes = np.stack(np.meshgrid(grid_d, grid_o, indexing="ij"), axis=-1).reshape(-1, 2)
    shape = (len(grid_d), len(grid_o))
    out: dict[str, Any] = {
        "bias": np.full(shape + (6,), np.nan),
        "spread": np.full(shape + (6,), np.nan),
        "bias_se": np.full(shape + (6,), np.nan),
        "calibration": np.full(6, np.nan),
        "correlation": np.eye(6),
        "fit": FIT_METHODS.index("none"),
    }
    if settings.min_pooled <= len(x) < settings.min_detections:
        return _pooled_tag(x, err, xd, flags, settings, nodes, shape, out)
    k_det, _ = smoothing.kernel(
        nodes, xd, np.array([settings.h_distance, settings.h_obliquity_det])
    )
    mass = k_det.sum(axis=1)
    hits = k_det @ flags.astype(float)
    rate = float(np.mean(flags)) if len(flags) else 0.5
    a, b = hits + rate, mass - hits + (1.0 - rate)
    out["p_detect"] = (a / (a + b)).reshape(shape)
    out["p_detect_lo"] = stats.beta.ppf(0.05, a, b).reshape(shape)
    out["p_detect_hi"] = stats.beta.ppf(0.95, a, b).reshape(shape)
    out["support_detection"] = mass.reshape(shape)
    k_err, _ = smoothing.kernel(nodes, x, h) if len(x) else (np.zeros((len(nodes), 0)), None)
    out["support_error"] = k_err.sum(axis=1).reshape(shape)
    if len(x) < settings.min_detections:
        return out
    k_data, _ = smoothing.kernel(x, x, h)
    np.fill_diagonal(k_data, 0.0)  # each point's spread from its neighbours only (leave-one-out)
    z = np.empty_like(err)
    for j in range(6):
        w, loo = smoothing.robust_local_linear(x, err[:, j], h, settings.robust_iterations)
        l_nodes = smoothing.local_linear_weights(nodes, x, w, h)
        l_data = smoothing.local_linear_weights(x, x, w, h)
        sigma_nodes = MAD_TO_SIGMA * smoothing.weighted_median(np.abs(loo), k_err)
        sigma_data = MAD_TO_SIGMA * smoothing.weighted_median(np.abs(loo), k_data)
        se_nodes = sigma_nodes * np.sqrt(np.sum(l_nodes**2, axis=1))
        se_data = sigma_data * np.sqrt(np.sum(l_data**2, axis=1))
        std_data = np.sqrt(sigma_data**2 + se_data**2)
        std_data = np.where(std_data > 0, std_data, np.finfo(float).tiny)
        ratio = np.abs(loo) / std_data
        calibration = float(np.quantile(ratio, 0.9) / Z90) or 1.0
        z[:, j] = loo / (calibration * std_data)
        out["bias"][..., j] = (l_nodes @ err[:, j]).reshape(shape)
        out["spread"][..., j] = (calibration * sigma_nodes).reshape(shape)
        out["bias_se"][..., j] = (calibration * se_nodes).reshape(shape)
        out["calibration"][j] = calibration
    out["correlation"] = smoothing.rank_correlation(z)
    out["fit"] = FIT_METHODS.index("local")
    return out


def fit_error_model(
    ds: xr.Dataset,
    settings: FitSettings | None = None,
    variant: str | None = None,
    config_mask: np.ndarray | None = None,
    source: str = "",
) -> ErrorModel:
    """Fit an error model to a result dataset (docs/conventions.md §3).

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset: simulated, or real after ``simgap ingest``.
    settings : FitSettings, optional
        Bandwidths, grid, coverage rule (default: :class:`FitSettings`).
    variant : str, optional
        Variant to model (default: the first).
    config_mask : ndarray of bool (p, theta), optional
        Use only these configurations (e.g. the fit half of
        :func:`~simgap.analysis.errormodel.check_error_model`).
    source : str
        Where ``ds`` came from, for the provenance attrs.

    Returns
    -------
    ErrorModel

    Raises
    ------
    ValueError
        If a required variable is missing, the variant is unknown, or no tag has at least
        ``settings.min_pooled`` detections (naming the counts and both minimums).
    """
    settings = settings or FitSettings()
    missing = [v for v in ("expected", "error", "detected") if v not in ds]
    if missing:
        raise ValueError(f"not a result dataset: missing variable(s) {', '.join(missing)}")
    variants = [str(v) for v in ds.variant.values]
    variant = variants[0] if variant is None else variant
    if variant not in variants:
        raise ValueError(f"variant: expected one of {', '.join(variants)}, got {variant!r}")
    sub = ds.sel(variant=variant)
    tags = [int(t) for t in ds.tag.values]
    samples = {t: _samples(sub, t, config_mask) for t in tags}
    counts = {t: len(s[0]) for t, s in samples.items()}
    if max(counts.values()) < settings.min_pooled:
        found = ", ".join(f"tag {t}: {c}" for t, c in counts.items())
        raise ValueError(
            f"too few detections to fit errors ({found}): need at least {settings.min_pooled} "
            f"detections of one tag for a pooled fit (constant bias and spread, t intervals), "
            f"{settings.min_detections} for the local fit"
        )
    allx = np.concatenate([s[2] for s in samples.values()])
    grid_d = _grid(allx[:, 0].min(), allx[:, 0].max(), settings.step_distance)
    grid_o = _grid(allx[:, 1].min(), allx[:, 1].max(), settings.step_obliquity)
    fits = [_fit_tag(*samples[t], settings, grid_d, grid_o, t) for t in tags]
    cube = ("tag", "distance", "obliquity", "axis")
    plane = cube[:3]

    def stack(key: str) -> np.ndarray:
        return np.stack([f[key] for f in fits])

    out = xr.Dataset(
        {
            **{k: (cube, stack(k)) for k in ("bias", "spread", "bias_se")},
            "correlation": (("tag", "axis", "axis_b"), stack("correlation")),
            "calibration": (("tag", "axis"), stack("calibration")),
            **{k: (plane, stack(k)) for k in ("p_detect", "p_detect_lo", "p_detect_hi")},
            "support_error": (plane, stack("support_error")),
            "support_detection": (plane, stack("support_detection")),
            "detections": (("tag",), np.array([counts[t] for t in tags])),
            "fit": (("tag",), np.array([f["fit"] for f in fits], np.int8)),
        },
        coords={
            "tag": ("tag", np.array(tags)),
            "distance": ("distance", grid_d),
            "obliquity": ("obliquity", grid_o),
            "axis": ("axis", np.array(AXES)),
            "axis_b": ("axis_b", np.array(AXES)),
        },
        attrs={
            "schema": SCHEMA,
            "title": "simgap error model",
            "method": "robust local-linear bias, local MAD spread (calibrated to 90 %), "
            "kernel detection rate; bilinear on the grid. Tags with fewer than min_detections "
            "detections (fit = pooled): constant mean and sample std with t(n-1) 90 % "
            "prediction intervals, Jeffreys detection rate, within the data's span",
            "settings": json.dumps(settings.__dict__),
            "variant": variant,
            "source": source,
            "source_title": str(ds.attrs.get("title", "")),
            "source_kind": str(ds.attrs.get("source", "simulation")),
            "simgap_version": _version(),
            "min_support": settings.min_support,
        },
    )
    return ErrorModel(with_attrs(out))


def _version() -> str:
    import simgap

    return simgap.__version__
