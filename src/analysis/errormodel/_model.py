"""The error model's query API: expected tag poses in, error statistics and samples out.

See :mod:`simgap.analysis.errormodel` for what the model holds; files are read and written by
:mod:`simgap.analysis.errormodel._io`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import xarray as xr
from scipy import stats
from scipy.spatial.transform import Rotation

from simgap.analysis.errormodel._geometry import covariates, perturb
from simgap.analysis.errormodel._io import dataset_to_json, read_model_dataset, write_model_dataset
from simgap.core.rig import Rig

#: Half width of the two-sided 90 % interval of the standard normal, Phi^-1(0.95) = 1.645.
Z90 = float(stats.norm.ppf(0.95))
Outside = Literal["raise", "nan"]


class OutOfRangeError(ValueError):
    """A query lies outside the (distance, obliquity) range the model was fitted on."""


@dataclass(frozen=True)
class TagPoses:
    """Expected tag poses: what a controller knows before the camera looks.

    Attributes
    ----------
    tags : ndarray of int (N,)
        Tag ids.
    poses : ndarray (N, 6)
        Poses in the global frame (docs/conventions.md §1): translation (m), rotation vector
        (rad), as the dataset's ``expected`` variable.
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

    @property
    def tags(self) -> list[int]:
        """Tag ids of the model."""
        return list(self._tags)

    # --- files ----------------------------------------------------------------------------

    @classmethod
    def load(cls, path: str | Path) -> ErrorModel:
        """Load a model from its netCDF (``.nc``) or JSON (``.json``) file."""
        return cls(read_model_dataset(path))

    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Write ``path`` (netCDF) and the same name with ``.json``, atomically; return both."""
        return write_model_dataset(self.ds, path)

    def to_json(self) -> dict:
        """The JSON form (schema in docs/errormodel.md): nested lists, NaN as null."""
        return dataset_to_json(self.ds)

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
        ti = np.array([self._tags.index(t) for t in tags], dtype=int)  # none: an empty query
        return ti, i, j, fd, fo, inside, np.abs(o) >= np.pi / 2, d, o

    def _interp(self, name: str, loc) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear value of ``name`` and whether the query is covered for it.

        Covered: inside the grid, interpolated support >= ``min_support`` (to a relative 1e-9)
        and a finite value.
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
        # relative 1e-9: bilinear weights summing to 1 in floating point (a pooled tag's support
        # is the same n at every corner and must not fall to n - 1 ulp)
        ok = inside & (sup >= float(self.ds.attrs["min_support"]) * (1 - 1e-9)) & finite
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
