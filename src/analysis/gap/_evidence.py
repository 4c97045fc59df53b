"""Where the gap lies beyond the pose means: pose scatter, detection rate and image evidence.

Three families of tests compare a real dataset with its simulation (aligned items):

scatter
    Per axis, over all items and per distance region, the spread of the pose error
    around its smooth course. With
    repeats, the deviations of each repeat from its item's mean; otherwise the residual
    of each value from the straight line through its two neighbours along the carriage (exact
    for any linear trend, also for unevenly spaced pin holes), scaled to unit noise. Real and
    simulated residuals are compared with the Brown-Forsythe test (``scipy.stats.levene`` with
    ``center="median"``). Significant when the test rejects at :data:`SIGNIFICANCE_LEVEL`
    (Bonferroni over the tests), the robust scales differ by :data:`SCATTER_RATIO` or more, and the
    extra scatter ``sqrt(|real^2 - sim^2|)`` reaches :data:`SCATTER_FLOOR_SHARE` of the practical
    floor.
detection
    Detected / visible counts of the real data and of the simulation (over repeats), overall,
    per distance region and per view-angle band; Boschloo's exact test of the 2 x 2 table
    (:func:`detection_pvalue`). The overall test is the one planned test, at
    :data:`~simgap.analysis.thresholds.SIGNIFICANCE_LEVEL`; the six regional tests are corrected for
    their multiplicity by Holm's step-down rule at the same level (:func:`holm_reject`). Significant
    when the test rejects and the rates differ by
    :data:`~simgap.analysis.thresholds.DETECTION_UNIT` or more. A fifth of 45 detections lost
    overall (36 / 45 against 45 / 45: p = 0.00098) and half of one 15-configuration region
    (7 / 15 against 15 / 15: p = 0.00082 < 0.01 / 6) are significant; with Fisher's test and
    Bonferroni over all seven (p 0.0025 against 0.0014) the first was not.
image
    Per statistic of :mod:`simgap.pose.image_stats`, the paired difference real - simulated over
    tags visible in both (levels and noise as log2 ratios, in stops); Wilcoxon's signed-rank test
    (``scipy.stats.wilcoxon``). Significant when it rejects at :data:`SIGNIFICANCE_LEVEL` and the
    median difference reaches the statistic's practical floor (:data:`IMAGE_FLOORS`).

The thresholds (:data:`SIGNIFICANCE_LEVEL` and the others) are those of
:mod:`simgap.analysis.thresholds`, with their sources; every one was fixed before the blind
validation runs that report on it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import xarray as xr
from scipy import stats as sps

from simgap.analysis.gap._gap import align
from simgap.analysis.gap._image_evidence import repeat_median_stats, tag_distance_and_view_angle
from simgap.analysis.thresholds import (
    BOSCHLOO_MAX_ATTEMPTS,
    DETECTION_UNIT,
    IMAGE_FLOORS,
    PRACTICAL_FLOOR,
    SCATTER_FLOOR_SHARE,
    SCATTER_RATIO,
    SIGNIFICANCE_LEVEL,
)
from simgap.core.axes import AXES, axis_unit
from simgap.core.robust import mad_sigma, signed_rank_pvalue

#: View-angle bands (deg) for the detection tests: oblique, intermediate, frontal.
VIEW_BANDS_DEG = ((0.0, 35.0), (35.0, 60.0), (60.0, 90.1))
#: Added to linear levels before taking log2 ratios (a tenth of an 8-bit step near black).
LEVEL_EPSILON = 0.002


@dataclass(frozen=True, kw_only=True)
class EvidenceTest:
    """A test of real against simulated evidence: its p-value and whether the difference matters.

    ``significant``: the test rejects (at :data:`~simgap.analysis.thresholds.SIGNIFICANCE_LEVEL`,
    Bonferroni over its family) and the difference reaches its practical floor (see the module
    docstring).
    """

    p_value: float
    significant: bool


@dataclass(frozen=True, kw_only=True)
class ScatterTest(EvidenceTest):
    """Brown-Forsythe test of real vs simulated pose scatter on one axis and region."""

    #: pose axis, distance region (``"all"`` or a third) and the axis unit (m or rad)
    axis: str
    region: str
    unit: str
    #: noise samples of each side
    n_real: int
    n_sim: int
    #: robust scales of the samples (m or rad), their ratio real / simulated and the extra
    #: scatter ``sqrt(|real^2 - sim^2|)`` (m or rad)
    real_scatter: float
    sim_scatter: float
    ratio: float
    extra_scatter: float


@dataclass(frozen=True, kw_only=True)
class DetectionTest(EvidenceTest):
    """Exact test of real vs simulated detection rate in one region (:func:`detection_pvalue`)."""

    #: ``"all"``, a distance third or a view-angle band
    region: str
    #: ``"planned"`` (``all``, at SIGNIFICANCE_LEVEL) or ``"Holm over regions"`` (the six regional
    #: tests); empty in results written before the exact tests were corrected this way (Fisher's
    #: test, Bonferroni over all seven)
    test: str = ""
    #: detections and attempts (visible items times repeats) of each side
    real_detected: int
    real_attempts: int
    sim_detected: int
    sim_attempts: int
    #: detection rates (0-1) and real minus simulated
    real_rate: float
    sim_rate: float
    difference: float


@dataclass(frozen=True, kw_only=True)
class ImageTest(EvidenceTest):
    """Wilcoxon signed-rank test of the paired real - simulated difference of one statistic."""

    #: statistic name (:data:`~simgap.analysis.thresholds.IMAGE_FLOORS`) and how it is compared:
    #: ``"difference"`` or ``"log2 ratio (stops)"``
    stat: str
    compared_as: str
    #: tags paired
    n: int
    #: median difference real - simulated, in the comparison units
    median_difference: float
    #: median of the statistic on each side (its own units)
    real_median: float
    sim_median: float
    #: smallest median difference that matters (None: reported only, never significant)
    floor: float | None


def robust_scale(values: np.ndarray) -> float:
    """Normal-consistent median absolute deviation of the finite values (NaN if fewer than 3)."""
    v = np.asarray(values, float)
    return mad_sigma(v) if np.isfinite(v).sum() >= 3 else float("nan")


def line_residuals(field: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Residuals of each value from the line through its neighbours along the last axis.

    For ``x[i-1] < x[i] < x[i+1]`` the residual is ``f[i] - (w f[i-1] + (1 - w) f[i+1])`` with
    ``w = (x[i+1] - x[i]) / (x[i+1] - x[i-1])``, divided by ``sqrt(1 + w^2 + (1 - w)^2)`` so
    that white noise of unit variance gives unit variance. A linear trend leaves zero.

    Returns
    -------
    ndarray (..., n - 2)
    """
    x = np.asarray(x, float)
    w = (x[2:] - x[1:-1]) / (x[2:] - x[:-2])
    res = field[..., 1:-1] - (w * field[..., :-2] + (1 - w) * field[..., 2:])
    return res / np.sqrt(1 + w**2 + (1 - w) ** 2)


