"""Convex quadrilaterals clipped to the unit square: a pixel's share of a projected print cell.

The exact print footprint (:mod:`simgap.render.print_footprint`) shifts each cell's projected
quadrilateral by its pixel's corner and asks for the area inside [0, 1]^2, for millions of
cell-pixel pairs a thin-lens render (one clipping per aperture point). Sutherland-Hodgman against
the square's four sides, vectorised over the pairs; the two cheap cases first (a quadrilateral
inside the square, one that holds it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Most vertices of a convex quadrilateral clipped by the four sides of a square (4 + 4).
CLIPPED_VERTICES = 8


def clipped_area(quads: NDArray[np.float64]) -> NDArray[np.float64]:
    """Area of each convex quadrilateral (M, 4, 2) inside the unit square [0, 1]^2.

    Sutherland-Hodgman against the square's four sides, vectorised: each polygon keeps
    :data:`CLIPPED_VERTICES` vertices, repeating its last one where it has fewer (a repeated
    vertex adds an edge of length zero, which the area does not see and the next clip skips).
    """
    quads = np.asarray(quads, np.float64)
    area = np.empty(len(quads))
    # most pairs need no clipping: a quadrilateral inside the square, or one that holds it
    inside = np.all((quads >= 0.0) & (quads <= 1.0), axis=(1, 2))
    area[inside] = _shoelace(quads[inside])
    holds = ~inside & _holds_unit_square(quads)
    area[holds] = 1.0
    rest = ~inside & ~holds
    polygon = quads[rest]
    for axis, bound, below in ((0, 0.0, False), (0, 1.0, True), (1, 0.0, False), (1, 1.0, True)):
        polygon = _clip(polygon, axis, bound, below)
    area[rest] = _shoelace(polygon)
    return area


def _following(values: NDArray) -> NDArray:
    """Each polygon's next vertex (or value) along axis 1, the last one's being the first.

    ``np.roll(values, -1, axis=1)`` without its concatenation (the same values).
    """
    out = np.empty_like(values)
    out[:, :-1] = values[:, 1:]
    out[:, -1] = values[:, 0]
    return out


def _shoelace(polygon: NDArray[np.float64]) -> NDArray[np.float64]:
    """Area of polygons (M, K, 2) from their vertices in order (either way round)."""
    x, y = polygon[..., 0], polygon[..., 1]
    twice = np.sum(x * _following(y) - _following(x) * y, axis=1)
    return 0.5 * np.abs(twice)


def _holds_unit_square(quads: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether each convex quadrilateral (M, 4, 2) holds all four corners of [0, 1]^2.

    Every corner must lie on the inner side of every edge (that of the quadrilateral's own
    turn): the cross product ``e_x (c_y - q_y) - e_y (c_x - q_x)`` of edge ``e`` from vertex ``q``
    to corner ``c`` has the turn's sign at all four corners. The corners' coordinates are 0 or 1
    independently, so its least and greatest over them are the least and greatest of each term
    (a rounded difference grows with its first operand and falls with its second, so these are
    the very values the four products give).
    """
    edge = _following(quads) - quads  # (M, 4, 2)
    ex, ey = edge[..., 0], edge[..., 1]
    a0, a1 = ex * (0.0 - quads[..., 1]), ex * (1.0 - quads[..., 1])
    b0, b1 = ey * (0.0 - quads[..., 0]), ey * (1.0 - quads[..., 0])
    least = np.minimum(a0, a1) - np.maximum(b0, b1)
    most = np.maximum(a0, a1) - np.minimum(b0, b1)
    turning = _following(edge)
    turn = np.sign(np.sum(ex * turning[..., 1], axis=1) - np.sum(ey * turning[..., 0], axis=1))
    left = np.all(least >= 0.0, axis=1)
    right = np.all(most <= 0.0, axis=1)
    return np.where(turn > 0, left, right) & (turn != 0)


def _clip(polygon: NDArray[np.float64], axis: int, bound: float, below: bool) -> NDArray:
    """Clip polygons (M, K, 2) to the half-plane ``coordinate <= bound`` (``below``) or ``>=``."""
    m, k, _ = polygon.shape
    side = polygon[..., axis] - bound
    if not below:
        side = -side
    inside = side <= 0
    following = _following(polygon)
    side_next = _following(side)
    # strictly: an edge that only touches the line emits its start (or its end, next), not both
    crosses = side * side_next < 0
    t = side / np.where(crosses, side - side_next, 1.0)
    crossing = polygon + t[..., None] * (following - polygon)
    # each edge emits its start where it is inside and the crossing where it leaves or enters;
    # an edge of length zero (a repeated vertex) emits nothing: the next edge emits its start
    moves = (polygon[..., 0] != following[..., 0]) | (polygon[..., 1] != following[..., 1])
    points = np.empty((m, k, 2, 2))
    points[:, :, 0], points[:, :, 1] = polygon, crossing
    valid = np.empty((m, k, 2), bool)
    valid[:, :, 0], valid[:, :, 1] = inside & moves, crosses
    points, valid = points.reshape(m, 2 * k, 2), valid.reshape(m, 2 * k)
    position = np.cumsum(valid, axis=1)
    count = position[:, -1]
    if np.any(count > CLIPPED_VERTICES):
        raise ValueError("clipped_area: expected convex quadrilaterals")
    # the emitted points in order, then the last one repeated; an empty polygon is all zeros
    clipped = np.zeros((m, CLIPPED_VERTICES, 2))
    row, col = np.nonzero(valid)
    clipped[row, position[row, col] - 1] = points[row, col]
    last = np.maximum(count - 1, 0)
    beyond = np.arange(CLIPPED_VERTICES)[None, :] > last[:, None]
    clipped[beyond] = np.repeat(clipped[np.arange(m), last], CLIPPED_VERTICES - 1 - last, axis=0)
    return clipped
