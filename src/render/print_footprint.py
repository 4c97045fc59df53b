"""Exact pixel footprints of a print: the pixel square clipped against its cells.

The converged render multiplies a smooth irradiance by the print's albedo averaged over each
pixel's footprint (:mod:`simgap.render.demodulate`). Under a ``box`` pixel filter, a pinhole and
``nearest`` texture lookup that average has a closed form: the print is a grid of
cells of one albedo each on the sticker's plane; the camera maps each cell to a convex
quadrilateral in the image (a homography), and the share of a pixel that a cell covers is the
area of that quadrilateral clipped to the pixel's square (:mod:`simgap.render.clipping`). The
albedo and the sticker's coverage are then exact, with no rays and none of a point pattern's
quadrature error (1/64 px along an edge at 64 points,
docs/results/converged_render_step8.md#step-3).

A **thin lens** keeps it exact per point of the aperture: the ray from lens point ``L`` through
a print point ``X`` (camera frame) meets the focus plane ``z = focus`` where the pinhole ray of
normalised coordinates ``(X_xy + L (X_z / focus - 1)) / X_z`` does (:meth:`simgap.render.camera`'s
``ray_through``), a homography of the print's plane for each ``L``. A pixel's footprint is then
the mean of the clipped footprints over :data:`LENS_POINTS` fixed points of the aperture disc
(:func:`lens_points`): the pixel's square is integrated exactly and only the aperture with a
quadrature, against the 4-D point pattern's quadrature of both (docs/results/
converged_render_step8.md#step-5).

Two things this geometry does not hold, and how they are handled:

- **Lens distortion** bends a cell's projected sides. A side of ``L`` px at normalised radius
  ``r`` bows by about ``0.75 |k1| r L^2 / f`` px from the straight line between its projected
  corners (the radial term's second derivative): 0.003 px for ``|k1|`` 0.1, ``r`` 0.7, a cell
  of 8 px and ``f`` 1400 px, against 0.016 px for the point pattern. The sides are taken straight.
- **Visibility**: an occluder in front of the sticker is not in the print's geometry.
  :func:`agrees` compares the footprint with the render's own samples on the pixels where
  either saw an edge; an occluder's edge across a sticker makes pixels the geometry calls
  wholly on it whose samples are not, and the caller then integrates the footprint with rays.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from simgap.core import transforms as tf
from simgap.render.clipping import clipped_area
from simgap.render.scene import pose_transforms

if TYPE_CHECKING:
    from simgap.render.scene import FixtureScene

#: A pixel whose exact coverage is within this of 1 (or of 0) is wholly on (off) the sticker:
#: float64 round-off of the clipped areas is about 1e-15 (dimensionless).
WHOLE_TOLERANCE = 1e-9
#: Points of the aperture disc a thin lens's footprint is averaged over (a power of two: the
#: first points of an Owen-scrambled Sobol' sequence, mapped to the disc as Mitsuba maps its
#: aperture samples). Chosen against 1024 points (docs/results/converged_render_step8.md#step-5).
LENS_POINTS = 64
#: Points on the aperture's rim that tell a thin lens's whole and empty pixels (:func:`agrees`):
#: the mean over :data:`LENS_POINTS` calls a pixel whole that a sample through the rim may see
#: partly off (the 64 points reach 0.88-0.98 of the radius).
RIM_POINTS = 16
#: Scrambling seed of :func:`lens_points` (any fixed value: every render seed shares them).
LENS_PATTERN_SEED = 28
#: Largest blur radius (px) of a thin lens whose footprint is clipped: the pixels it is
#: computed on grow with the blur (a band of its radius around every print edge) and each
#: costs :data:`LENS_POINTS` clippings (1.2-3.0 s a configuration of the defocus variant at
#: 1.1-2.0 px, docs/results/converged_render_step8.md#step-5); beyond it the 64 rays decide.
LENS_REACH_MAX_PX = 4.0


def exact_footprint_applies(scene: FixtureScene) -> bool:
    """Whether :func:`print_footprint` holds for posed ``scene`` (box filter, nearest lookup).

    Exact for a pinhole; for a thin lens, up to the aperture's quadrature (:data:`LENS_POINTS`),
    and only while its blur is at most :data:`LENS_REACH_MAX_PX` on every sticker.
    """
    return (
        scene.spec.rfilter["type"] == "box"
        and scene.spec.tag.texture_filter == "nearest"
        and all(defocus_reach_px(scene, tag) <= LENS_REACH_MAX_PX for tag in scene.print_albedo)
    )


def lens_points(scene: FixtureScene) -> NDArray[np.float64]:
    """The aperture points (K, 2) of the footprint, in the lens plane (m; camera frame x, y).

    One point at the centre for a pinhole; else :data:`LENS_POINTS` of a fixed Sobol' pattern on
    the unit square, mapped to the disc by Mitsuba's own concentric warp (as the camera maps its
    aperture samples) and scaled by the aperture's radius.
    """
    radius = scene.lens[0]
    if radius == 0.0:
        return np.zeros((1, 2))
    from scipy.stats import qmc

    mi = scene.mi
    square = qmc.Sobol(d=2, scramble=True, seed=LENS_PATTERN_SEED).random_base2(
        int(LENS_POINTS).bit_length() - 1
    )
    disc = mi.warp.square_to_uniform_disk_concentric(mi.Point2f(square[:, 0], square[:, 1]))
    return radius * np.column_stack([np.asarray(disc.x, np.float64), np.asarray(disc.y)])


def _cv_from_rect(scene: FixtureScene, tag: int) -> NDArray[np.float64]:
    """The transform (4, 4) from sticker ``tag``'s rectangle to the OpenCV camera frame."""
    if scene.pose is None:
        raise RuntimeError("set_pose() must be called before the footprint")
    world = pose_transforms(scene.rig, *scene.pose, scene.errors, scene.tag_scale)
    return np.linalg.inv(world["camera"]) @ world[f"tag_{tag}"]


