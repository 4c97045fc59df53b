"""Where the gap lies beyond the pose means: pose scatter, detection rate and image evidence.

Three families of tests compare a real dataset with its simulation (aligned configurations):

scatter
    Per axis, over all configurations and per distance region, the spread of the pose error
    around its smooth course. With
    repeats, the deviations of each repeat from its configuration's mean; otherwise the residual
    of each value from the straight line through its two neighbours along the carriage (exact
    for any linear trend, also for unevenly spaced pin holes), scaled to unit noise. Real and
    simulated residuals are compared with the Brown-Forsythe test (``scipy.stats.levene`` with
    ``center="median"``). Significant when the test rejects at :data:`ALPHA` (Bonferroni over the
    tests), the robust scales differ by :data:`SCATTER_RATIO` or more, and the extra scatter
    ``sqrt(|real^2 - sim^2|)`` reaches :data:`SCATTER_FLOOR_SHARE` of the practical floor.
detection
    Detected / visible counts of the real data and of the simulation (over repeats), overall,
    per distance region and per view-angle band; Boschloo's exact test of the 2 x 2 table
    (:func:`detection_pvalue`). The overall test is the one planned test, at :data:`ALPHA`; the
    six regional tests are corrected for their multiplicity by Holm's step-down rule at
    :data:`ALPHA` (:func:`holm_reject`). Significant when the test rejects and the rates differ
    by :data:`DETECTION_MIN_DIFFERENCE` or more. A fifth of 45 detections lost overall (36 / 45
    against 45 / 45: p = 0.00098) and half of one 15-configuration region (7 / 15 against
    15 / 15: p = 0.00082 < 0.01 / 6) are significant; with Fisher's test and Bonferroni over
    all seven (p 0.0025 against 0.0014) the first was not.
image
    Per statistic of :mod:`simgap.pose.image_stats`, the paired difference real - simulated over
    tags visible in both (levels and noise as log2 ratios, in stops); Wilcoxon's signed-rank test
    (``scipy.stats.wilcoxon``). Significant when it rejects at :data:`ALPHA` and the median
    difference reaches the statistic's practical floor (:data:`IMAGE_FLOORS`).

Every threshold here was fixed before the blind validation runs that report on it.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import xarray as xr
from scipy import stats as sps

from simgap.analysis.gap import PRACTICAL_FLOOR, align
from simgap.analysis.image_evidence import repeat_median_stats, tag_distance_and_view_angle
from simgap.core.axes import AXES, axis_unit
from simgap.core.robust import mad_sigma, signed_rank_pvalue

#: Family-wise false-alarm rate of each family of tests.
ALPHA = 0.01
#: Smallest ratio of robust scatter (real / simulated, or its inverse) that matters.
SCATTER_RATIO = 1.5
#: The extra scatter must reach this share of the practical floor (0.5 mm / 8.7 mrad).
SCATTER_FLOOR_SHARE = 0.5
#: Smallest difference of detection rates that matters.
DETECTION_MIN_DIFFERENCE = 0.05
#: Largest number of attempts (the smaller side of a 2 x 2 table) for which Boschloo's test is
#: run; beyond it Fisher's, whose power is then the same and which is far cheaper (Boschloo on
#: 540 x 2160 attempts: 7.6 s, measured).
BOSCHLOO_MAX_ATTEMPTS = 200
#: View-angle bands (deg) for the detection tests: oblique, intermediate, frontal.
VIEW_BANDS_DEG = ((0.0, 35.0), (35.0, 60.0), (60.0, 90.1))
#: Added to linear levels before taking log2 ratios (a tenth of an 8-bit step near black).
LEVEL_EPSILON = 0.002

#: ``stat -> (transform, floor)``: compared as a difference ("diff") or a log2 ratio ("log2",
#: stops), and the smallest median difference that matters. ``None`` floors are reported only.
IMAGE_FLOORS: dict[str, tuple[str, float | None]] = {
    "ink_linear": ("log2", 0.5),
    "paper_linear": ("log2", 0.3),
    "contrast": ("diff", 0.05),
    "edge_width_px": ("diff", None),
    "edge_width_x_px": ("diff", 0.2),
    "edge_width_y_px": ("diff", 0.2),
    "noise_ink_linear": ("log2", 0.5),
    "noise_paper_linear": ("log2", 0.5),
    "clipped_fraction": ("diff", 0.02),
    "highlight_fraction": ("diff", 0.02),
    "rejected_candidates": ("diff", None),
    "blockiness": ("log2", 0.25),
}


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
    """Pose noise samples per configuration (repeat or neighbour residuals), see module docstring.

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


def scatter_tests(real: xr.Dataset, sim: xr.Dataset) -> list[dict[str, Any]]:
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
                pvalue < ALPHA / n_tests
                and (ratio >= SCATTER_RATIO or ratio <= 1 / SCATTER_RATIO)
                and extra >= SCATTER_FLOOR_SHARE * PRACTICAL_FLOOR[unit]
            )
            rows.append(
                {
                    "axis": axis,
                    "region": name,
                    "unit": unit,
                    "n_real": int(a.size),
                    "n_sim": int(b.size),
                    "real_scatter": sa,
                    "sim_scatter": sb,
                    "ratio": float(ratio),
                    "extra_scatter": extra,
                    "p_value": pvalue,
                    "significant": bool(significant),
                }
            )
    return rows