def _variant(ds: xr.Dataset, name: str) -> xr.Dataset:
    return ds.sel(variant=name) if name in ds.variant.values else ds.isel(variant=0)


def noise_residuals(ds: xr.Dataset, variant: str | None = None) -> xr.DataArray:
    """Pose noise samples per item (repeat or neighbour residuals), see module docstring.

    Returns
    -------
    xarray.DataArray (sample, tag, p, theta, axis)
        NaN where there is no sample; ``p`` is the middle pin hole of a neighbour residual.
    """
    err = _variant(ds, variant or "").error.transpose("repeat", "tag", "p", "theta", "axis")
    e = err.values
    r = e.shape[0]
    if r > 1:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            dev = (e - np.nanmean(e, axis=0, keepdims=True)) * np.sqrt(r / (r - 1))
        coords = {"tag": err.tag, "p": err.p, "theta": err.theta, "axis": err.axis}
        return xr.DataArray(dev, dims=("sample", "tag", "p", "theta", "axis"), coords=coords)
    field = np.moveaxis(e[0], 1, -1)  # tag, theta, axis, p
    ps = err.p.values
    res = np.moveaxis(line_residuals(field, ps), -1, 1)[None] if ps.size >= 3 else e[:, :, :0]
    coords = {"tag": err.tag, "p": ps[1:-1], "theta": err.theta, "axis": err.axis}
    return xr.DataArray(res, dims=("sample", "tag", "p", "theta", "axis"), coords=coords)


