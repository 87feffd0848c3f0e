# Copyright 2026 The pytest-metamorphic Authors
# Derived from Apollo (https://github.com/ApolloAuto/apollo), Copyright 2017-2018 The Apollo
# Authors, licensed under the Apache License, Version 2.0.
# What it derives from: MinBoxObjectBuilder::ComputePolygon2dxy (min_box.cc).
# Changed: re-implemented in Python and NumPy, with the differences stated in the docstring
# of pytest_metamorphic.lidar.systems.perception.minbox. See NOTICE.
# SPDX-License-Identifier: Apache-2.0
"""MinBox's polygon: the clockwise convex hull of a cluster's points (``ComputePolygon2dxy``),
after vectorised prunes of each cluster's interior (an octagon of extreme points, qhull for
large clusters), so that the exact hull's Python work depends on the hull's size."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

HullStart = Literal["apollo", "nearest"]
_QHULL_FROM = 64  # clusters with more points are pruned with qhull before the hull
_QHULL_MARGIN = 1e-6  # metres; qhull's rounding is below 1e-12 at LiDAR ranges


def hull_candidates(
    xy: NDArray[np.float64], sizes: NDArray[np.intp], starts: NDArray[np.intp]
) -> list[list[tuple[float, float]]]:
    """Per cluster, the points that may be hull vertices (others are strictly inside).

    ``xy`` holds the clusters contiguously (cluster ``c`` is rows ``starts[c]`` to
    ``starts[c] + sizes[c]``). Two prunings, both vectorised, drop only points strictly
    inside the hull by more than ``_QHULL_MARGIN`` metres (far above float64 rounding),
    so every true hull vertex survives: the Akl-Toussaint octagon of every cluster's
    extreme points in eight directions, then, for clusters still larger than
    ``_QHULL_FROM`` points, qhull's hull. They only prune; the hull itself is always the
    exact monotone chain over what is left, so the result cannot depend on them or on
    the point order.
    """
    keep = ~_inside_octagon(xy, sizes, starts)
    kept = np.compress(keep, xy, axis=0)  # still contiguous by cluster
    ends = np.cumsum(np.add.reduceat(keep.astype(np.intp), starts))
    # One conversion to Python tuples for all clusters, sliced per cluster.
    points = _tuples(kept)
    result = []
    begin = 0
    for end in ends.tolist():
        if end - begin > _QHULL_FROM:
            chunk = kept[begin:end]
            result.append(_tuples(chunk[~_inside_qhull(chunk)]))
        else:
            result.append(points[begin:end])
        begin = end
    return result


def _tuples(xy: NDArray[np.float64]) -> list[tuple[float, float]]:
    """The rows of ``xy`` as (x, y) tuples (zip of two columns: 1.7x faster than tuples of
    ``tolist``'s rows)."""
    return list(zip(xy[:, 0].tolist(), xy[:, 1].tolist(), strict=True))


def _inside_octagon(
    xy: NDArray[np.float64], sizes: NDArray[np.intp], starts: NDArray[np.intp]
) -> NDArray[np.bool_]:
    """(n,) bool: strictly inside its cluster's octagon of extreme points, by the margin.

    The octagon joins each cluster's extreme points in eight directions, counter-clockwise
    from +x (``_octagon_columns``; the support points of a convex set for increasing
    angles follow its boundary counter-clockwise).
    It lies inside the hull, so a point strictly inside it is not a hull vertex.
    Repeated vertices (zero-length edges) are skipped; a degenerate octagon (a segment)
    has edges both ways, and a single point no edge, so nothing is inside them.
    """
    # Column by column on contiguous copies, per-cluster values spread with np.repeat:
    # 2.7x faster than (n, 8) projections, gathers and an axis-1 reduction (measured).
    x, y = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
    count = len(sizes)
    corner_x, corner_y = np.empty((count, 8)), np.empty((count, 8))
    for direction, (column, largest) in enumerate(_octagon_columns(x, y)):
        best = (np.maximum if largest else np.minimum).reduceat(column, starts)
        rows = np.flatnonzero(column == np.repeat(best, sizes))
        corner = np.empty(count, dtype=np.intp)
        # One of the points reaching each cluster's extreme (clusters are contiguous).
        corner[np.searchsorted(starts, rows, side="right") - 1] = rows
        corner_x[:, direction], corner_y[:, direction] = x[corner], y[corner]
    ex = np.roll(corner_x, -1, axis=1) - corner_x
    ey = np.roll(corner_y, -1, axis=1) - corner_y
    length = np.hypot(ex, ey)
    # Left of an edge (inside) by more than the margin: cross(edge, p - start) > margin *
    # length, with cross = ex * py - ey * px - (ex * sy - ey * sx). Rounding is below
    # 1e-13 * length at LiDAR ranges, far under the margin.
    offset = ex * corner_y - ey * corner_x + _QHULL_MARGIN * length
    offset[length == 0.0] = -np.inf  # a repeated corner is no edge
    # All corners one point: every point is that point, none is inside.
    inside = np.repeat((length > 0.0).any(axis=1), sizes)
    for edge in range(8):
        spread = (np.repeat(values[:, edge], sizes) for values in (ex, ey, offset))
        ex_edge, ey_edge, offset_edge = spread
        inside &= y * ex_edge - x * ey_edge > offset_edge
    return inside


def _octagon_columns(
    x: NDArray[np.float64], y: NDArray[np.float64]
) -> list[tuple[NDArray[np.float64], bool]]:
    """The projections on the directions +x, +x+y, +y, -x+y, -x, -x-y, -y, +x-y as
    (column, whether the extreme is its maximum).

    Opposite directions are one column's maximum and minimum. x + y and x - y of float32
    coordinates are exact in float64, so the extremes are.
    """
    both, difference = x + y, x - y
    return [
        (x, True), (both, True), (y, True), (difference, False),
        (x, False), (both, False), (y, False), (difference, True),
    ]  # fmt: skip


def _inside_qhull(xy: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(n,) bool: strictly inside qhull's hull by more than ``_QHULL_MARGIN``."""
    try:
        equations = ConvexHull(xy).equations  # unit outward normals and offsets
    except QhullError:  # (nearly) collinear: nothing is inside
        return np.zeros(len(xy), dtype=bool)
    distance = xy @ equations[:, :2].T + equations[:, 2]
    return (distance < -_QHULL_MARGIN).all(axis=1)


def convex_hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Andrew's monotone chain: counter-clockwise hull vertices, no collinear ones."""
    unique = sorted(set(points))
    if len(unique) < 3:
        return unique
    chains = []
    for sequence in (unique, unique[::-1]):
        chain: list[tuple[float, float]] = []
        for p in sequence:
            px, py = p
            while len(chain) >= 2:
                (ox, oy), (ax, ay) = chain[-2], chain[-1]
                if (ax - ox) * (py - oy) - (ay - oy) * (px - ox) > 0:
                    break
                chain.pop()
            chain.append(p)
        chains.append(chain[:-1])
    return chains[0] + chains[1]


def hull_polygon(
    candidates: list[tuple[float, float]],
    low: list[float],
    high: list[float],
    start: HullStart,
    ref: tuple[float, float, float],
) -> list[tuple[float, float]]:
    """``ComputePolygon2dxy``: the x, y of the clockwise hull vertices, or of the rectangle
    for collinear points (``low``, ``high``: the cluster's bounds)."""
    hull = convex_hull(candidates)
    if len(hull) < 3:
        # Where qhull gives up, Apollo falls back to the clockwise bounding rectangle.
        x0, y0, x1, y1 = low[0], low[1], high[0], high[1]
        return [(x0, y0), (x0, y1), (x1, y1), (x1, y0)]
    # PCL sorts by atan2 about the centroid, largest angle first: clockwise.
    cx = sum(p[0] for p in hull) / len(hull)
    cy = sum(p[1] for p in hull) / len(hull)
    hull.sort(key=lambda p: -math.atan2(p[1] - cy, p[0] - cx))
    if start == "nearest":
        first = min(
            range(len(hull)), key=lambda i: math.hypot(hull[i][0] - ref[0], hull[i][1] - ref[1])
        )
        hull = hull[first:] + hull[:first]
    return hull
