"""Error models for control software, fitted to a result dataset, loadable without simgap.

Pose error and detection probability of each tag as smooth functions of distance and obliquity.

Covariates (the same geometry as :meth:`simgap.core.rig.Rig.view_angle`, from a tag pose in the
global frame):

``distance`` (m)
    Distance from the eyepoint to the tag centre, ``|t|``.
``obliquity`` (rad)
    Angle between the tag normal and the line of sight to the camera, signed by which way the tag
    is turned about global +Z (positive: the normal turned counter-clockwise from the line of
    sight, as tag 0 for theta in (0, pi/2)). ``|obliquity| = pi/2 - view_angle``; 0 is a tag
    facing the camera squarely. The sign matters: lateral and yaw errors change sign with it.

Method (per tag and error axis, on the detected configurations of one variant, every repeat):

1. **Bias**: robust local-linear regression (LOESS) of the signed error on (distance,
   obliquity), Gaussian kernel with bandwidths ``h_distance``, ``h_obliquity``; three bisquare
   robustness iterations (Cleveland 1979), so single bad detections do not move it.
2. **Spread**: a kernel-weighted median of the absolute leave-one-out residuals times 1.4826
   (a local MAD, the standard deviation for Gaussian errors), so the spread grows where the
   errors do. Its Gaussian-equivalent scale is then calibrated: the training set's leave-one-out
   residuals, divided by the predictive standard deviation, must have their 90 % central interval
   at +-1.645 (one factor per tag and axis, stored as ``calibration``).
3. **Bias uncertainty** (``bias_se``): the standard error of the local fit, ``spread *
   sqrt(sum l_i**2)`` with ``l`` the smoother's weights at the node; it grows where data are thin.
   The predictive standard deviation is ``sqrt(spread**2 + bias_se**2)``.
4. **Correlation across axes**: one 6x6 matrix per tag, the Spearman rank correlation of the
   standardised leave-one-out residuals mapped to Pearson (``2 sin(pi rho / 6)``), clipped to be
   positive semi-definite. It does not vary with the covariates (too few data to say more).
5. **Detection probability**: kernel-weighted detection rate of the configurations whose tag faces
   the camera (view angle > 0), with a Beta prior of weight 1 centred on the tag's overall rate;
   its 90 % interval from the Beta posterior with the kernel mass as the number of trials.

Everything is tabulated on a regular (distance, obliquity) grid spanning the data and evaluated by
bilinear interpolation. **No silent extrapolation**: a node is covered when the kernel mass of the
data there (``support``, about the number of configurations within one bandwidth) is at least
``min_support``; a query is inside the model when it lies in the grid and its bilinearly
interpolated support is at least ``min_support``. Outside, the runtime raises
:class:`OutOfRangeError` (or returns NaN when asked to). A tag facing away from the camera
(obliquity beyond +-pi/2) is never detected: that is geometry, not extrapolation.

Files: :meth:`ErrorModel.save` writes netCDF (grid, units, provenance) and JSON (the schema in the
README, readable by a controller without simgap).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import xarray as xr
from scipy import stats
from scipy.spatial.transform import Rotation

from simgap.core.atomic import atomic_write
from simgap.core.axes import AXES
from simgap.core.rig import Rig, view_angles
from simgap.results.dataset import ERROR_UNITS, write_netcdf

SCHEMA = "simgap-errormodel/1"
#: Two-sided 90 % interval of the standard normal.
Z90 = float(stats.norm.ppf(0.95))
MAD_TO_SIGMA = 1.4826
Outside = Literal["raise", "nan"]


class OutOfRangeError(ValueError):
    """A query lies outside the (distance, obliquity) range the model was fitted on."""


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
        Fewest detections of a tag to fit its errors at all.
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
    robust_iterations: int = 3

    def __post_init__(self) -> None:
        for name in ("h_distance", "h_obliquity", "h_obliquity_det", "step_distance"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: expected a positive value, got {getattr(self, name)}")
        if self.min_support <= 0 or self.min_detections < 4:
            raise ValueError("min_support: expected > 0; min_detections: expected >= 4")


# --- geometry ---------------------------------------------------------------------------------


def pose_matrices(poses: np.ndarray) -> np.ndarray:
    """4x4 ``eyepoint_from_tag`` of poses ``(..., 6)`` (translation m, rotation vector rad)."""
    poses = np.asarray(poses, dtype=float)
    flat = poses.reshape(-1, 6)
    out = np.repeat(np.eye(4)[None], len(flat), axis=0)
    out[:, :3, :3] = Rotation.from_rotvec(flat[:, 3:]).as_matrix()
    out[:, :3, 3] = flat[:, :3]
    return out.reshape(poses.shape[:-1] + (4, 4))


def covariates(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) and signed obliquity (rad) of tag poses ``(..., 6)`` in the global frame."""
    m = pose_matrices(poses)
    t, normal = m[..., :3, 3], m[..., :3, 2]
    distance = np.linalg.norm(t, axis=-1)
    to_camera = -t / distance[..., None]
    turn = to_camera[..., 0] * normal[..., 1] - to_camera[..., 1] * normal[..., 0]
    side = np.where(turn < 0, -1.0, 1.0)
    return distance, side * (np.pi / 2 - view_angles(m))


