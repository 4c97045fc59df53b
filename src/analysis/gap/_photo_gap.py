"""The sim-to-real gap of a board's real photos: where it lies, which camera effects, how far.

Each photo is rendered at its reference pose (:func:`simgap.pipeline.photos.render_photos`) and
measured as the photo is; the gap is each marker sighting's real minus simulated single-marker
error (:func:`simgap.results.photo_summary.gap_by`, mm), read in thirds of the photos' distances,
view angles and image radii (where it lies).

Which: the camera's own exposure and softness, fitted on the image statistics around the
markers, never on the pose gap (:func:`fit_photo_camera`): the exposure from the paper's
linear level (the median over sightings of real over simulated, papers clipped in either left
out), the blur from the edge width (the catalogue's blur whose simulated median edge width is
the real one, :func:`fit_photo_camera`). Both are the catalogue's image effects
(``exposure``, ``blur``) run on the renders (:func:`simgap.effects.image.run_pipeline`).

How far, cross-fitted: the frames are split in two cross-fit folds (even and odd positions); each
fold is simulated with the camera fitted on the other fold's statistics, so no frame's gap after is
measured with effects fitted on that frame.

Against an external reference (a robot's chain, a poses file) the rig's own geometry is fitted
too, on the gap left after the camera (:func:`simgap.analysis.gap.fit_rig`: a camera offset such
as a hand-eye error, a board offset, a print scale), and its gap after is cross-fitted the same
way: each fold's predicted rig error, from the model fitted on the other fold, taken off its real
errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import xarray as xr
from scipy.optimize import brentq

from simgap.analysis.gap._rig_fit import RigFit, fit_rig, rig_error
from simgap.core.board import Board
from simgap.core.limits import PHOTO_SPP
from simgap.core.progress import ProgressCallback
from simgap.core.rig import CameraModel
from simgap.effects import make_effect
from simgap.effects.state import ImageState, VariantState
from simgap.pipeline.photo_references import EXTERNAL_REFERENCES
from simgap.pipeline.photos import render_photos, simulate_photos
from simgap.results.photo_summary import COVARIATES, BandGap, gap_by
from simgap.scene.spec import SceneSpec

#: Paper levels at or above this linear level (of full scale) are clipped or nearly so (8-bit
#: 250 of 255 through sRGB): a lower bound of the exposure only, left out of its fit.
PAPER_CLIP_LEVEL = 0.955
#: Blur searched (PSF sigma, px): from a sampled Gaussian that barely blurs to a soft lens.
BLUR_BOUNDS_PX = (0.05, 3.0)
#: First upper end of the blur's bracket (px), doubled until the simulated edges are wider.
BLUR_BRACKET_START_PX = 0.5
#: Tolerance of the blur's root (px).
BLUR_XTOL_PX = 0.01
#: Labels of the ``image`` dimension of a photo diagnosis's dataset.
PHOTO_IMAGES = ("real", "simulated", "simulated_fitted")


@dataclass(frozen=True)
class PhotoCameraFit:
    """The camera's own exposure and softness, fitted on a photo set's image statistics.

    Attributes
    ----------
    exposure_ev : float
        log2 of the median real over simulated paper level (stops).
    blur_sigma_px : float
        Gaussian PSF (px) added to the simulation; 0 where the real edges are not wider.
    real_edge_width_px, simulated_edge_width_px : float
        Median 10-90 % edge widths of the markers' borders (px) the blur was fitted on.
    real_paper_level, simulated_paper_level : float
        Median paper levels (linear, of full scale) the exposure was fitted on.
    sightings : int
        Marker sightings with statistics in both.
    """

    exposure_ev: float
    blur_sigma_px: float
    real_edge_width_px: float
    simulated_edge_width_px: float
    real_paper_level: float
    simulated_paper_level: float
    sightings: int

    def image_state(self) -> ImageState:
        """The camera pipeline of the fit (:func:`camera_pipeline`)."""
        return camera_pipeline(self.exposure_ev, self.blur_sigma_px)


def camera_pipeline(exposure_ev: float, blur_sigma_px: float) -> ImageState:
    """The catalogue's ``exposure`` (EV) and ``blur`` (px), each where it is not zero."""
    state = VariantState()
    if np.isfinite(exposure_ev) and exposure_ev != 0.0:
        state = make_effect("exposure", {"ev": exposure_ev}).apply(state)
    if blur_sigma_px > 0.0:
        state = make_effect("blur", {"sigma_px": blur_sigma_px}).apply(state)
    return state.image