def cell_corners(scene: FixtureScene, tag: int) -> tuple[NDArray[np.float64], NDArray]:
    """The corners of sticker ``tag``'s print cells in the camera frame, and the cells' albedo.

    Returns
    -------
    points : ndarray (rows + 1, cols + 1, 3)
        The cell grid's corners (m, OpenCV camera frame).
    albedo : ndarray (rows, cols)
        Each cell's print albedo (linear, dimensionless).
    """
    grid = scene.print_albedo[tag]
    rows, cols = grid.shape
    # the rectangle's local x, y in [-1, 1]; texel row 0 at y = +1 (the bitmap's v is flipped,
    # simgap.render.mitsuba_scene.tag_bsdf)
    x = -1.0 + 2.0 * np.arange(cols + 1) / cols
    y = 1.0 - 2.0 * np.arange(rows + 1) / rows
    xx, yy = np.meshgrid(x, y)
    local = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
    points = tf.apply(_cv_from_rect(scene, tag), local)
    return points.reshape(rows + 1, cols + 1, 3), grid


def projected_cells(
    scene: FixtureScene, points: NDArray[np.float64], lens_point: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The print's cells as image quadrilaterals, seen through one point of the aperture.

    Parameters
    ----------
    scene : FixtureScene
        A posed scene (its camera and thin lens).
    points : ndarray (rows + 1, cols + 1, 3)
        The cells' corners in the camera frame (:func:`cell_corners`).
    lens_point : ndarray (2,)
        The point of the thin lens's aperture the print is seen through (m, camera frame x and
        y; the centre for a pinhole): module docstring.

    Returns
    -------
    ndarray (C, 4, 2)
        Full-image pixel coordinates (px; pixel centres at integers) of each cell's corners,
        in order around the cell.
    """
    rows, cols = points.shape[0] - 1, points.shape[1] - 1
    points = points.reshape(-1, 3)
    if np.any(lens_point):  # where the ray through the lens point meets the focus plane
        depth = points[:, 2:]
        points = np.column_stack(
            [points[:, :2] + np.asarray(lens_point) * (depth / scene.lens[1] - 1.0), depth]
        )
    camera = scene.camera_model
    corners = camera.project(points).reshape(rows + 1, cols + 1, 2)
    return np.stack(
        [corners[:-1, :-1], corners[:-1, 1:], corners[1:, 1:], corners[1:, :-1]], axis=2
    ).reshape(-1, 4, 2)


@dataclass(frozen=True)
class ClippedFootprint:
    """Sticker ``tag``'s print over each pixel's square (:func:`print_footprint`).

    Attributes
    ----------
    coverage : ndarray (N,)
        Share of the pixel's footprint on the sticker (0-1; a thin lens: the mean over
        :func:`lens_points`).
    albedo : ndarray (N,)
        The print's mean albedo over that share (NaN where the share is 0).
    least, most : ndarray (N,)
        The least and most coverage the pixel's square has through any point of the aperture
        (the pinhole's: ``coverage``; a thin lens: over :data:`RIM_POINTS` points on its rim,
        where they lie, since the aperture points that see a pixel wholly on a convex sticker
        form a convex set), which :func:`agrees` tells whole and empty pixels by.
    """

    coverage: NDArray[np.float64]
    albedo: NDArray[np.float64]
    least: NDArray[np.float64]
    most: NDArray[np.float64]


def print_footprint(scene: FixtureScene, pixels: NDArray, tag: int) -> ClippedFootprint:
    """Coverage and mean albedo of sticker ``tag`` over each pixel's square (module docstring).

    Parameters
    ----------
    scene : FixtureScene
        A posed scene for which :func:`exact_footprint_applies` (a thin lens: averaged over
        :func:`lens_points`).
    pixels : ndarray of int (N, 2)
        Full-image pixel columns and rows (px), each once.
    tag : int
        The sticker's tag id.
    """
    pixels = np.asarray(pixels).reshape(-1, 2).astype(np.int64)
    n = len(pixels)
    points, grid = cell_corners(scene, tag)
    albedo = grid.ravel().astype(np.float64)
    index = _PixelIndex.of(pixels)

    def clipped(lens_point: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Through one aperture point: each pixel's area on the sticker, and times albedo."""
        quads = projected_cells(scene, points, lens_point)
        cell, pixel = index.pairs(quads)
        area = clipped_area(quads[cell] - (pixels[pixel] - 0.5)[:, None, :])
        return (
            np.bincount(pixel, area, minlength=n),
            np.bincount(pixel, area * albedo[cell], minlength=n),
        )

    coverage, weighted = np.zeros(n), np.zeros(n)
    lens = lens_points(scene)
    for point in lens:
        share, shaded = clipped(point)
        coverage += share
        weighted += shaded
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(coverage > 0, weighted / coverage, np.nan)
    coverage = np.minimum(coverage / len(lens), 1.0)
    if scene.lens[0] == 0.0:
        return ClippedFootprint(coverage, mean, coverage, coverage)
    rim = np.stack([clipped(point)[0] for point in rim_points(scene)])
    return ClippedFootprint(coverage, mean, np.minimum(rim.min(axis=0), 1.0), rim.max(axis=0))


