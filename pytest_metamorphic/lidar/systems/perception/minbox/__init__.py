# Copyright 2026 The pytest-metamorphic Authors
# Derived from Apollo (https://github.com/ApolloAuto/apollo), Copyright 2017-2018 The Apollo
# Authors, licensed under the Apache License, Version 2.0.
# What it derives from: MinBoxObjectBuilder (min_box.cc).
# Changed: re-implemented in Python and NumPy, with the differences stated below. See NOTICE.
# SPDX-License-Identifier: Apache-2.0
"""Apollo's MinBox object builder: an oriented box from one obstacle's points.

A port of ``MinBoxObjectBuilder`` (ApolloAuto/apollo,
``modules/perception/obstacle/lidar/object_builder/min_box/min_box.cc`` with
``BaseObjectBuilder::SetDefaultValue``), the box builder of the LiDAR obstacle pipeline
that Zhou & Sun tested. The algorithm, step by step:

1. **Defaults** (``SetDefaultValue``): the axis-aligned bounding box, every extent widened
   to at least 1 mm (in float32, like Apollo); length is the longer of the x/y extents
   and the direction +x or +y accordingly. Clusters with fewer than 4 points keep this
   box's extents unless step 3 finds a better edge, with this box's rectangle as polygon.
2. **Polygon** (``ComputePolygon2dxy``): the 2-D convex hull of the points, its vertices
   sorted clockwise by angle about the hull centroid, starting from the largest ``atan2``
   (PCL's ``comparePoints2D``). When the points are collinear (qhull fails in Apollo) the
   polygon is the clockwise axis-aligned rectangle. The height is ``max z - min z``.
3. **Edges facing the sensor** (``ReconstructPolygon``): the two hull vertices that bound
   the polygon's angular extent as seen from ``ref_center`` are found; only hull edges on
   the sensor's side of the line between them are candidates, and edges that are both
   shorter than the longest facing edge and shorter than half of the facing outline are
   skipped.
4. **Minimum area** (``ComputeAreaAlongOneEdge``): for each candidate edge, the box with
   one side on that edge and enclosing the polygon; the smallest area wins (the first
   one on ties, walking the hull from the first bounding vertex). Length is the longer
   side, ``direction`` its unit vector.

Quirks kept on purpose, because Apollo's expected boxes depend on them: the sign of
``direction`` follows vertex order; the box centre's z is the *lowest* point (Apollo's
convention, not the box middle); when no hull edge qualifies, the default box stays.

Differences, none of which changes Apollo's five expected test boxes: the hull is
Andrew's monotone chain in exact double arithmetic rather than qhull (the same vertices
except for points within rounding error of a hull edge); Apollo's ``10 * DBL_EPSILON``
nudge of collinear clusters is omitted (it cannot change a float32 coordinate); a
zero-length edge, where Apollo divides by zero and produces NaN, is never chosen.

:func:`min_boxes` builds every cluster of a frame in one call: the per-cluster bounds and
default boxes are vectorised; points strictly inside each cluster's hull are pruned before
the exact hull (:mod:`.hull`), so the per-cluster Python work depends on the hull size,
not the point count; only the facing-edge walk is per cluster, and the boxes along all
candidate edges of the frame are one vectorised pass (:mod:`.edges`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.systems.perception.minbox.edges import best_boxes, facing_edges
from pytest_metamorphic.lidar.systems.perception.minbox.hull import (
    HullStart,
    hull_candidates,
    hull_polygon,
)

__all__ = ["HullStart", "MinBox", "min_box", "min_boxes"]


_DEGENERATE = np.float32(1e-3)  # SetDefaultValue's minimum extent


@dataclass(frozen=True)
class MinBox:
    """The box MinBox builds for one cluster (Apollo's ``Object`` fields).

    Attributes
    ----------
    center : (3,) tuple of float
        x, y of the box centre; z of the cluster's lowest point (Apollo's convention).
    length, width, height : float
        Length >= width, the sides of the box in the x-y plane; height = z extent.
    direction : (3,) tuple of float
        Unit vector along the length (z = 0). Its sign follows Apollo's vertex order.
    polygon : (k, 3) float64
        The clockwise convex hull (or rectangle) the box was fitted to, at the lowest z.
    points : int
        How many points the cluster had.
    """

    center: tuple[float, float, float]
    length: float
    width: float
    height: float
    direction: tuple[float, float, float]
    polygon: NDArray[np.float64]
    points: int

    @property
    def yaw(self) -> float:
        """Heading of ``direction`` in radians, counter-clockwise from +x."""
        return math.atan2(self.direction[1], self.direction[0])


def min_box(
    points: ArrayLike,
    *,
    ref_center: ArrayLike = (0.0, 0.0, 0.0),
    start: HullStart = "apollo",
) -> MinBox:
    """Build Apollo's MinBox for one obstacle cluster.

    Parameters
    ----------
    points : (n, 3) or (n, 4) array_like
        The cluster's x, y, z[, intensity], n >= 1. Apollo's clouds are float32; values
        are rounded to float32 first so results match Apollo's.
    ref_center : (3,) array_like
        The sensor position the "edges facing the sensor" are judged from (Apollo's
        ``ObjectBuilderOptions::ref_center``).
    start : {"apollo", "nearest"}
        Where the clockwise hull walk starts, see :func:`min_boxes`.

    Returns
    -------
    MinBox
    """
    xyz = _as_points(points)
    labels = np.zeros(len(xyz), dtype=np.intp)
    return min_boxes(xyz, labels, ref_center=ref_center, start=start)[0]


def min_boxes(
    points: ArrayLike,
    labels: ArrayLike,
    *,
    ref_center: ArrayLike = (0.0, 0.0, 0.0),
    start: HullStart = "apollo",
) -> list[MinBox]:
    """Build Apollo's MinBox for every cluster of a frame.

    Parameters
    ----------
    points : (n, 3) or (n, 4) array_like
        x, y, z[, intensity] of all clustered points (rounded to float32).
    labels : (n,) array_like of int
        Cluster of each point, ``0 <= label < k``; every cluster must have a point.
    ref_center : (3,) array_like
        The sensor position (Apollo's ``ObjectBuilderOptions::ref_center``).
    start : {"apollo", "nearest"}
        The vertex the clockwise hull polygon starts at. ``"apollo"``: the largest
        ``atan2`` about the centroid, as PCL sorts it. The facing-edge search breaks
        near-ties (vertices on one laser ray, within ``EPSILON``) by that order, so with
        ``"apollo"`` the box can change when the whole scene is turned about the sensor.
        ``"nearest"``: the vertex nearest ``ref_center``, which turns with the scene; the
        box is then rotation-equivariant (Apollo's boxes otherwise, up to the sign of
        ``direction``).

    Returns
    -------
    list of MinBox
        One per cluster, in label order. The result depends only on each cluster's set
        of points and their multiplicity (Apollo's "fewer than 4 points" rule counts
        repeats), never on their order.
    """
    xyz = _as_points(points)
    ids = _as_labels(labels, len(xyz))
    ref = _as_ref(ref_center)
    if start not in ("apollo", "nearest"):
        raise InvalidArgument(f"start={start!r} must be 'apollo' or 'nearest'")
    count = int(ids.max()) + 1
    sizes = np.bincount(ids, minlength=count)
    if not sizes.all():
        raise InvalidArgument(
            f"labels must use every cluster id 0..{count - 1}; id {int(np.argmin(sizes))} "
            "has no points"
        )
    # Contiguous clusters: every per-cluster reduction is then one reduceat. A stable
    # sort of 16-bit labels is a radix sort, 3x faster than one of 64-bit labels.
    narrow = ids.astype(np.int16) if count <= np.iinfo(np.int16).max else ids
    xyz = np.take(xyz, np.argsort(narrow, kind="stable"), axis=0)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    low = np.minimum.reduceat(xyz, starts, axis=0)
    high = np.maximum.reduceat(xyz, starts, axis=0)
    defaults = _default_boxes(low, high)
    hulls = hull_candidates(xyz[:, :2].astype(np.float64), sizes, starts)
    lows, highs = low.tolist(), high.tolist()
    outlines, floors, heights = [], [], []
    for cluster, size in enumerate(sizes.tolist()):
        if size >= 4:
            outline = hull_polygon(hulls[cluster], lows[cluster], highs[cluster], start, ref)
            floors.append(lows[cluster][2])
            heights.append(highs[cluster][2] - lows[cluster][2])
        else:
            outline = defaults.rectangles[cluster]
            floors.append(defaults.floors[cluster])
            heights.append(defaults.heights[cluster])
        outlines.append(outline)
    every, polygons = _polygons(outlines, floors)
    edges = facing_edges(outlines, every, ref)
    fits = best_boxes(every, [len(outline) for outline in outlines], edges)
    boxes = []
    for cluster, (size, fit) in enumerate(zip(sizes.tolist(), fits, strict=True)):
        if fit is None:  # no edge qualifies: the default box stays
            center, length, width = defaults.centers[cluster], *defaults.extents[cluster]
            direction = defaults.directions[cluster]
        else:
            length, width, cx, cy, direction = fit
            center = (cx, cy, floors[cluster])
        boxes.append(
            MinBox(center, length, width, heights[cluster], direction, polygons[cluster], size)
        )
    return boxes


def _polygons(
    outlines: list[list[tuple[float, float]]], floors: list[float]
) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
    """(k, 3) float64 polygons at the given heights, as views of one (n, 3) array (also
    returned): one conversion for all clusters instead of one per cluster."""
    counts = [len(outline) for outline in outlines]
    every = np.empty((sum(counts), 3))
    every[:, :2] = [vertex for outline in outlines for vertex in outline]
    every[:, 2] = np.repeat(floors, counts)
    ends = np.cumsum(counts).tolist()
    return every, [every[end - count : end] for count, end in zip(counts, ends, strict=True)]


def _as_points(points: ArrayLike) -> NDArray[np.float32]:
    try:
        array = np.asarray(getattr(points, "points", points), dtype=np.float32)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"points cannot be converted to a float array: {error}") from None
    if array.ndim != 2 or array.shape[1] not in (3, 4):
        raise InvalidArgument(f"points must have shape (n, 3) or (n, 4), got {array.shape}")
    if len(array) == 0:
        raise InvalidArgument("points is empty; a box needs at least one point")
    if not np.isfinite(array[:, :3]).all():
        raise DataError("points: NaN or infinite coordinates")
    return np.ascontiguousarray(array[:, :3])


def _as_labels(labels: ArrayLike, n: int) -> NDArray[np.intp]:
    array = np.asarray(labels)
    if array.shape != (n,) or not np.issubdtype(array.dtype, np.integer):
        raise InvalidArgument(
            f"labels must be ({n},) integers, one per point; got {array.dtype} {array.shape}"
        )
    if n and array.min() < 0:
        raise InvalidArgument(f"labels must be >= 0, got {int(array.min())}")
    return array.astype(np.intp, copy=False)


def _as_ref(ref_center: ArrayLike) -> tuple[float, float, float]:
    try:
        ref = tuple(float(v) for v in np.asarray(ref_center, dtype=np.float64).reshape(-1))
    except (TypeError, ValueError):
        ref = ()
    if len(ref) != 3 or not all(math.isfinite(v) for v in ref):
        raise InvalidArgument(f"ref_center={ref_center!r} must be 3 finite numbers")
    return ref


@dataclass(frozen=True)
class _Defaults:
    centers: list[tuple[float, float, float]]
    extents: list[tuple[float, float]]  # length, width
    heights: list[float]
    directions: list[tuple[float, float, float]]
    rectangles: list[list[tuple[float, float]]]  # the polygon's x, y
    floors: list[float]  # the polygon's z


def _default_boxes(low: NDArray[np.float32], high: NDArray[np.float32]) -> _Defaults:
    """``SetDefaultValue`` for every cluster, in float32 like Apollo's Eigen::Vector4f."""
    middle = (low + high) / np.float32(2)
    thin = (high - low) < _DEGENERATE
    half = _DEGENERATE / np.float32(2)
    low = np.where(thin, middle - half, low).astype(np.float32)
    high = np.where(thin, middle + half, high).astype(np.float32)
    extent = high - low
    swap = extent[:, 0] - extent[:, 1] < 0
    lengths = np.where(swap, extent[:, 1], extent[:, 0])
    widths = np.where(swap, extent[:, 0], extent[:, 1])
    centers = (high + low) / np.float32(2)
    # Counter-clockwise from the lower-left corner, as SetDefaultValue writes it.
    corners = np.concatenate([low[:, :2], high[:, :2]], axis=1).tolist()
    rectangles = [[(x0, y0), (x1, y0), (x1, y1), (x0, y1)] for x0, y0, x1, y1 in corners]
    return _Defaults(
        centers=list(map(tuple, centers.tolist())),
        extents=list(zip(lengths.tolist(), widths.tolist(), strict=True)),
        heights=extent[:, 2].tolist(),
        directions=[(0.0, 1.0, 0.0) if s else (1.0, 0.0, 0.0) for s in swap.tolist()],
        rectangles=rectangles,
        floors=low[:, 2].tolist(),
    )
