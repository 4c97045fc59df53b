"""Sensor noise fitted by the photon transfer of the capture's noise (EMVA 1288).

The appearance candidate ``sensor_noise`` (:class:`SensorNoiseCandidate`): shot and read noise
of the real camera from the noise of flat ink and paper cells against their level, beyond what
the simulation already has, modelled the way the image statistics measure it (the grey frame of
8-bit sRGB channels clipped at black: :func:`grey_noise`).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Sequence

import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.optimize import least_squares

from simgap.analysis.candidates._appearance import (
    AppearanceCandidate,
    capture_jpeg_quality,
    misfit_rms,
    signature_supported,
)
from simgap.analysis.candidates._fitting import Fit, on_bound
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.gap import Items
from simgap.effects.state import VariantState
from simgap.pose.image_stats import STAT_INDEX, linearise
from simgap.render import imaging
from simgap.render.imaging import GRAY_NOISE_VARIANCE_RATIO

#: Largest photo-response non-uniformity of a real camera the noise fit allows (relative sigma):
#: EMVA 1288 datasheets give below 1 % for machine-vision CMOS sensors; 2 % allows for the
#: print's texture. Without a bound, shot noise and a multiplicative term cannot be told apart
#: over the narrow range of paper levels of a fit split (a blind capture's fit ran off to
#: a 10^6 e full well when its renderer's noise was twice the simulation's).
PRNU_MAX = 0.02
#: Range of full wells fitted (electrons per linear 1.0): from a very noisy sensor to none
#: (10^6 e is the photon noise of a 20-bit sensor, far below the 8-bit frame's steps).
FULL_WELL_BOUNDS_E = (10.0, 1e6)
#: Largest read noise reported (e-): ten times the noisiest machine-vision sensor of EMVA 1288
#: datasheets (about 100 e-); beyond it the fit has traded shot noise for read noise.
READ_NOISE_MAX_E = 1e3
#: (level, spatial noise) and (level, temporal noise) statistics of the ink and paper cells.
NOISE_PAIRS = (("ink_linear", "noise_ink_linear"), ("paper_linear", "noise_paper_linear"))
TEMPORAL_NOISE_PAIRS = (
    ("ink_linear", "temporal_noise_ink_linear"),
    ("paper_linear", "temporal_noise_paper_linear"),
)
#: Highest level (share of the white level, linear) of a cell the photon transfer is fitted on:
#: EMVA 1288 fits the photon transfer up to 70 % of saturation, where no channel clips yet. Above
#: it a channel clips before the grey frame does (a warm light's red), and the variance falls with
#: the level (tenfold from 0.59 to 0.92 on a development capture, where the fit ran to its
#: 10^6 e- bound). Measured on development captures, fitting below this share brought the full
#: wells' 90th-percentile error from 141 % to 51 % (docs/results/design_evidence.md#sensor_noise).
SATURATION_FIT_SHARE = 0.7
#: Fixed-point steps that recover the level before clipping at black from a measured median.
CLIP_STEPS = 12


class SensorNoiseCandidate(AppearanceCandidate):
    """Shot + read noise from the photon transfer of the capture's noise (EMVA 1288).

    The effect adds, in each of R, G and B at linear level ``mu``, the variance
    ``mu / full_well + (read / full_well)^2`` (linear 1.0 = ``full_well`` electrons). What the
    image statistics see of it on the grey frame, and what the fit models:

    - the grey frame averages the channels: :data:`~simgap.render.imaging.GRAY_NOISE_VARIANCE_RATIO`
      (0.447) of the per-channel variance;
    - the 8-bit frame clips each channel at black and averages them in sRGB-encoded values: the
      median and variance of the linearised grey value (:func:`grey_noise`) at the ink's level;
    - a multiplicative term ``c mu^2`` beside it: the camera's spatial variance of flat cells
      that grows with the level squared (photo-response non-uniformity in EMVA 1288, print
      texture), between 0 and :data:`PRNU_MAX` squared. It is not part of the effect.

    The capture's own spatial variance of ink and paper regions of every tag of the fit split is
    fitted by bounded robust least squares on ``(1 / full_well, (read / full_well)^2, c)``. The
    simulation's variance is not subtracted: it is the renderer's Monte Carlo noise, which a
    camera does not have, and it is measured at the simulation's level, not the capture's (a
    capture a stop darker than the simulation had its paper's shot noise cancelled). Subtracting it
    sent a third of the one-frame development captures to the 10^6 e- bound, and the hidden sensors'
    full wells read a median 59 % off; fitted on the capture's own variance, 25 % (a renderer's own
    noise in a pseudo-real capture still reads as shot noise: full wells up to 0.3-0.5x on the
    noisiest; docs/results/design_evidence.md#sensor_noise). Where the capture has two frames of a
    pose, shot and read noise are fitted on the temporal noise instead (the frames' difference: no
    fixed pattern, so no ``c``; the simulation's own sensor noise, if it models one, subtracted),
    and ``c`` alone on the spatial variance: over the narrow range of paper levels of one capture
    the spatial noise cannot tell shot noise from ``c`` (full wells read 1.4-2.2x too large from one
    frame of development captures).

    A compressed capture's noise is not its sensor's: the quantiser rounds most of the sensor's
    noise away, and the blocks' steps read as spatial noise. On eight synthetic tags through the
    camera pipeline, one frame compressed at qualities 35-80 (a DC step the tags agree on), the
    fit read full wells 1.9-15x the sensor's (1500 e- read 22 735; 2000 e- at quality 80 read
    8464; tests/test_appearance_fit.py), and on rendered captures the other way: a converged
    simulation compressed at quality 69 alone had more paper noise than the capture (0.0085
    against 0.0075 on a development capture). A fit through the compression (the simulation's
    noise compressed and matched) did not converge: the quantiser kept 5-56 % of the noise
    variance between two noise levels of the same tags. Where the capture shows a JPEG
    quantiser (its tags agree on a DC step,
    :func:`~simgap.analysis.candidates._appearance.capture_jpeg_quality`) the fit is therefore not
    supported: the noise is explained by the JPEG candidate, whose prediction compresses the
    simulation, or left unexplained (where it was supported, a sensor noise took the
    compression's noise of blind JPEG captures and the JPEG was left out;
    docs/results/design_evidence.md#sensor_noise).
    """

    n_params = 2

    def __init__(self) -> None:
        stats = ("noise_paper_linear", "noise_ink_linear")
        super().__init__("sensor_noise", stats, "full_well_e", FULL_WELL_BOUNDS_E, 0.0)

    @staticmethod
    def excess_variance(x: np.ndarray | Sequence[float], level: np.ndarray) -> np.ndarray:
        """Predicted excess variance of the linearised grey frame at measured ``level``.

        ``x`` = (1 / full well, (read / full well)^2, multiplicative c); linear units (squared).
        ``level`` is the median of the linearised grey values; the level before clipping at
        black is recovered from it by fixed-point steps (:func:`grey_noise`).
        """
        slope, intercept, c = x
        mu = level.copy()
        for _ in range(CLIP_STEPS):
            sigma = np.sqrt(slope * np.clip(mu, 0.0, None) + intercept) + 1e-12
            median, variance = grey_noise(mu, sigma)
            mu = mu + (level - median)
        return variance + c * level**2

    @staticmethod
    def _samples(items: Items, pairs: tuple[tuple[str, str], ...]) -> tuple[np.ndarray, np.ndarray]:
        """Levels and variances of the capture's cells of ``pairs`` in the photon-transfer range.

        Cells without a measured noise, and cells above :data:`SATURATION_FIT_SHARE` of the
        white level, are left out.
        """
        levels, variances = [], []
        for level, noise in pairs:
            mu = items.required("real_stats")[:, STAT_INDEX[level]]
            var = items.required("real_stats")[:, STAT_INDEX[noise]] ** 2
            ok = np.isfinite(mu) & np.isfinite(var) & (var > 0) & (mu <= SATURATION_FIT_SHARE)
            levels.append(mu[ok])
            variances.append(var[ok])
        return np.concatenate(levels), np.concatenate(variances)

    @classmethod
    def _simulated_temporal_variance(cls, base: VariantState, level: np.ndarray) -> np.ndarray:
        """Temporal variance the simulation's own sensor noise (if any) has at ``level``."""
        for name, params in base.image.ops:
            if name == "sensor_noise":
                fw, read = params.full_well_e, params.read_noise_e
                return cls.excess_variance((1.0 / fw, (read / fw) ** 2, 0.0), level)
        return np.zeros_like(level)

    def _photon_transfer(self, base: VariantState, items: Items) -> tuple[np.ndarray, bool] | None:
        """The photon transfer of the capture's noise (class doc).

        Parameters
        ----------
        base : VariantState
            The simulation's state (its own sensor noise, if any, is subtracted from the
            temporal noise).
        items : Items
            The capture's cells: their levels and noise (linear).

        Returns
        -------
        (ndarray (3,), bool) or None
            ``(1 / full well, (read / full well)^2, c)`` (per electron, squared, and the
            multiplicative variance; linear 1.0 = the full well) and whether shot and read noise
            came from the temporal noise; None with fewer than 4 cells.
        """
        # the capture's own spatial variance: a camera has no render noise, so the simulation's
        # (its Monte Carlo noise, measured at the simulation's level, not the capture's) is not
        # subtracted (see the class doc)
        mu, var = self._samples(items, NOISE_PAIRS)
        if mu.size < 4:
            return None
        # c is the camera's multiplicative variance: its photo-response non-uniformity and the
        # print's texture, at most PRNU_MAX^2
        c_bounds = (0.0, PRNU_MAX**2)
        mu_t, real_t = self._samples(items, TEMPORAL_NOISE_PAIRS)
        var_t = real_t - self._simulated_temporal_variance(base, mu_t)
        temporal = mu_t.size >= 4 and bool(np.any(var_t > 0))
        # the slope 1 / full well, bounded by the full wells fitted
        slope_lo, slope_hi = 1.0 / FULL_WELL_BOUNDS_E[1], 1.0 / FULL_WELL_BOUNDS_E[0]
        # a variance estimated from n pixel pairs has a standard error proportional to it:
        # residuals relative to the measured variance weigh every tag alike
        if temporal:
            # EMVA 1288: the temporal variance has no fixed-pattern part, so shot and read noise
            # are fitted alone; the spatial excess then gives the multiplicative term only
            shot_read = least_squares(
                lambda x: (self.excess_variance((x[0], x[1], 0.0), mu_t) - var_t) / real_t,
                x0=[1e-3, 1e-5],
                x_scale=[1e-3, 1e-4],
                bounds=([slope_lo, 0.0], [slope_hi, 1e-2]),
                loss="soft_l1",
            ).x
            c = least_squares(
                lambda x: (self.excess_variance((*shot_read, x[0]), mu) - var) / var,
                x0=[0.5 * sum(c_bounds)],
                x_scale=[1e-3],
                bounds=c_bounds,
                loss="soft_l1",
            ).x
            return np.concatenate([shot_read, c]), temporal
        x = least_squares(
            lambda x: (self.excess_variance(x, mu) - var) / var,
            x0=[1e-3, 1e-5, 0.5 * sum(c_bounds)],
            x_scale=[1e-3, 1e-4, 1e-3],
            bounds=([slope_lo, 0.0, c_bounds[0]], [slope_hi, 1e-2, c_bounds[1]]),
            loss="soft_l1",
        ).x
        return x, temporal

    @staticmethod
    def _params(x: np.ndarray) -> dict[str, float]:
        """Effect parameters of ``x`` = (1 / full well, (read / full well)^2, c).

        Returns ``full_well_e`` (e-, within :data:`FULL_WELL_BOUNDS_E`) and ``read_noise_e``
        (e-, at most :data:`READ_NOISE_MAX_E`).
        """
        full_well = float(np.clip(1.0 / x[0], *FULL_WELL_BOUNDS_E))
        read = float(min(np.sqrt(x[1]) * full_well, READ_NOISE_MAX_E))
        return {"full_well_e": full_well, "read_noise_e": read}

    def fit(self, runner: Runner | None, base: VariantState, items: Items) -> Fit:
        """Photon transfer fit of the capture's noise (temporal where it has two frames a pose).

        Not supported where the capture shows a JPEG quantiser (class doc).
        """
        t0 = time.perf_counter()
        fitted = self._photon_transfer(base, items)
        quality = capture_jpeg_quality(items.required("real_stats"))
        if fitted is None:  # nothing to fit on: no noise found
            none = {"full_well_e": FULL_WELL_BOUNDS_E[1], "read_noise_e": 0.0}
            return Fit(self.effect, none, 0.0, {"supported": False, "jpeg_quality": quality})
        x, temporal = fitted
        params = self._params(x)
        full_well, read = params["full_well_e"], params["read_noise_e"]
        # on a bound: no shot noise at all (the full well at 10^6 e) or 10 e-, or read noise at
        # its cap (none, at zero, is a value, not a bound); the full well's range spans five
        # decades, so it is judged on a log scale
        at_bound = tuple(
            name
            for name, hit in (
                ("full_well_e", on_bound(*np.log10([full_well, *FULL_WELL_BOUNDS_E]))),
                ("read_noise_e", on_bound(read, -READ_NOISE_MAX_E, READ_NOISE_MAX_E)),
            )
            if hit
        )
        # the capture's noise statistics the fit predicts, for the signature gate
        stats = self.fit_stats
        real, sim = items.required("real_stats"), items.required("sim_stats")
        pred = sim.copy()
        for level, noise in NOISE_PAIRS:
            i, j = STAT_INDEX[level], STAT_INDEX[noise]
            variance = self.excess_variance(x, real[:, i])
            pred[:, j] = np.sqrt(np.clip(variance, 0.0, None))
        rms_before = misfit_rms(stats, real, sim)
        rms_after = misfit_rms(stats, real, pred)
        return Fit(
            self.effect,
            params,
            time.perf_counter() - t0,
            {
                "slope_per_level": float(x[0]),
                "intercept": float(x[1]),
                "multiplicative_variance": float(x[2]),
                "temporal": temporal,
                "jpeg_quality": quality,
                "supported": signature_supported(rms_before, rms_after) and quality is None,
                "at_bound": at_bound,
            },
        )


@functools.cache
def grey_noise_table() -> tuple[np.ndarray, np.ndarray, RectBivariateSpline, RectBivariateSpline]:
    """Median and variance of the linearised grey value of noisy R, G, B (see :func:`grey_noise`).

    Each channel is ``max(mu + sigma n, 0)`` with ``n ~ N(0, 1)`` independent, encoded to 8-bit
    sRGB, converted to grey and linearised: the camera pipeline and the image statistics'
    own functions. Tabulated against ``z = mu / sigma`` (-3 to 6) and ``log sigma``; Monte
    Carlo with a fixed seed (the same table in every run; ~1.6 s, once per process). Returns
    the two grids and bilinear interpolators of the median and the variance on them (degree-1
    splines through the grid values: the same interpolation as
    ``scipy.interpolate.RegularGridInterpolator``, about ten times cheaper to call, which the
    photon-transfer fit does thousands of times).
    """
    z = np.linspace(-3.0, 6.0, 61)
    log_sigma = np.linspace(np.log(1e-3), np.log(0.3), 25)
    n = np.random.default_rng(0).standard_normal((4000, 3)).astype(np.float32)
    median = np.empty((z.size, log_sigma.size))
    variance = np.empty_like(median)
    for j, sigma in enumerate(np.exp(log_sigma)):
        rgb = sigma * (z[:, None, None] + n[None])
        grey = linearise(imaging.to_gray(imaging.encode_srgb8(rgb)))
        median[:, j], variance[:, j] = np.median(grey, axis=1), np.var(grey, axis=1)
    return (
        z,
        log_sigma,
        RectBivariateSpline(z, log_sigma, median, kx=1, ky=1),
        RectBivariateSpline(z, log_sigma, variance, kx=1, ky=1),
    )


def grey_noise(mu: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Median and variance of the linearised grey value at channel level ``mu``, noise ``sigma``.

    What the image statistics measure of independent noise ``sigma`` in R, G and B at linear
    level ``mu``: the grey frame averages the channels (variance
    :data:`~simgap.render.imaging.GRAY_NOISE_VARIANCE_RATIO` of one channel's), the 8-bit frame
    clips each at black first and averages them in sRGB-encoded values. Far above black
    (``mu / sigma`` > 6) the median is ``mu`` and the variance the ratio times ``sigma^2``.
    """
    z_grid, s_grid, median, variance = grey_noise_table()
    z = mu / sigma
    far = z > z_grid[-1]
    z_in = np.clip(z, z_grid[0], z_grid[-1])
    log_sigma = np.clip(np.log(sigma), s_grid[0], s_grid[-1])
    scale = sigma / np.exp(log_sigma)  # beyond the sigma grid, scale the nearest column
    return (
        np.where(far, mu, median.ev(z_in, log_sigma) * scale),
        np.where(
            far, GRAY_NOISE_VARIANCE_RATIO * sigma**2, variance.ev(z_in, log_sigma) * scale**2
        ),
    )
