"""Reports of result datasets: the paper-style report, variant comparison and error-model bands.

The paper-style report of one result dataset: figures, Table 2 beside the paper's, and a summary.
The entry point is :func:`write_report`. It validates the dataset against the result-dataset
contract (docs/conventions.md §3), reduces the first variant to a
:class:`~simgap.analysis.report._summaries.VariantSummary` (absolute and signed errors averaged over
repeats, restricted to visible configurations) and writes, atomically:

========================================  ======================================================
file                                      content
========================================  ======================================================
``error_vs_distance_tag{t}.png``          2x3 panels, absolute error (m or rad) against carriage
                                          position (m), one line per turntable angle, threshold
                                          line, visible-but-undetected configurations as ``x``
``heatmap_tag{t}.png``                    2x3 panels, signed error over (theta, p), diverging
                                          colours centred on 0, grey where there is no estimate
``table2.md``                             our max/min absolute error beside the paper's Table 2,
                                          fraction within threshold, detection rate per tag
``summary.md``                            counts, fractions within thresholds, observations
                                          computed from the data, embedded figures
========================================  ======================================================

The package holds one job a module, composed here and by the variant comparison
(:mod:`~simgap.analysis.report._compare`, :func:`write_comparison`):
:mod:`~simgap.analysis.report._summaries` (reductions, the dataset's rig),
:mod:`~simgap.analysis.report._comparisons` (paired variant comparison),
:mod:`~simgap.analysis.report._tables`, :mod:`~simgap.analysis.report._figures` (with
:mod:`~simgap.analysis.report._heatmaps`), :mod:`~simgap.analysis.report._markdown` and
:mod:`~simgap.analysis.report._output` (atomic files); :mod:`~simgap.analysis.report._sun` the
sun-direction section (:func:`write_sun_report`),
:mod:`~simgap.analysis.report._errormodel_bands` an error model's 90 % bands over the data it
describes (:func:`write_error_model_bands`) and :mod:`~simgap.analysis.report._photos` the
report of a board's photo set (:func:`write_photo_report`). The modules are private; other
packages import the names of ``__all__`` from here.

Examples
--------
>>> import xarray as xr
>>> from pathlib import Path
>>> from simgap.analysis.report import write_report
>>> paths = write_report(xr.open_dataset("results/baseline.nc"), Path("rep"))  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import xarray as xr

from simgap.analysis.gap import plot_image_stats
from simgap.analysis.report._compare import write_comparison
from simgap.analysis.report._comparisons import (
    change_by_p,
    compare_variants,
    resolve_baseline,
    rig_facing_theta_rad,
    variant_names,
)
from simgap.analysis.report._errormodel_bands import plot_error_model_bands, write_error_model_bands
from simgap.analysis.report._figures import (
    plot_axis_change_heatmap,
    plot_change_by_distance,
    plot_change_heatmap,
    plot_comparison_heatmap,
    plot_error_heatmap,
    plot_error_vs_distance,
)
from simgap.analysis.report._heatmaps import (
    mark_beyond_limit,
    robust_colour_limit,
    row_distance_labels,
    sampled_axis,
)
from simgap.analysis.report._markdown import summary_markdown, table2_markdown
from simgap.analysis.report._output import save_figure, save_text
from simgap.analysis.report._photos import (
    PHOTO_ERRORS_FIGURE,
    PHOTO_GAP_FIGURE,
    PHOTO_REPORT,
    dataset_board,
    dataset_calibration_check,
    is_photo_dataset,
    plot_photo_errors,
    plot_photo_gap,
    write_photo_report,
)
from simgap.analysis.report._summaries import (
    VariantSummary,
    check_report_dataset,
    dataset_distance_m,
    dataset_rig,
    fit_abs_error_slope,
    summarize_variant,
)
from simgap.analysis.report._sun import envelope_rows, summarize_sun, worst_directions
from simgap.analysis.report._tables import (
    binned_change_table,
    markdown_table,
    moves_most,
    variant_summary_table,
)
from simgap.core.progress import ProgressCallback, Steps

__all__ = [
    "PHOTO_ERRORS_FIGURE",
    "PHOTO_GAP_FIGURE",
    "PHOTO_REPORT",
    "VariantSummary",
    "binned_change_table",
    "change_by_p",
    "compare_variants",
    "dataset_board",
    "dataset_calibration_check",
    "dataset_distance_m",
    "dataset_rig",
    "envelope_rows",
    "fit_abs_error_slope",
    "is_photo_dataset",
    "mark_beyond_limit",
    "markdown_table",
    "moves_most",
    "plot_axis_change_heatmap",
    "plot_change_by_distance",
    "plot_change_heatmap",
    "plot_comparison_heatmap",
    "plot_error_heatmap",
    "plot_error_model_bands",
    "plot_error_vs_distance",
    "plot_photo_errors",
    "plot_photo_gap",
    "resolve_baseline",
    "rig_facing_theta_rad",
    "robust_colour_limit",
    "row_distance_labels",
    "sampled_axis",
    "save_figure",
    "save_text",
    "summarize_sun",
    "summarize_variant",
    "variant_names",
    "variant_summary_table",
    "worst_directions",
    "write_comparison",
    "write_error_model_bands",
    "write_photo_report",
    "write_report",
    "write_sun_report",
    "write_variant_report",
]

#: Writes one figure; module-level so that tests can replace PNG encoding with a placeholder.
_save_figure = save_figure


def write_variant_report(
    summary: VariantSummary,
    out_dir: Path,
    variants: Sequence[str] = (),
    image_datasets: dict[str, xr.Dataset] | None = None,
    progress: ProgressCallback | None = None,
) -> list[Path]:
    """Write the figures, ``table2.md`` and ``summary.md`` of one variant.

    Parameters
    ----------
    summary : VariantSummary
        Output of :func:`~simgap.analysis.report.summarize_variant`.
    out_dir : pathlib.Path
        Existing output folder.
    variants : sequence of str, optional
        All variants of the dataset, named in the summary when some are not reported.
    image_datasets : dict of str to xarray.Dataset, optional
        Datasets with ``image_stats`` to plot against distance and view angle.
    progress : ProgressCallback, optional
        Told of each figure written (step ``"figures"``).

    Returns
    -------
    list of pathlib.Path
        Written files: per tag ``error_vs_distance_tag{t}.png``, then per tag
        ``heatmap_tag{t}.png``, then ``image_stats_vs_{distance,view_angle}.png`` when the
        dataset has image statistics, then ``table2.md`` and ``summary.md``.
    """
    plotters = (("error_vs_distance", plot_error_vs_distance), ("heatmap", plot_error_heatmap))
    against = ("distance", "view_angle") if image_datasets else ()
    steps = Steps(progress)
    steps.start("figures", len(plotters) * len(summary.tags) + len(against))
    figures = []
    for stem, plot in plotters:
        for tag in summary.tags:
            figures.append(_save_figure(plot(summary, tag), out_dir / f"{stem}_tag{tag}.png"))
            steps.advance()
    for axis in against:
        fig = plot_image_stats(image_datasets or {}, axis)  # against is () without them
        figures.append(_save_figure(fig, out_dir / f"image_stats_vs_{axis}.png"))
        steps.advance()
    table = save_text(table2_markdown(summary), out_dir / "table2.md")
    text = save_text(summary_markdown(summary, figures, variants), out_dir / "summary.md")
    return [*figures, table, text]


def write_report(
    ds: xr.Dataset,
    out_dir: Path,
    *,
    pin_pitch_m: float | None = None,
    progress: ProgressCallback | None = None,
) -> list[Path]:
    """Write the paper-style report of a result dataset.

    Parameters
    ----------
    ds : xarray.Dataset
        Result dataset following docs/conventions.md §3. Only the first variant
        (``ds.variant[0]``) is reported; errors are averaged over ``repeat`` with NaN skipped.
    out_dir : pathlib.Path
        Output folder, created if needed; files in it are replaced atomically.
    pin_pitch_m : float, optional
        Carriage pin-hole pitch in metres (x axis of the error-vs-distance figures and the slope
        fit use carriage position ``pin_pitch_m * p``); default: the pitch of the dataset's rig
        (:func:`~simgap.analysis.report.dataset_rig`).
    progress : ProgressCallback, optional
        Told of each figure written (:func:`write_variant_report`).

    Returns
    -------
    list of pathlib.Path
        The written files (see :func:`write_variant_report`).

    Raises
    ------
    ValueError
        If required variables or coordinates are missing (all are named), or dims are wrong.
    """
    check_report_dataset(ds)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    variants = [str(v) for v in ds["variant"].values]
    summary = summarize_variant(ds.isel(variant=0), pin_pitch_m=pin_pitch_m)
    images = {variants[0]: ds.isel(variant=[0])} if "image_stats" in ds else None
    return write_variant_report(summary, out_dir, variants, images, progress)


def write_sun_report(
    ds: xr.Dataset, out_dir: Path, cache_dir: Path | None = None
) -> list[Path]:
    """Write the sun-direction section of a sweep over the sun (nothing for other datasets).

    ``sun_polar.png`` (:func:`~simgap.analysis.report._sun.plot_sun_polar`),
    ``sun_worst_frames.png`` (the worst directions' frames, from the pipeline's cache in
    ``cache_dir``, default the user's) and ``sun.md``.
    """
    from simgap.analysis.report import _sun as sun
    from simgap.core.paths import default_cache_dir

    sweep = sun.summarize_sun(ds)
    if sweep is None:
        return []
    out_dir = Path(out_dir)
    title = str(ds.attrs.get("experiment", "result"))
    paths = [_save_figure(sun.plot_sun_polar(sweep, title), out_dir / "sun_polar.png")]
    frames = sun.worst_frames(ds, sweep, cache_dir or default_cache_dir())
    fig = sun.plot_frames(frames, f"{title}: the worst sun directions")
    paths.append(_save_figure(fig, out_dir / "sun_worst_frames.png"))
    text = sun.sun_markdown(ds, sweep, [p.name for p in paths], sun.envelope_rows(ds, sweep))
    return [*paths, save_text(text, out_dir / "sun.md")]