def rim_points(scene: FixtureScene) -> NDArray[np.float64]:
    """:data:`RIM_POINTS` points evenly spaced on the aperture's rim (m; camera frame x, y).

    Their polygon misses the disc by at most ``1 - cos(pi / RIM_POINTS)`` of its radius (2 %).
    """
    angle = 2.0 * np.pi * (np.arange(RIM_POINTS) + 0.5) / RIM_POINTS
    return scene.lens[0] * np.column_stack([np.cos(angle), np.sin(angle)])


def defocus_reach_px(scene: FixtureScene, tag: int) -> float:
    """Radius of the thin lens's blur disc on sticker ``tag`` at its widest (px; 0: pinhole).

    A point at depth ``z`` is spread over a disc of radius ``f r |1 / focus - 1 / z|`` (focal
    length ``f`` in px, aperture radius ``r``), taken at the sticker's corners (a plane's
    extreme depths are at its corners).
    """
    radius, focus = scene.lens
    if radius == 0.0:
        return 0.0
    corners = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    depth = tf.apply(_cv_from_rect(scene, tag), corners)[:, 2]
    f = max(scene.camera_model.fx, scene.camera_model.fy)
    return float(f * radius * np.max(np.abs(1.0 / focus - 1.0 / depth)))


@dataclass(frozen=True)
class _PixelIndex:
    """The pixels asked for on their bounding grid: where each one is in the list (-1: none)."""

    lo: NDArray
    shape: NDArray
    index: NDArray

    @classmethod
    def of(cls, pixels: NDArray) -> _PixelIndex:
        """The index of full-image pixels (N, 2), each once."""
        lo = pixels.min(axis=0)
        shape = pixels.max(axis=0) - lo + 1
        index = np.full((shape[1], shape[0]), -1, np.int64)
        index[pixels[:, 1] - lo[1], pixels[:, 0] - lo[0]] = np.arange(len(pixels))
        return cls(lo, shape, index)

    def pairs(self, quads: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Every (cell, pixel) pair whose bounding boxes overlap, among the pixels indexed."""
        lo, shape = self.lo, self.shape
        # pixel u spans [u - 0.5, u + 0.5): the pixels a cell's bounding box touches
        first = np.floor(quads.min(axis=1) + 0.5).astype(np.int64) - lo
        last = np.floor(quads.max(axis=1) + 0.5).astype(np.int64) - lo
        first, last = np.maximum(first, 0), np.minimum(last, shape - 1)
        width, height = np.maximum(last - first + 1, 0).T
        count = width * height
        cell = np.repeat(np.arange(len(quads)), count)
        k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        step = np.repeat(np.maximum(width, 1), count)
        pixel = self.index[first[cell, 1] + k // step, first[cell, 0] + k % step]
        keep = pixel >= 0
        return cell[keep], pixel[keep]


def agrees(
    footprint: ClippedFootprint,
    sample_sticker: NDArray,
    sample_coverage: NDArray[np.float64],
    tag: int,
) -> bool:
    """Whether the render's samples see sticker ``tag`` where its geometry puts it.

    Over the same pixels: a pixel wholly on the sticker through every point of the aperture
    (``footprint.least`` 1) must have all its samples on it, and a pixel wholly off through
    every point (``footprint.most`` 0) none (its samples' sticker is another). An occluder, or a
    geometry the renderer does not share, fails this.
    """
    whole = footprint.least >= 1.0 - WHOLE_TOLERANCE
    none = footprint.most <= WHOLE_TOLERANCE
    seen = sample_sticker == tag
    return bool(np.all(seen[whole] & (sample_coverage[whole] >= 1.0)) and not np.any(seen[none]))