def detection_pvalue(kr: int, nr: int, ks: int, ns: int) -> float:
    """Two-sided p-value that real and simulated detection rates are equal.

    ``kr`` of ``nr`` real attempts detected, ``ks`` of ``ns`` simulated. Boschloo's exact test
    (``scipy.stats.boschloo_exact``), uniformly more powerful than Fisher's for a 2 x 2 table
    with fixed attempts; Fisher's beyond :data:`BOSCHLOO_MAX_ATTEMPTS` attempts, where both
    have the same power.
    """
    table = [[kr, nr - kr], [ks, ns - ks]]
    if kr + ks in (0, nr + ns):  # every attempt detected (or none) on both sides: no evidence
        return 1.0
    if min(nr, ns) > BOSCHLOO_MAX_ATTEMPTS:
        return float(sps.fisher_exact(table).pvalue)
    return float(min(sps.boschloo_exact(table).pvalue, 1.0))


def holm_reject(pvalues: list[float], alpha: float = ALPHA) -> list[bool]:
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


def detection_tests(real: xr.Dataset, sim: xr.Dataset) -> list[dict[str, Any]]:
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
        rows.append(
            {
                "region": name,
                "real_detected": kr,
                "real_attempts": nr,
                "sim_detected": ks,
                "sim_attempts": ns,
                "real_rate": kr / nr,
                "sim_rate": ks / ns,
                "difference": kr / nr - ks / ns,
                "p_value": detection_pvalue(kr, nr, ks, ns),
            }
        )
    regional = [r for r in rows if r["region"] != "all"]
    rejected = holm_reject([r["p_value"] for r in regional])
    for row in rows:
        reject = row["p_value"] < ALPHA if row["region"] == "all" else rejected[regional.index(row)]
        row["test"] = "planned" if row["region"] == "all" else "Holm over regions"
        row["significant"] = bool(reject and abs(row["difference"]) >= DETECTION_MIN_DIFFERENCE)
    return rows


def compare_stat(stat: str, real: np.ndarray, sim: np.ndarray) -> np.ndarray:
    """Per-tag difference real - simulated of one statistic in its comparison units."""
    transform, _ = IMAGE_FLOORS.get(stat, ("diff", None))
    if transform == "log2":
        return np.log2((real + LEVEL_EPSILON) / (sim + LEVEL_EPSILON))
    return real - sim


def paired_test(stat: str, real: np.ndarray, sim: np.ndarray) -> dict[str, Any] | None:
    """Wilcoxon signed-rank test of the paired difference real - simulated of one statistic.

    Parameters
    ----------
    stat : str
        Statistic name (:data:`IMAGE_FLOORS`), which sets the comparison units.
    real, sim : ndarray
        The statistic on the same tags, real and simulated; pairs with a NaN are left out.

    Returns
    -------
    dict or None
        ``n``, ``median_difference`` (comparison units), ``p_value`` and ``significant`` (rejects
        at :data:`ALPHA` and the median reaches the statistic's floor; never for a statistic
        without a floor); None for fewer than 3 pairs.
    """
    d = compare_stat(stat, np.asarray(real, float), np.asarray(sim, float)).ravel()
    d = d[np.isfinite(d)]
    if d.size < 3:
        return None
    median = float(np.median(d))
    pvalue = signed_rank_pvalue(d)
    floor = IMAGE_FLOORS.get(stat, ("diff", None))[1]
    return {
        "n": int(d.size),
        "median_difference": median,
        "p_value": pvalue,
        "significant": bool(floor is not None and pvalue < ALPHA and abs(median) >= floor),
    }


def image_tests(real: xr.Dataset, sim: xr.Dataset) -> list[dict[str, Any]]:
    """Paired real - simulated tests of every image statistic (:func:`paired_test`)."""
    if "image_stats" not in real or "image_stats" not in sim:
        return []
    real, sim = align(real, sim)
    visible = real.visible if "variant" not in real.visible.dims else real.visible.isel(variant=0)
    r, s = repeat_median_stats(real).where(visible), repeat_median_stats(sim).where(visible)
    rows = []
    for stat, (transform, floor) in IMAGE_FLOORS.items():
        if stat not in r.stat.values:
            continue
        test = paired_test(stat, r.sel(stat=stat).values, s.sel(stat=stat).values)
        if test is None:
            continue
        rows.append(
            {
                "stat": stat,
                "compared_as": "log2 ratio (stops)" if transform == "log2" else "difference",
                "n": test["n"],
                "median_difference": test["median_difference"],
                "real_median": float(np.nanmedian(r.sel(stat=stat).values)),
                "sim_median": float(np.nanmedian(s.sel(stat=stat).values)),
                "floor": floor,
                "p_value": test["p_value"],
                "significant": test["significant"],
            }
        )
    return rows