def distance_regions(ps: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Near / mid / far thirds of the pin holes, named with their range."""
    ps = np.asarray(ps)
    thirds = np.array_split(np.arange(ps.size), 3)
    return [
        (f"{name} (p {ps[idx].min()}-{ps[idx].max()})", ps[idx])
        for name, idx in zip(("near", "mid", "far"), thirds, strict=True)
        if idx.size
    ]


def scatter_tests(real: xr.Dataset, sim: xr.Dataset) -> list[ScatterTest]:
    """Brown-Forsythe tests of real vs simulated pose scatter per axis, overall and per region."""
    real, sim = align(real, sim)
    res_r, res_s = noise_residuals(real), noise_residuals(sim)
    rows = []
    regions = distance_regions(res_r.p.values) if res_r.p.size else []
    regions = [("all", res_r.p.values)] + regions if regions else []
    n_tests = max(len(regions) * len(AXES), 1)
    for axis in AXES:
        unit = axis_unit(axis)
        for name, members in regions:
            a = res_r.sel(axis=axis, p=members).values.ravel()
            b = res_s.sel(axis=axis, p=members).values.ravel()
            a, b = a[np.isfinite(a)], b[np.isfinite(b)]
            if a.size < 5 or b.size < 5:
                continue
            sa, sb = robust_scale(a), robust_scale(b)
            pvalue = float(sps.levene(a, b, center="median").pvalue)
            ratio = sa / sb if sb > 0 else float("inf")
            extra = float(np.sqrt(abs(sa**2 - sb**2)))
            significant = (
                pvalue < SIGNIFICANCE_LEVEL / n_tests
                and (ratio >= SCATTER_RATIO or ratio <= 1 / SCATTER_RATIO)
                and extra >= SCATTER_FLOOR_SHARE * PRACTICAL_FLOOR[unit]
            )
            rows.append(
                ScatterTest(
                    axis=axis,
                    region=name,
                    unit=unit,
                    n_real=int(a.size),
                    n_sim=int(b.size),
                    real_scatter=sa,
                    sim_scatter=sb,
                    ratio=float(ratio),
                    extra_scatter=extra,
                    p_value=pvalue,
                    significant=bool(significant),
                )
            )
    return rows


def detection_pvalue(kr: int, nr: int, ks: int, ns: int) -> float:
    """Two-sided p-value that real and simulated detection rates are equal.

    ``kr`` of ``nr`` real attempts detected, ``ks`` of ``ns`` simulated. Boschloo's exact test
    (``scipy.stats.boschloo_exact``), uniformly more powerful than Fisher's for a 2 x 2 table
    with fixed attempts; Fisher's beyond
    :data:`~simgap.analysis.thresholds.BOSCHLOO_MAX_ATTEMPTS` attempts, where both have the same
    power.
    """
    table = [[kr, nr - kr], [ks, ns - ks]]
    if kr + ks in (0, nr + ns):  # every attempt detected (or none) on both sides: no evidence
        return 1.0
    if min(nr, ns) > BOSCHLOO_MAX_ATTEMPTS:
        return float(sps.fisher_exact(table).pvalue)
    return float(min(sps.boschloo_exact(table).pvalue, 1.0))


def holm_reject(pvalues: list[float], alpha: float = SIGNIFICANCE_LEVEL) -> list[bool]:
    """Holm's step-down rule: which of ``pvalues`` are rejected at family-wise ``alpha``.

    The k-th smallest p-value (k from 0) is compared with ``alpha / (m - k)``; testing stops at
    the first that is not below it. Uniformly more powerful than Bonferroni, same guarantee.
    """
    order = np.argsort(pvalues)
    reject = [False] * len(pvalues)
    for k, i in enumerate(order):
        if not pvalues[i] < alpha / (len(pvalues) - k):
            break
        reject[i] = True
    return reject


def detection_tests(real: xr.Dataset, sim: xr.Dataset) -> list[DetectionTest]:
    """Tests of real vs simulated detection rates, overall and per region (module docstring).

    Rows: ``all`` (the planned test), then the distance regions and view-angle bands (Holm).
    """
    real, sim = align(real, sim)
    visible = real.visible if "variant" not in real.visible.dims else real.visible.isel(variant=0)
    _, view = tag_distance_and_view_angle(real)
    det_r = real.detected.isel(variant=0).where(visible)
    det_s = sim.detected.isel(variant=0).where(visible)
    ps = real.p.values
    masks: list[tuple[str, xr.DataArray]] = [("all", visible)]
    masks += [(name, visible & real.p.isin(members)) for name, members in distance_regions(ps)]
    masks += [
        (f"view {lo:g}-{min(hi, 90):g} deg", visible & (view >= lo) & (view < hi))
        for lo, hi in VIEW_BANDS_DEG
    ]
    rows = []
    for name, mask in masks:
        nr = int((mask.sum() * real.sizes["repeat"]).item())
        ns = int((mask.sum() * sim.sizes["repeat"]).item())
        if nr == 0 or ns == 0:
            continue
        kr = int(det_r.where(mask).sum().item())
        ks = int(det_s.where(mask).sum().item())
        rows.append((name, kr, nr, ks, ns))
    pvalues = [detection_pvalue(kr, nr, ks, ns) for _, kr, nr, ks, ns in rows]
    regional = [i for i, row in enumerate(rows) if row[0] != "all"]
    rejected = dict(zip(regional, holm_reject([pvalues[i] for i in regional]), strict=True))
    tests = []
    for i, (name, kr, nr, ks, ns) in enumerate(rows):
        planned = name == "all"
        reject = pvalues[i] < SIGNIFICANCE_LEVEL if planned else rejected[i]
        diff = kr / nr - ks / ns
        tests.append(
            DetectionTest(
                region=name,
                test="planned" if planned else "Holm over regions",
                real_detected=kr,
                real_attempts=nr,
                sim_detected=ks,
                sim_attempts=ns,
                real_rate=kr / nr,
                sim_rate=ks / ns,
                difference=diff,
                p_value=pvalues[i],
                significant=bool(reject and abs(diff) >= DETECTION_UNIT),
            )
        )
    return tests


def compare_stat(stat: str, real: np.ndarray, sim: np.ndarray) -> np.ndarray:
    """Per-tag difference real - simulated of one statistic in its comparison units.

    A log2 ratio of a value at or below ``-LEVEL_EPSILON`` (a level below black, from a dark
    frame's offset) is NaN: not comparable, left out like an undetected tag.
    """
    transform, _ = IMAGE_FLOORS.get(stat, ("diff", None))
    if transform == "log2":
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = (real + LEVEL_EPSILON) / (sim + LEVEL_EPSILON)
            return np.log2(np.where(ratio > 0, ratio, np.nan))
    return real - sim


def paired_test(stat: str, real: np.ndarray, sim: np.ndarray) -> ImageTest | None:
    """Wilcoxon signed-rank test of the paired difference real - simulated of one statistic.

    Parameters
    ----------
    stat : str
        Statistic name (:data:`~simgap.analysis.thresholds.IMAGE_FLOORS`), which sets the
        comparison units and the floor.
    real, sim : ndarray
        The statistic on the same tags, real and simulated; pairs with a NaN are left out of
        the test (the medians of each side take every finite value).

    Returns
    -------
    ImageTest or None
        None for fewer than 3 pairs.
    """
    real, sim = np.asarray(real, float), np.asarray(sim, float)
    d = compare_stat(stat, real, sim).ravel()
    d = d[np.isfinite(d)]
    if d.size < 3:
        return None
    median = float(np.median(d))
    pvalue = signed_rank_pvalue(d)
    transform, floor = IMAGE_FLOORS.get(stat, ("diff", None))
    return ImageTest(
        stat=stat,
        compared_as="log2 ratio (stops)" if transform == "log2" else "difference",
        n=int(d.size),
        median_difference=median,
        real_median=float(np.nanmedian(real)),
        sim_median=float(np.nanmedian(sim)),
        floor=floor,
        p_value=pvalue,
        significant=bool(
            floor is not None and pvalue < SIGNIFICANCE_LEVEL and abs(median) >= floor
        ),
    )


def image_tests(real: xr.Dataset, sim: xr.Dataset) -> list[ImageTest]:
    """Paired real - simulated tests of every image statistic (:func:`paired_test`)."""
    if "image_stats" not in real or "image_stats" not in sim:
        return []
    real, sim = align(real, sim)
    visible = real.visible if "variant" not in real.visible.dims else real.visible.isel(variant=0)
    r, s = repeat_median_stats(real).where(visible), repeat_median_stats(sim).where(visible)
    tests = (
        paired_test(stat, r.sel(stat=stat).values, s.sel(stat=stat).values)
        for stat in IMAGE_FLOORS
        if stat in r.stat.values
    )
    return [test for test in tests if test is not None]