def fit_photo_camera(
    real: xr.Dataset,
    nominal: xr.Dataset,
    renders: list[np.ndarray | None],
    board: Board,
    camera: CameraModel,
    frames: np.ndarray | None = None,
) -> PhotoCameraFit:
    """Exposure and blur of the camera from real and simulated marker statistics (module doc).

    ``nominal`` is the renders' simulation without camera effects
    (:func:`simgap.pipeline.photos.simulate_photos`); ``frames`` (bool per frame) restricts the
    fit to some frames (default: all). The exposure is read off the paper levels; the blur is
    the root in :data:`BLUR_BOUNDS_PX` (bracketed from :data:`BLUR_BRACKET_START_PX` up) of
    the median edge width of the frames simulated through
    the catalogue's ``blur`` after that exposure, against the real median (the sampled
    Gaussian of a small sigma blurs less than its sigma says, so the width is matched through
    the effect itself, not by adding variances).
    """
    keep = np.ones(real.sizes["frame"], bool) if frames is None else np.asarray(frames, bool)

    def values(ds: xr.Dataset, name: str) -> np.ndarray:
        return ds[name].transpose("frame", "marker").values[keep].ravel()

    paper_r, paper_s = values(real, "paper_level"), values(nominal, "paper_level")
    width_r = values(real, "edge_width")
    seen = np.isfinite(paper_r) & np.isfinite(paper_s)
    unclipped = seen & (paper_r < PAPER_CLIP_LEVEL) & (paper_s < PAPER_CLIP_LEVEL) & (paper_r > 0)
    nan = float("nan")
    ratio = np.log2(paper_r[unclipped] / paper_s[unclipped])
    ev = float(np.median(ratio)) if unclipped.any() else 0.0
    target = float(np.nanmedian(width_r)) if np.isfinite(width_r).any() else nan
    subset = [r if k else None for r, k in zip(renders, keep, strict=True)]

    def width(sigma: float) -> float:
        sim = simulate_photos(real, subset, board, camera, camera_pipeline(ev, sigma))
        return float(np.nanmedian(sim["edge_width"].values))

    w_sim = width(0.0)
    sigma = 0.0
    if np.isfinite(target) and target > w_sim:
        lo, hi = BLUR_BOUNDS_PX[0], BLUR_BRACKET_START_PX
        w_hi = width(hi)
        while np.isfinite(w_hi) and w_hi <= target and hi < BLUR_BOUNDS_PX[1]:
            lo, hi = hi, min(2 * hi, BLUR_BOUNDS_PX[1])
            w_hi = width(hi)
        if not np.isfinite(w_hi) or w_hi <= target:
            sigma = lo if not np.isfinite(w_hi) else hi  # at the edge of what can be measured
        else:
            sigma = float(brentq(lambda s: width(s) - target, lo, hi, xtol=BLUR_XTOL_PX))
    return PhotoCameraFit(
        exposure_ev=ev,
        blur_sigma_px=sigma,
        real_edge_width_px=target,
        simulated_edge_width_px=w_sim,
        real_paper_level=float(np.median(paper_r[unclipped])) if unclipped.any() else nan,
        simulated_paper_level=float(np.median(paper_s[unclipped])) if unclipped.any() else nan,
        sightings=int(np.isfinite(width_r).sum()),
    )


@dataclass(frozen=True)
class PhotoGaps:
    """Where a photo diagnosis's gap lies before and after, read from its dataset alone.

    Attributes
    ----------
    before, after : dict of str to list of BandGap
        Real - simulated in thirds of each covariate
        (:data:`simgap.results.photo_summary.COVARIATES`): the nominal simulation
        (``simulated``) and the cross-fitted one (``simulated_fitted``).
    rig : RigFit or None
        The rig's geometry fitted on all frames' gap after the camera; None without an external
        reference.
    after_rig : dict of str to list of BandGap
        Real - simulated after the camera and the found rig model, cross-fitted (empty where
        no rig model was found).
    """

    before: dict[str, list[BandGap]]
    after: dict[str, list[BandGap]]
    rig: RigFit | None = None
    after_rig: dict[str, list[BandGap]] = field(default_factory=dict)


@dataclass(frozen=True)
class PhotoDiagnosis:
    """A photo set's gap before and after the fitted camera effects.

    Attributes
    ----------
    fit : PhotoCameraFit
        The camera fitted on all frames (what is reported).
    gaps : PhotoGaps
        Where the gap lies before and after (the camera's, and the rig's where found).
    edge_width_after_px : float
        Median edge width of the cross-fitted simulation (px), against ``fit``'s real one.
    dataset : xarray.Dataset
        The photo datasets along ``image`` (:data:`PHOTO_IMAGES`), with the fit in its attributes.
    """

    fit: PhotoCameraFit
    gaps: PhotoGaps
    edge_width_after_px: float
    dataset: xr.Dataset


