"""Compare the variants of a result dataset (rendering/estimation options) with a reference variant.

The reference is the variant named ``baseline`` (or the first), unless another is named; every
other variant is compared with it over *paired* items (both have an estimate of every
axis), with the spread over repeats as the noise level
(:mod:`simgap.analysis.report._comparisons` says how).

:func:`compare_variants` returns all of this as one :class:`xarray.Dataset` in SI units (m, rad);
the tables (:func:`variant_summary_table`, :func:`binned_change_table`) convert to mm and mrad. The
entry point :func:`write_comparison` writes, atomically:

==================================  ==============================================================
file                                content
==================================  ==============================================================
``comparison.md``                   per variant and axis: mean and max ``|error|`` of variant and
                                    reference, change of mean ``|error|``, mean signed shift,
                                    noise, detection rates, change by distance and view angle,
                                    and which axis each variant moves most
``change_by_distance.png``          2x3 panels: change of mean ``|error|`` against p, one line
                                    per variant
``change_heatmap_<variant>.png``    per variant, two rows of 2x3 panels per tag: mean signed
                                    error change over (view angle, p)
==================================  ==============================================================

This module is the entry point; the work is done by :mod:`simgap.analysis.report`'s
:mod:`~simgap.analysis.report._comparisons`, :mod:`~simgap.analysis.report._tables`,
:mod:`~simgap.analysis.report._figures` and :mod:`~simgap.analysis.report._markdown`, whose public
comparison API is re-exported here and, for notebooks, by :mod:`simgap.analysis.report`.

Examples
--------
>>> from pathlib import Path
>>> from simgap.results.dataset import read_netcdf
>>> from simgap.analysis.report import compare_variants, variant_summary_table, write_comparison
>>> ds = read_netcdf("results/variants.nc")  # doctest: +SKIP
>>> variant_summary_table(compare_variants(ds))  # doctest: +SKIP
>>> write_comparison(ds, Path("cmp"))  # doctest: +SKIP
"""

from __future__ import annotations

import re
from pathlib import Path

import xarray as xr

from simgap.analysis.report._comparisons import (
    REFERENCE_NAME,
    change_by_p,
    compare_variants,
    resolve_baseline,
    rig_facing_theta_rad,
    variant_names,
    view_angle_deg,
)
from simgap.analysis.report._figures import (
    plot_axis_change_heatmap,
    plot_change_by_distance,
    plot_change_heatmap,
)
from simgap.analysis.report._markdown import comparison_markdown
from simgap.analysis.report._output import save_figure, save_text
from simgap.analysis.report._tables import (
    ANGLE_BINS_DEG,
    binned_change_table,
    moves_most,
    variant_summary_table,
)
from simgap.core.progress import ProgressCallback, Steps

__all__ = [
    "ANGLE_BINS_DEG",
    "REFERENCE_NAME",
    "binned_change_table",
    "change_by_p",
    "compare_variants",
    "comparison_markdown",
    "heatmap_filename",
    "moves_most",
    "plot_axis_change_heatmap",
    "plot_change_by_distance",
    "plot_change_heatmap",
    "resolve_baseline",
    "rig_facing_theta_rad",
    "variant_names",
    "variant_summary_table",
    "view_angle_deg",
    "write_comparison",
]


def heatmap_filename(variant: str) -> str:
    """File name of a variant's heatmap: ``change_heatmap_<variant>.png``, unsafe chars as ``_``."""
    return f"change_heatmap_{re.sub(r'[^A-Za-z0-9_.-]', '_', variant)}.png"


def write_comparison(
    ds: xr.Dataset,
    out_dir: Path,
    baseline: str | None = None,
    progress: ProgressCallback | None = None,
) -> list[Path]:
    """Write the comparison of a multi-variant result dataset with its reference variant.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset (docs/conventions.md §3) with at least two variants.
    out_dir : pathlib.Path
        Output folder, created if needed; files in it are replaced atomically.
    baseline : str, optional
        Reference variant; default ``"baseline"`` if present, else the first variant.
    progress : ProgressCallback, optional
        Told of each figure written (step ``"comparison figures"``).

    Returns
    -------
    list of pathlib.Path
        ``change_by_distance.png``, ``change_heatmap_<variant>.png`` per compared variant, then
        ``comparison.md``.

    Raises
    ------
    ValueError
        If the dataset has fewer than two variants ("needs at least two variants; dataset has:
        [...]"), `baseline` is not a variant (the variants are listed), or required variables
        are missing.
    """
    cmp = compare_variants(ds, baseline)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    variants = [str(v) for v in cmp["variant"].values]
    steps = Steps(progress)
    steps.start("comparison figures", 1 + len(variants))
    figures = [save_figure(plot_change_by_distance(cmp), out_dir / "change_by_distance.png")]
    steps.advance()
    for variant in variants:
        figures.append(
            save_figure(plot_change_heatmap(cmp, variant), out_dir / heatmap_filename(variant))
        )
        steps.advance()
    text = save_text(comparison_markdown(cmp, figures), out_dir / "comparison.md")
    return [*figures, text]
