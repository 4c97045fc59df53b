"""The rig's own geometry, fitted on a board photo set's gap against an external reference.

Where each photo's board pose comes from outside the photos (a robot's chain with its hand-eye,
a tracker's poses: :mod:`simgap.pipeline.photo_references`), an error in that chain moves every
marker's reference the same way, and the single-marker errors carry it. The gap, real minus
simulated (each photo rendered at its reference pose and measured as the photo is, so the
detector's own bias cancels), is read per sighting as a position error ``g`` (m, OpenCV camera
frame) and fitted by linear least squares with each of :data:`RIG_MODELS`:

``camera_offset``
    The camera is not where the reference puts it: its true pose in the reference's camera
    frame is ``D = (I + [w]x, d)`` (a hand-eye error; a tracker's camera calibration), so a
    marker the reference puts at ``p`` (camera frame) is seen at ``D^-1 p`` and
    ``g = -d + [p]x w``. The hand-eye that removes it is the given one times ``D``.
``board_offset``
    The board is not where the reference puts it: its true pose is ``T_ref E``, ``E = (I +
    [w_b]x, d_b)`` in the board frame (a board-in-base error; a tracker's board calibration), so
    ``g = R (d_b - [q]x w_b)``, ``q`` the marker centre on the board and ``R`` the board's
    rotation. The board-in-base that removes it is the given one times ``E``.
``print_scale``
    The print is ``1 + s`` times its nominal size (about the board's origin): a single marker's
    pose from its corners at the nominal size is the true one scaled towards the camera centre,
    ``g = -s t`` to first order, ``t`` the board origin in the camera frame.

The least squares are weighted per camera axis by the gap's robust spread along it (``mad_sigma``
about the median): one marker's depth from its four corners scatters by millimetres where its
lateral position scatters by tenths (measured on simgap's own renders of six board photos at
16 spp: 4.5-5.2 mm against 0.4-0.7 mm), and unweighted, that depth scatter decided the fit. The
misfit is the RMS of the weighted gap (in those spreads).

Each model's parameters get leave-one-photo-out jackknife standard deviations (Efron &
Tibshirani 1993, ch. 11). A model is found where, as a calibration file's correction
(:mod:`simgap.pose.calibration_check`), it is clear (a parameter at least
:data:`~simgap.pose.calibration_check.DISAGREE_SIGMAS` sd from zero) and useful (the misfit
falls by at least :data:`~simgap.pose.calibration_check.MIN_RMS_FALL`). The found models whose
misfit is within that share of the least one explain the gap alike: the one with the fewest
parameters is the answer (a print scale before a six-parameter offset), and the others are named
as look-alikes the photos do not tell apart (photos from more board orientations would).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Final

import numpy as np
import xarray as xr

from simgap.core import transforms as tf
from simgap.core.board import Board
from simgap.core.robust import jackknife_std, mad_sigma
from simgap.pose.calibration_check import DISAGREE_SIGMAS, MIN_PHOTOS, MIN_RMS_FALL

#: Least spread (m) an axis is weighted by, and least RMS gap a model is fitted on: a hundredth of
#: a millimetre, below any single marker's positional scatter in a photo (0.4-5 mm measured,
#: module doc); an axis or a gap under it is round-off.
SPREAD_FLOOR_M: Final[float] = 1e-5


def _skew(v: np.ndarray) -> np.ndarray:
    """``[v]x`` for each row of ``v`` (n, 3) -> (n, 3, 3): ``[v]x u = v x u``."""
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    return out - out.transpose(0, 2, 1)


@dataclass(frozen=True)
class _Geometry:
    """What the rig models read of each sighting.

    The marker centre in the camera (``p``) and board (``q``) frames (m), the board's reference
    ``rotation`` and ``origin`` (camera frame, m) and the sighting's frame index.
    """

    p: np.ndarray
    q: np.ndarray
    rotation: np.ndarray
    origin: np.ndarray
    frame: np.ndarray


def _camera_offset(g: _Geometry) -> np.ndarray:
    eye = np.broadcast_to(np.eye(3), (len(g.p), 3, 3))
    return np.concatenate([-eye, _skew(g.p)], axis=2)


def _board_offset(g: _Geometry) -> np.ndarray:
    return np.concatenate([g.rotation, -g.rotation @ _skew(g.q)], axis=2)


def _print_scale(g: _Geometry) -> np.ndarray:
    return -g.origin[:, :, None]


@dataclass(frozen=True)
class RigModel:
    """One way the rig's geometry can differ from the reference: its design matrix and units.

    Attributes
    ----------
    name : str
        ``camera_offset``, ``board_offset`` or ``print_scale`` (module doc).
    parameters : tuple of str
        Its parameters' names, in the fit's order.
    design : callable
        Per sighting the (3, k) matrix taking the parameters (m, rad, or a fraction) to ``g`` (m).
    """

    name: str
    parameters: tuple[str, ...]
    design: Callable[[_Geometry], np.ndarray]


#: The models fitted (module doc).
RIG_MODELS: Final = (
    RigModel("camera_offset", ("dx_m", "dy_m", "dz_m", "wx_rad", "wy_rad", "wz_rad"),
             _camera_offset),
    RigModel("board_offset", ("dx_m", "dy_m", "dz_m", "wx_rad", "wy_rad", "wz_rad"),
             _board_offset),
    RigModel("print_scale", ("scale",), _print_scale),
)  # fmt: skip


@dataclass(frozen=True)
class RigModelFit:
    """One rig model fitted on the gap.

    Attributes
    ----------
    name : str
        The model (:data:`RIG_MODELS`).
    parameters : dict of str to float
        Fitted values: ``d*_m`` in m, ``w*_rad`` in rad, ``scale`` a fraction (module doc).
    std : dict of str to float
        Their jackknife standard deviations (same units; NaN with too few photos).
    rms_before_m, rms_after_m : float
        RMS over sightings of the gap's length before and after the model (m).
    misfit_before, misfit_after : float
        RMS of the weighted gap before and after the model (each axis in its robust spread).
    clear, useful : bool
        A parameter at least ``DISAGREE_SIGMAS`` sd from zero; the misfit falls by
        ``MIN_RMS_FALL``.
    """

    name: str
    parameters: dict[str, float]
    std: dict[str, float]
    rms_before_m: float
    rms_after_m: float
    misfit_before: float
    misfit_after: float
    clear: bool
    useful: bool

    @property
    def found(self) -> bool:
        """Clear and useful (module doc)."""
        return self.clear and self.useful


@dataclass(frozen=True)
class RigFit:
    """The rig models fitted on a photo set's gap, and which one the photos single out.

    Attributes
    ----------
    models : tuple of RigModelFit
        Every model of :data:`RIG_MODELS`, in its order (none without a sighting).
    found : RigModelFit or None
        Of the found models within ``MIN_RMS_FALL`` of the least misfit, the one with the
        fewest parameters (None: the gap holds no rig offset).
    look_alikes : tuple of str
        The other found models within ``MIN_RMS_FALL`` of the least misfit.
    sightings, frames : int
        Sightings (markers seen in both real and simulated photos) and photos fitted on.
    spread_m : tuple of float
        The gap's robust spread along the camera's x, y and z (m): the weights.
    """

    models: tuple[RigModelFit, ...]
    found: RigModelFit | None
    look_alikes: tuple[str, ...]
    sightings: int
    frames: int
    spread_m: tuple[float, float, float]

    def lines(self, reference: str) -> list[str]:
        """What the fit found, for the console, in mm, mrad and %.

        A heading naming the ``reference``, one line a model, and the verdict.
        """
        spreads = ", ".join(
            f"{a} {1e3 * v:.2f} mm" for a, v in zip("xyz", self.spread_m, strict=True)
        )
        out = [
            f"the rig, fitted on the gap after the camera against the {reference} "
            f"({self.sightings} sightings, {self.frames} photos; value +- jackknife sd; RMS gap "
            f"before -> after, and weighted by each axis's spread, {spreads}):"
        ]
        for m in self.models:
            values = ", ".join(
                f"{k.removesuffix('_m').removesuffix('_rad')} {parameter_text(k, v)} "
                f"+- {parameter_text(k, m.std[k]).lstrip('+')}"
                for k, v in m.parameters.items()
            )
            mark = "  FOUND" if m is self.found else ""
            out.append(
                f"  {m.name:<14} {values}; RMS {1e3 * m.rms_before_m:.2f} -> "
                f"{1e3 * m.rms_after_m:.2f} mm, weighted {m.misfit_before:.2f} -> "
                f"{m.misfit_after:.2f}{mark}"
            )
        if self.found is None:
            out.append(
                f"no rig offset: no model is both {DISAGREE_SIGMAS:g} sd from zero and lowering "
                f"the weighted RMS by {100 * MIN_RMS_FALL:g} %"
            )
        elif self.look_alikes:
            out.append(
                f"{self.found.name} and {', '.join(self.look_alikes)} explain the gap alike: "
                "photos from more board orientations would tell them apart"
            )
        return out


def _geometry(ds: xr.Dataset, board: Board) -> _Geometry:
    """Every (frame, marker) sighting's geometry from the reference poses of ``ds``."""
    ids = [int(m) for m in ds["marker"].values]
    q_marker = np.array([board.board_from_marker(m)[:3, 3] for m in ids])
    rotvec = ds["board_rotation"].transpose("frame", "camera_axis").values
    origin = ds["board_translation"].transpose("frame", "camera_axis").values
    # a frame without a reference pose: identity here, NaN through its origin
    rot = tf.rotvec_to_matrix(np.where(np.isfinite(rotvec), rotvec, 0.0)).reshape(-1, 3, 3)
    n_f, n_m = len(origin), len(ids)
    rotation = np.repeat(rot, n_m, axis=0)
    q = np.tile(q_marker, (n_f, 1))
    t = np.repeat(origin, n_m, axis=0)
    p = np.einsum("nij,nj->ni", rotation, q) + t
    return _Geometry(p, q, rotation, t, np.repeat(np.arange(n_f), n_m))