def perturb(poses: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """Estimated poses from expected poses and errors (DESIGN §1), both ``(..., 6)``.

    Translation: ``t + e_t``; rotation: ``R_est = R(e_r) R_exp``, the inverse of
    :func:`simgap.pose.estimate.pose_error`.
    """
    poses, errors = np.asarray(poses, float), np.asarray(errors, float)
    shape = np.broadcast_shapes(poses.shape, errors.shape)
    p = np.array(np.broadcast_to(poses, shape)).reshape(-1, 6)
    e = np.array(np.broadcast_to(errors, shape)).reshape(-1, 6)
    rot = Rotation.from_rotvec(e[:, 3:]) * Rotation.from_rotvec(p[:, 3:])
    return np.concatenate([p[:, :3] + e[:, :3], rot.as_rotvec()], axis=1).reshape(shape)


# --- smoothing --------------------------------------------------------------------------------


def _kernel(xq: np.ndarray, x: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian kernel weights (Q, N) and scaled offsets (Q, N, 2) of data ``x`` from ``xq``."""
    u = (x[None, :, :] - xq[:, None, :]) / h
    return np.exp(-0.5 * np.sum(u**2, axis=-1)), u


def _local_linear_weights(xq: np.ndarray, x: np.ndarray, w: np.ndarray, h: np.ndarray):
    """Rows ``l`` (Q, N) of the local-linear smoother: the fit at ``xq`` is ``l @ y``."""
    k, u = _kernel(xq, x, h)
    kw = k * w[None, :]
    design = np.concatenate([np.ones(u.shape[:2] + (1,)), u], axis=-1)  # Q, N, 3
    a = np.einsum("qn,qni,qnj->qij", kw, design, design)
    a += np.diag([0.0, 1e-3, 1e-3]) * np.maximum(kw.sum(axis=1), 1e-12)[:, None, None]
    b = np.transpose(design * kw[..., None], (0, 2, 1))  # Q, 3, N
    return np.linalg.solve(a, b)[:, 0, :]


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted median of ``values`` (N,) under each row of ``weights`` (Q, N)."""
    order = np.argsort(values)
    cum = np.cumsum(weights[:, order], axis=1)
    idx = np.argmax(cum >= 0.5 * cum[:, -1:], axis=1)
    return values[order][idx]


def _robust_local_linear(x: np.ndarray, y: np.ndarray, h: np.ndarray, iterations: int):
    """Robustness weights (N,) and leave-one-out residuals (N,) of a robust LOESS fit."""
    w = np.ones(len(y))
    for _ in range(iterations + 1):
        l_data = _local_linear_weights(x, x, w, h)
        resid = y - l_data @ y
        scale = np.median(np.abs(resid)) or 1e-12
        u = resid / (6.0 * scale)
        w_new = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
        if np.array_equal(w_new, w):
            break
        w = w_new
    leverage = np.clip(np.diag(l_data), 0.0, 0.95)
    return w, resid / (1.0 - leverage)


def _rank_correlation(z: np.ndarray) -> np.ndarray:
    """Pearson-equivalent correlation (6, 6) from Spearman's rho, positive semi-definite."""
    rho = stats.spearmanr(z).statistic
    r = 2 * np.sin(np.pi * np.atleast_2d(rho) / 6)
    vals, vecs = np.linalg.eigh(r)
    r = vecs @ np.diag(np.clip(vals, 1e-6, None)) @ vecs.T
    d = np.sqrt(np.diag(r))
    return r / np.outer(d, d)


# --- fitting ----------------------------------------------------------------------------------


def _samples(ds: xr.Dataset, tag: int, config_mask: np.ndarray | None):
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


def _fit_tag(x, err, xd, flags, settings: FitSettings, grid_d, grid_o, tag: int):
    h = np.array([settings.h_distance, settings.h_obliquity])
    nodes = np.stack(np.meshgrid(grid_d, grid_o, indexing="ij"), axis=-1).reshape(-1, 2)
    shape = (len(grid_d), len(grid_o))
    out = {
        "bias": np.full(shape + (6,), np.nan),
        "spread": np.full(shape + (6,), np.nan),
        "bias_se": np.full(shape + (6,), np.nan),
        "calibration": np.full(6, np.nan),
        "correlation": np.eye(6),
    }
    k_det, _ = _kernel(nodes, xd, np.array([settings.h_distance, settings.h_obliquity_det]))
    mass = k_det.sum(axis=1)
    hits = k_det @ flags.astype(float)
    rate = float(np.mean(flags)) if len(flags) else 0.5
    a, b = hits + rate, mass - hits + (1.0 - rate)
    out["p_detect"] = (a / (a + b)).reshape(shape)
    out["p_detect_lo"] = stats.beta.ppf(0.05, a, b).reshape(shape)
    out["p_detect_hi"] = stats.beta.ppf(0.95, a, b).reshape(shape)
    out["support_detection"] = mass.reshape(shape)
    k_err, _ = _kernel(nodes, x, h) if len(x) else (np.zeros((len(nodes), 0)), None)
    out["support_error"] = k_err.sum(axis=1).reshape(shape)
    if len(x) < settings.min_detections:
        return out
    k_data, _ = _kernel(x, x, h)
    np.fill_diagonal(k_data, 0.0)  # each point's spread from its neighbours only (held-out-like)
    z = np.empty_like(err)
    for j in range(6):
        w, loo = _robust_local_linear(x, err[:, j], h, settings.robust_iterations)
        l_nodes = _local_linear_weights(nodes, x, w, h)
        l_data = _local_linear_weights(x, x, w, h)
        sigma_nodes = MAD_TO_SIGMA * _weighted_median(np.abs(loo), k_err)
        sigma_data = MAD_TO_SIGMA * _weighted_median(np.abs(loo), k_data)
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
    out["correlation"] = _rank_correlation(z)
    return out


def fit_error_model(
    ds: xr.Dataset,
    settings: FitSettings = FitSettings(),
    variant: str | None = None,
    config_mask: np.ndarray | None = None,
    source: str = "",
) -> ErrorModel:
    """Fit an error model to a result dataset (DESIGN §3).

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset: simulated, or real after ``simgap ingest``.
    settings : FitSettings
        Bandwidths, grid, coverage rule.
    variant : str, optional
        Variant to model (default: the first).
    config_mask : ndarray of bool (p, theta), optional
        Use only these configurations (e.g. a training half).
    source : str
        Where ``ds`` came from, for the provenance attrs.

    Returns
    -------
    ErrorModel

    Raises
    ------
    ValueError
        If a required variable is missing, the variant is unknown, or no tag has at least
        ``settings.min_detections`` detections (naming the counts).
    """
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
    if max(counts.values()) < settings.min_detections:
        raise ValueError(
            f"too few detections to fit errors: {counts} per tag, need at least "
            f"{settings.min_detections} for one tag"
        )
    allx = np.concatenate([s[2] for s in samples.values()])
    grid_d = _grid(allx[:, 0].min(), allx[:, 0].max(), settings.step_distance)
    grid_o = _grid(allx[:, 1].min(), allx[:, 1].max(), settings.step_obliquity)
    fits = [_fit_tag(*samples[t], settings, grid_d, grid_o, t) for t in tags]
    cube = ("tag", "distance", "obliquity", "axis")
    plane = cube[:3]
    units = {"units": ERROR_UNITS}

    def stack(key: str) -> np.ndarray:
        return np.stack([f[key] for f in fits])

    out = xr.Dataset(
        {
            "bias": (cube, stack("bias"), {**units, "long_name": "location of the signed error"}),
            "spread": (cube, stack("spread"), {**units, "long_name": "std of the error"}),
            "bias_se": (cube, stack("bias_se"), {**units, "long_name": "std error of bias"}),
            "correlation": (("tag", "axis", "axis_b"), stack("correlation")),
            "calibration": (("tag", "axis"), stack("calibration")),
            "p_detect": (plane, stack("p_detect"), {"long_name": "detection probability"}),
            "p_detect_lo": (plane, stack("p_detect_lo"), {"long_name": "5 % bound"}),
            "p_detect_hi": (plane, stack("p_detect_hi"), {"long_name": "95 % bound"}),
            "support_error": (plane, stack("support_error")),
            "support_detection": (plane, stack("support_detection")),
            "detections": (("tag",), np.array([counts[t] for t in tags])),
        },
        coords={
            "tag": ("tag", np.array(tags)),
            "distance": ("distance", grid_d, {"units": "m", "long_name": "eyepoint-tag distance"}),
            "obliquity": (
                "obliquity",
                grid_o,
                {"units": "rad", "long_name": "signed angle between tag normal and line of sight"},
            ),
            "axis": ("axis", np.array(AXES)),
            "axis_b": ("axis_b", np.array(AXES)),
        },
        attrs={
            "schema": SCHEMA,
            "title": "simgap error model",
            "method": "robust local-linear bias, local MAD spread (calibrated to 90 %), "
            "kernel detection rate; bilinear on the grid",
            "settings": json.dumps(settings.__dict__),
            "variant": variant,
            "source": source,
            "source_title": str(ds.attrs.get("title", "")),
            "source_kind": str(ds.attrs.get("source", "simulation")),
            "simgap_version": _version(),
            "min_support": settings.min_support,
        },
    )
    return ErrorModel(out)


def _version() -> str:
    import simgap

    return simgap.__version__


# --- runtime ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class TagPoses:
    """Expected tag poses: what a controller knows before the camera looks.

    Attributes
    ----------
    tags : ndarray of int (N,)
        Tag ids.
    poses : ndarray (N, 6)
        Poses in the global frame (DESIGN §1): translation (m), rotation vector (rad), as the
        dataset's ``expected`` variable.
    """

    tags: np.ndarray
    poses: np.ndarray

    @classmethod
    def one(cls, tag: int, pose: Sequence[float]) -> TagPoses:
        """A single expected pose: ``tags`` is a scalar and ``poses`` has shape (6,)."""
        return cls(np.asarray(int(tag)), np.asarray(pose, float).reshape(6))

    @classmethod
    def from_rig(cls, rig: Rig, tags, ps, thetas) -> TagPoses:
        """Expected poses of the rig's CAD tree at (tag, p, theta) arrays (theta in rad)."""
        tags = np.atleast_1d(np.asarray(tags, int))
        m = rig.eyepoints_from_tags(tags, np.atleast_1d(ps), np.atleast_1d(thetas))
        rotvec = Rotation.from_matrix(m[:, :3, :3]).as_rotvec()
        return cls(tags, np.concatenate([m[:, :3, 3], rotvec], axis=1))


class ErrorModel:
    """A fitted error model (see the module docstring); evaluate, sample, save, load.

    Every method takes :class:`TagPoses` and is vectorised over them. ``outside="raise"`` raises
    :class:`OutOfRangeError` for a query outside the fitted range; ``outside="nan"`` returns NaN
    there instead (use :meth:`covered` to find them).
    """

    def __init__(self, ds: xr.Dataset) -> None:
        self.ds = ds
        self._tags = [int(t) for t in ds.tag.values]

    # --- files ----------------------------------------------------------------------------

    @classmethod
    def load(cls, path: str | Path) -> ErrorModel:
        """Load a model from its netCDF (``.nc``) or JSON (``.json``) file."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: error model not found")
        if path.suffix == ".json":
            return cls(_from_json(json.loads(path.read_text())))
        with xr.open_dataset(path, engine="netcdf4") as ds:
            ds = ds.load()
        if ds.attrs.get("schema") != SCHEMA:
            raise ValueError(f"{path}: not a simgap error model (schema {SCHEMA!r})")
        return cls(ds)

    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Write ``path`` (netCDF) and the same name with ``.json``, atomically; return both."""
        path = Path(path)
        nc = write_netcdf(self.ds, path)
        js = atomic_write(path.with_suffix(".json"), json.dumps(self.to_json()))
        return nc, js

    def to_json(self) -> dict:
        """The JSON form (schema in the README): nested lists, NaN as null."""

        def lists(a: np.ndarray):
            a = np.asarray(a)
            return np.where(np.isfinite(a), np.round(a, 9), np.nan).astype(object).tolist()

        def clean(v):
            if isinstance(v, list):
                return [clean(x) for x in v]
            return None if isinstance(v, float) and math.isnan(v) else v

        ds = self.ds
        tags = {}
        for t in self._tags:
            s = ds.sel(tag=t)
            tags[str(t)] = {
                k: clean(lists(s[k].values))
                for k in (
                    "bias", "spread", "bias_se", "correlation", "p_detect", "p_detect_lo",
                    "p_detect_hi", "support_error", "support_detection",
                )
            }  # fmt: skip
        return {
            "schema": SCHEMA,
            "axes": list(AXES),
            "units": {"distance": "m", "obliquity": "rad", "errors": ERROR_UNITS},
            "min_support": float(ds.attrs["min_support"]),
            "distance": ds.distance.values.tolist(),
            "obliquity": ds.obliquity.values.tolist(),
            "attrs": {k: str(v) for k, v in ds.attrs.items()},
            "tags": tags,
        }

    # --- evaluation -----------------------------------------------------------------------

    def _locate(self, q: TagPoses):
        """Per query: tag index, grid cell (i, j), bilinear fractions, facing-away flag."""
        tags = np.atleast_1d(np.asarray(q.tags, int))
        unknown = sorted(set(tags.tolist()) - set(self._tags))
        if unknown:
            raise ValueError(f"tags {unknown}: not in the model (tags: {self._tags})")
        d, o = covariates(np.asarray(q.poses, float).reshape(-1, 6))
        gd, go = self.ds.distance.values, self.ds.obliquity.values
        inside = (d >= gd[0]) & (d <= gd[-1]) & (o >= go[0]) & (o <= go[-1])
        i = np.clip(np.searchsorted(gd, d, side="right") - 1, 0, max(len(gd) - 2, 0))
        j = np.clip(np.searchsorted(go, o, side="right") - 1, 0, max(len(go) - 2, 0))
        fd = np.clip((d - gd[i]) / np.maximum(np.diff(gd)[i] if len(gd) > 1 else 1, 1e-12), 0, 1)
        fo = np.clip((o - go[j]) / np.maximum(np.diff(go)[j] if len(go) > 1 else 1, 1e-12), 0, 1)
        ti = np.array([self._tags.index(t) for t in tags])
        return ti, i, j, fd, fo, inside, np.abs(o) >= np.pi / 2, d, o

    def _interp(self, name: str, loc) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear value of ``name`` and whether the query is covered for it.

        Covered: inside the grid, interpolated support >= ``min_support`` and a finite value.
        """
        ti, i, j, fd, fo, inside, *_ = loc
        arr = self.ds[name].values
        support = "support_detection" if name.startswith("p_detect") else "support_error"
        i1 = np.minimum(i + 1, arr.shape[1] - 1)
        j1 = np.minimum(j + 1, arr.shape[2] - 1)
        weights = [(1 - fd) * (1 - fo), fd * (1 - fo), (1 - fd) * fo, fd * fo]
        corners = [(i, j), (i1, j), (i, j1), (i1, j1)]

        def bilinear(a: np.ndarray) -> np.ndarray:
            shape = (-1,) + (1,) * (a.ndim - 3)
            return sum(
                w.reshape(shape) * a[ti, r, c] for w, (r, c) in zip(weights, corners, strict=True)
            )

        val = bilinear(arr)
        sup = bilinear(self.ds[support].values)
        finite = np.isfinite(val) if val.ndim == 1 else np.all(np.isfinite(val), axis=1)
        ok = inside & (sup >= float(self.ds.attrs["min_support"])) & finite
        return val, ok

    def covered(self, q: TagPoses) -> np.ndarray:
        """Whether each query lies where the error model was fitted (bool (N,))."""
        return self._interp("bias", self._locate(q))[1]

    def _check(self, ok: np.ndarray, loc, what: str, outside: Outside) -> None:
        if outside == "raise" and not ok.all():
            k = int(np.argmin(ok))
            d, o = loc[7][k], loc[8][k]
            gd, go = self.ds.distance.values, self.ds.obliquity.values
            raise OutOfRangeError(
                f"query {k}: distance {d:.4f} m, obliquity {math.degrees(o):.1f} deg is outside "
                f"the fitted {what} range (distance {gd[0]:.4f}..{gd[-1]:.4f} m, obliquity "
                f"{math.degrees(go[0]):.1f}..{math.degrees(go[-1]):.1f} deg, and covered nodes "
                "only); pass outside='nan' to get NaN there"
            )
        if outside not in ("raise", "nan"):
            raise ValueError(f"outside: expected 'raise' or 'nan', got {outside!r}")

    def error_mean(self, q: TagPoses, outside: Outside = "raise") -> np.ndarray:
        """Mean signed error (N, 6) (m, rad): the bias."""
        loc = self._locate(q)
        val, ok = self._interp("bias", loc)
        self._check(ok, loc, "error", outside)
        return np.where(ok[:, None], val, np.nan)

    def mean(self, q: TagPoses, outside: Outside = "raise") -> np.ndarray:
        """Mean estimated pose (N, 6): the expected pose perturbed by the bias."""
        return perturb(q.poses, self.error_mean(q, outside))

    def std(self, q: TagPoses, outside: Outside = "raise") -> np.ndarray:
        """Predictive standard deviation of the error (N, 6): ``sqrt(spread**2 + bias_se**2)``."""
        loc = self._locate(q)
        spread, ok = self._interp("spread", loc)
        se, _ = self._interp("bias_se", loc)
        self._check(ok, loc, "error", outside)
        return np.where(ok[:, None], np.sqrt(spread**2 + se**2), np.nan)

    def cov(self, q: TagPoses, outside: Outside = "raise") -> np.ndarray:
        """Predictive covariance of the error (N, 6, 6), in the error's axes (m, rad)."""
        sd = self.std(q, outside)
        ti = self._locate(q)[0]
        corr = self.ds.correlation.values[ti]
        return sd[:, :, None] * corr * sd[:, None, :]

    def interval(self, q: TagPoses, outside: Outside = "raise") -> tuple[np.ndarray, np.ndarray]:
        """Central 90 % interval of the signed error per axis: (low, high), each (N, 6)."""
        mean, sd = self.error_mean(q, outside), self.std(q, outside)
        return mean - Z90 * sd, mean + Z90 * sd

    def detection_probability(self, q: TagPoses, outside: Outside = "raise") -> np.ndarray:
        """Probability (N,) that each tag is detected (0 for a tag facing away)."""
        loc = self._locate(q)
        p, ok = self._interp("p_detect", loc)
        away = loc[6]
        ok = ok | away
        self._check(ok, loc, "detection", outside)
        return np.where(away, 0.0, np.where(ok, p, np.nan))

    def sample(
        self, q: TagPoses, rng: np.random.Generator, outside: Outside = "raise"
    ) -> np.ndarray | None:
        """Draw estimated poses: NaN rows (or None for a single query) where missed.

        Parameters
        ----------
        q : TagPoses
            Expected poses (one or many).
        rng : numpy.random.Generator
            Random source.
        outside : {"raise", "nan"}
            What to do outside the fitted range.

        Returns
        -------
        ndarray (N, 6), ndarray (6,) or None
            The perturbed poses (global frame, m and rad); for a single query (``len(tags) ==
            1``) the pose (6,) or None for a missed detection.
        """
        n = len(np.atleast_1d(q.tags))
        p = self.detection_probability(q, outside)
        hit = rng.uniform(size=n) < np.nan_to_num(p)
        out = np.full((n, 6), np.nan)
        if hit.any():
            tags = np.broadcast_to(np.atleast_1d(q.tags), (n,))
            sub = TagPoses(tags[hit], np.asarray(q.poses).reshape(-1, 6)[hit])
            mean, cov = self.error_mean(sub, outside), self.cov(sub, outside)
            good = np.all(np.isfinite(mean), axis=1)
            chol = np.linalg.cholesky(np.where(good[:, None, None], cov, np.eye(6)))
            e = mean + np.einsum("nij,nj->ni", chol, rng.standard_normal((len(mean), 6)))
            out[hit] = perturb(sub.poses, e)
        if np.ndim(q.tags) == 0:
            return out[0] if hit[0] else None
        return out


def _from_json(data: dict) -> xr.Dataset:
    """The model dataset from its JSON form."""
    if data.get("schema") != SCHEMA:
        raise ValueError(f"not a simgap error model (schema {SCHEMA!r})")
    tags = sorted(int(t) for t in data["tags"])

    def arr(key: str) -> np.ndarray:
        values = [data["tags"][str(t)][key] for t in tags]
        return np.array(values, dtype=object).astype(float)  # null -> NaN

    cube, plane = ("tag", "distance", "obliquity", "axis"), ("tag", "distance", "obliquity")
    return xr.Dataset(
        {
            "bias": (cube, arr("bias")),
            "spread": (cube, arr("spread")),
            "bias_se": (cube, arr("bias_se")),
            "correlation": (("tag", "axis", "axis_b"), arr("correlation")),
            "p_detect": (plane, arr("p_detect")),
            "p_detect_lo": (plane, arr("p_detect_lo")),
            "p_detect_hi": (plane, arr("p_detect_hi")),
            "support_error": (plane, arr("support_error")),
            "support_detection": (plane, arr("support_detection")),
        },
        coords={
            "tag": tags,
            "distance": data["distance"],
            "obliquity": data["obliquity"],
            "axis": list(data["axes"]),
            "axis_b": list(data["axes"]),
        },
        attrs={**data.get("attrs", {}), "min_support": float(data["min_support"])},
    )


# --- the honest check -------------------------------------------------------------------------


def split_configurations(ds: xr.Dataset, seed: int = 0) -> np.ndarray:
    """A random half of the (p, theta) configurations: bool (p, theta), True = training."""
    rng = np.random.default_rng(seed)
    n = ds.sizes["p"] * ds.sizes["theta"]
    train = np.zeros(n, bool)
    train[rng.permutation(n)[: n // 2]] = True
    return train.reshape(ds.sizes["p"], ds.sizes["theta"])


def evaluate_held_out(
    model: ErrorModel, ds: xr.Dataset, held_out: np.ndarray, variant: str | None = None
) -> dict:
    """Coverage of the 90 % intervals and detection calibration on held-out configurations.

    Parameters
    ----------
    model : ErrorModel
        Fitted on the other configurations.
    ds : xarray.Dataset
        The result dataset.
    held_out : ndarray of bool (p, theta)
        The configurations to predict.
    variant : str, optional
        Default: the model's variant.

    Returns
    -------
    dict
        ``coverage`` (per axis: fraction of held-out detected errors inside the 90 % interval),
        ``coverage_by_tag``, ``n_errors`` (held-out detections inside the model's range),
        ``n_outside`` (held-out detections outside it: not predicted, counted),
        ``detection`` (``bins``: predicted-probability bins with mean predicted, observed rate
        and count; ``brier``; ``n``; ``n_outside``).
    """
    variant = variant or str(model.ds.attrs.get("variant", ds.variant.values[0]))
    sub = ds.sel(variant=variant)
    inside_all, hits, probs = [], [], []
    cover: dict[int, list] = {}
    n_outside = n_det_outside = 0
    for tag in model._tags:
        exp = sub.sel(tag=tag).expected.transpose("p", "theta", "axis").values
        det = sub.sel(tag=tag).detected.transpose("repeat", "p", "theta").values
        errs = sub.sel(tag=tag).error.transpose("repeat", "p", "theta", "axis").values
        poses = np.broadcast_to(exp, det.shape + (6,))
        _, o = covariates(exp)
        trials = np.broadcast_to(held_out & (np.abs(o) < np.pi / 2), det.shape)
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
            int(t): {a: float(c[:, k].mean()) for k, a in enumerate(AXES)} for t, c in cover.items()
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
    ds: xr.Dataset, settings: FitSettings = FitSettings(), seed: int = 0, variant: str | None = None
) -> dict:
    """Fit on a random half of the configurations, evaluate on the other half."""
    train = split_configurations(ds, seed)
    model = fit_error_model(ds, settings, variant, config_mask=train)
    return evaluate_held_out(model, ds, ~train, variant)