def diagnose_photos(
    real: xr.Dataset,
    board: Board,
    camera: CameraModel,
    spec: SceneSpec | None = None,
    spp: int = PHOTO_SPP,
    seed: int = 0,
    progress: ProgressCallback | None = None,
) -> PhotoDiagnosis:
    """Simulate ``real`` (:func:`simgap.pipeline.photos.measure_photos`), fit, re-simulate.

    See the module doc; ``spec``, ``spp`` and ``seed`` are the renders'
    (:func:`simgap.pipeline.photos.render_photos`).
    """
    renders = render_photos(real, board, camera, spec, spp, seed, progress)
    nominal = simulate_photos(real, renders, board, camera, progress=progress)
    fit = fit_photo_camera(real, nominal, renders, board, camera)
    fold = cross_fit_fold(real.sizes["frame"])
    parts = []
    for held in (fold, ~fold):
        other = fit_photo_camera(real, nominal, renders, board, camera, frames=~held)
        sim = simulate_photos(real, renders, board, camera, other.image_state(), progress=progress)
        parts.append(sim.where(xr.DataArray(held, dims="frame")))
    fitted = parts[0].fillna(parts[1])
    fitted["detected"] = fitted["detected"].fillna(0).astype(np.int8)
    fitted["reference_points"] = fitted["reference_points"].fillna(0).astype(np.int32)
    for name in fitted.data_vars:
        fitted[name].attrs = nominal[name].attrs
    dataset = xr.concat([real, nominal, fitted], dim="image", combine_attrs="override")
    dataset = dataset.assign_coords(
        image=("image", list(PHOTO_IMAGES), {"long_name": "image source"})
    )
    dataset.attrs.update(
        fitted_exposure_ev=fit.exposure_ev,
        fitted_blur_sigma_px=fit.blur_sigma_px,
        render_spp=spp,
        render_seed=seed,
    )
    gaps = photo_gaps(dataset, board)
    if gaps.rig is not None and gaps.rig.found is not None:
        dataset.attrs.update(
            fitted_rig_model=gaps.rig.found.name,
            **{f"fitted_rig_{k}": v for k, v in gaps.rig.found.parameters.items()},
        )
    return PhotoDiagnosis(
        fit=fit,
        gaps=gaps,
        edge_width_after_px=float(np.nanmedian(fitted["edge_width"].values)),
        dataset=dataset,
    )


def photo_gaps(dataset: xr.Dataset, board: Board) -> PhotoGaps:
    """The gaps of a photo diagnosis's dataset (its ``image`` dimension: :data:`PHOTO_IMAGES`).

    The same from the dataset :func:`diagnose_photos` returns or from its netCDF file: the rig
    is fitted again (a weighted linear least squares, deterministic) where the reference is
    external, with the same cross-fit folds.
    """
    real, nominal, fitted = (dataset.sel(image=name, drop=True) for name in PHOTO_IMAGES)
    rig, after_rig = None, {}
    if real.attrs.get("reference") in EXTERNAL_REFERENCES:
        rig = fit_rig(real, fitted, board)
        if rig.found is not None:
            fold = cross_fit_fold(real.sizes["frame"])
            corrected = rig_corrected(real, fitted, board, fold, rig.found.name)
            after_rig = {c: gap_by(corrected, fitted, c) for c in COVARIATES}
    return PhotoGaps(
        before={c: gap_by(real, nominal, c) for c in COVARIATES},
        after={c: gap_by(real, fitted, c) for c in COVARIATES},
        rig=rig,
        after_rig=after_rig,
    )


def cross_fit_fold(frames: int) -> np.ndarray:
    """The first cross-fit fold of ``frames`` photos (bool (frames,)): the even positions."""
    return np.arange(frames) % 2 == 0


def rig_corrected(
    real: xr.Dataset, simulated: xr.Dataset, board: Board, fold: np.ndarray, model: str
) -> xr.Dataset:
    """``real`` with each fold's predicted rig error taken off its position errors.

    The error of ``model`` fitted on the other fold (module doc).
    """
    errors = real["error_translation"].transpose("frame", "marker", "camera_axis").values.copy()
    for held in (fold, ~fold):
        other = fit_rig(real.isel(frame=~held), simulated.isel(frame=~held), board)
        fitted = next(m for m in other.models if m.name == model)
        errors[held] -= rig_error(real.isel(frame=held), board, fitted)
    corrected = real.copy()
    corrected["error_translation"] = (("frame", "marker", "camera_axis"), errors)
    return corrected


__all__ = [
    "BLUR_BOUNDS_PX",
    "BLUR_BRACKET_START_PX",
    "BLUR_XTOL_PX",
    "PHOTO_IMAGES",
    "PAPER_CLIP_LEVEL",
    "PhotoCameraFit",
    "PhotoDiagnosis",
    "PhotoGaps",
    "camera_pipeline",
    "cross_fit_fold",
    "diagnose_photos",
    "fit_photo_camera",
    "photo_gaps",
    "rig_corrected",
]