def _gap(real: xr.Dataset, simulated: xr.Dataset) -> np.ndarray:
    """Real minus simulated position error per (frame, marker) sighting, (n, 3) m."""

    def err(ds: xr.Dataset) -> np.ndarray:
        return ds["error_translation"].transpose("frame", "marker", "camera_axis").values

    return (err(real) - err(simulated)).reshape(-1, 3)


def _solve(design: np.ndarray, gap: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Weighted least-squares parameters of ``gap`` (n, 3) through ``design`` (n, 3, k)."""
    a = (design / spread[None, :, None]).reshape(-1, design.shape[2])
    return np.linalg.lstsq(a, (gap / spread).reshape(-1), rcond=None)[0]


def _rms(gap: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(gap**2, axis=1))))


def _fit_model(
    model: RigModel, geometry: _Geometry, gap: np.ndarray, spread: np.ndarray
) -> RigModelFit:
    design = model.design(geometry)
    x = _solve(design, gap, spread)
    after = gap - np.einsum("nik,k->ni", design, x)
    frames = np.unique(geometry.frame)
    std = np.full(len(x), np.nan)
    if len(frames) >= MIN_PHOTOS:
        loo = np.array([
            _solve(design[geometry.frame != f], gap[geometry.frame != f], spread) for f in frames
        ])  # fmt: skip
        std = jackknife_std(loo)
    misfit_before, misfit_after = _rms(gap / spread), _rms(after / spread)
    return RigModelFit(
        name=model.name,
        parameters=dict(zip(model.parameters, map(float, x), strict=True)),
        std=dict(zip(model.parameters, map(float, std), strict=True)),
        rms_before_m=_rms(gap),
        rms_after_m=_rms(after),
        misfit_before=misfit_before,
        misfit_after=misfit_after,
        clear=bool(np.any((std > 0) & (np.abs(x) >= DISAGREE_SIGMAS * std))),
        useful=bool(
            _rms(gap) >= SPREAD_FLOOR_M and misfit_after <= (1.0 - MIN_RMS_FALL) * misfit_before
        ),
    )


def _seen(real: xr.Dataset, simulated: xr.Dataset, board: Board) -> tuple[_Geometry, np.ndarray]:
    """The geometry and gap of the sightings seen in both (finite gap and reference)."""
    geometry = _geometry(real, board)
    gap = _gap(real, simulated)
    ok = np.isfinite(gap).all(axis=1) & np.isfinite(geometry.p).all(axis=1)
    kept = _Geometry(**{f.name: getattr(geometry, f.name)[ok] for f in fields(geometry)})
    return kept, gap[ok]


def fit_rig(real: xr.Dataset, simulated: xr.Dataset, board: Board) -> RigFit:
    """Fit :data:`RIG_MODELS` on the gap of ``real`` against ``simulated`` (module doc).

    Both are photo datasets of the same frames and markers measured against the same external
    reference (:func:`simgap.pipeline.photos.simulate_photos`). Without a sighting seen in both
    no model is fitted (``models`` empty); in fewer than
    :data:`~simgap.pose.calibration_check.MIN_PHOTOS` photos the models are fitted without a
    jackknife, so none is found.
    """
    geometry, gap = _seen(real, simulated, board)
    frames = len(np.unique(geometry.frame))
    if not len(gap):
        return RigFit((), None, (), 0, 0, (np.nan, np.nan, np.nan))
    spread = np.array([mad_sigma(gap[:, k] - np.median(gap[:, k])) for k in range(3)])
    spread = np.maximum(spread, SPREAD_FLOOR_M)
    models = tuple(_fit_model(m, geometry, gap, spread) for m in RIG_MODELS)
    found = sorted((m for m in models if m.found), key=lambda m: m.misfit_after)
    alike = [m for m in found if m.misfit_after * (1.0 - MIN_RMS_FALL) <= found[0].misfit_after]
    # of models that explain the gap alike, the one with the fewest parameters (parsimony)
    best = min(alike, key=lambda m: len(m.parameters)) if alike else None
    look_alikes = tuple(m.name for m in alike if m is not best)
    x, y, z = (float(v) for v in spread)
    return RigFit(models, best, look_alikes, len(gap), frames, (x, y, z))


def parameter_text(name: str, value: float) -> str:
    """A rig model's parameter, signed, in the engineer's units.

    ``*_m`` in mm, ``*_rad`` in mrad, a scale in %.
    """
    if name.endswith("_m"):
        return f"{1e3 * value:+.2f} mm"
    if name.endswith("_rad"):
        return f"{1e3 * value:+.2f} mrad"
    return f"{100 * value:+.3f} %"


def rig_error(ds: xr.Dataset, board: Board, model: RigModelFit) -> np.ndarray:
    """The position error (m, camera frame) ``model`` predicts per sighting of ``ds``.

    Shaped as its ``error_translation`` (frame, marker, camera_axis); from ``ds``'s reference
    poses.
    """
    spec = next(m for m in RIG_MODELS if m.name == model.name)
    x = np.array([model.parameters[p] for p in spec.parameters])
    geometry = _geometry(ds, board)
    predicted = np.einsum("nik,k->ni", spec.design(geometry), x)
    return predicted.reshape(ds.sizes["frame"], ds.sizes["marker"], 3)


__all__ = [
    "RIG_MODELS",
    "SPREAD_FLOOR_M",
    "RigFit",
    "RigModel",
    "RigModelFit",
    "fit_rig",
    "parameter_text",
    "rig_error",
]
