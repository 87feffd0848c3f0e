# Copyright 2026 The pytest-metamorphic Authors
# Derived from Apollo (https://github.com/ApolloAuto/apollo), Copyright 2017-2018 The Apollo
# Authors, licensed under the Apache License, Version 2.0.
# What it derives from: MinBoxObjectBuilder::ReconstructPolygon and ComputeAreaAlongOneEdge
# (min_box.cc).
# Changed: re-implemented in Python and NumPy, with the differences stated in the docstring
# of pytest_metamorphic.lidar.systems.perception.minbox. See NOTICE.
# SPDX-License-Identifier: Apache-2.0
"""MinBox's box: the edges of the polygon that face the sensor (``ReconstructPolygon``) and
the minimum-area box along one of them (``ComputeAreaAlongOneEdge``)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

_EPSILON = 1e-6  # min_box.cc's EPSILON for the facing-edge tests


def facing_edges(
    outlines: list[list[tuple[float, float]]],
    every: NDArray[np.float64],
    ref: tuple[float, float, float],
) -> list[list[int]]:
    """``ReconstructPolygon``'s choice of edges for every cluster: those facing the sensor
    that are long enough, in Apollo's order (their boxes are compared in
    :func:`best_boxes`).

    ``every`` holds the outlines' vertices one after another (as :func:`best_boxes`
    takes them). The bounding vertices are a sequential walk per cluster; which side of
    the line between them each vertex lies on, and the edge lengths, are computed for
    all clusters at once, with the same arithmetic.

    Returns
    -------
    list of list of int
        Per cluster: edge ``i`` runs from vertex ``i`` to vertex ``i + 1``. Empty when no
        edge qualifies (the default box stays).
    """
    rx, ry = ref[0], ref[1]
    bounds = [_bounding_vertices(outline, rx, ry) for outline in outlines]
    counts = [len(outline) for outline in outlines]
    line = np.repeat(np.array([bound[2:] for bound in bounds]).reshape(-1, 4), counts, axis=0)
    min_x, min_y, line_x, line_y = line.T
    x, y = every[:, 0], every[:, 1]
    # side[i] > 0: vertex i lies beyond the line between the bounding vertices, away
    # from the sensor. Apollo mixes frames here (an absolute vertex minus a
    # sensor-relative point); identical for ref_center at the origin, kept as is.
    side = (line_x * (y - min_y) - (x - min_x) * line_y).tolist()
    # edge[i]: length of the edge from vertex i to vertex i + 1 (math.hypot: numpy's
    # differs in the last bit for ~0.6 % of inputs).
    ends = np.cumsum(counts)
    following = np.arange(1, len(x) + 1)
    following[ends - 1] = ends - np.array(counts)
    edge = list(map(math.hypot, (x[following] - x).tolist(), (y[following] - y).tolist()))
    result = []
    for (min_index, max_index, *_), end, count in zip(bounds, ends.tolist(), counts, strict=True):
        begin = end - count
        result.append(_walks(side[begin:end], edge[begin:end], min_index, max_index))
    return result


def _bounding_vertices(
    vertices: list[tuple[float, float]], rx: float, ry: float
) -> tuple[int, int, float, float, float, float]:
    """The vertices that bound the polygon's angular extent seen from ``(rx, ry)``:
    ``(min_index, max_index, min_x, min_y, line_x, line_y)``, positions relative to the
    sensor and ``line`` from the counter-clockwise-most to the clockwise-most one."""
    max_index = min_index = 0
    max_x = min_x = vertices[0][0] - rx
    max_y = min_y = vertices[0][1] - ry
    for i in range(1, len(vertices)):
        x, y = vertices[i][0] - rx, vertices[i][1] - ry
        if max_x * y - x * max_y < _EPSILON:  # clockwise-most so far
            max_x, max_y, max_index = x, y, i
        if min_x * y - x * min_y > _EPSILON:  # counter-clockwise-most so far
            min_x, min_y, min_index = x, y, i
    return min_index, max_index, min_x, min_y, max_x - min_x, max_y - min_y


def _walks(side: list[float], edge: list[float], min_index: int, max_index: int) -> list[int]:
    """Apollo's two walks around one polygon from ``min_index``: the facing outline's
    length and longest edge, then the candidate edges in order."""
    count = len(side)
    bounds = (min_index, max_index)
    span = ((min_index, max_index), (max_index, min_index))
    walk = [((min_index + step) % count, (min_index + step + 1) % count) for step in range(count)]
    # First walk: length of the facing outline, its longest edge, whether any edge
    # lies on the far side.
    total_len = max_dis = 0.0
    has_out = False
    for i, j in walk:
        if j not in bounds:
            if side[j] < _EPSILON:
                total_len += edge[i]
                if edge[i] - max_dis > _EPSILON:
                    max_dis = edge[i]
            else:
                has_out = True
        elif (i, j) in span:
            # Apollo tests polygon[0] here (the outer-scope variable it shadows elsewhere).
            if not side[0] < 0:
                has_out = True
        elif side[i] < _EPSILON:
            total_len += edge[i]
            if edge[i] > max_dis:
                max_dis = edge[i]
        else:
            has_out = True

    # Second walk: candidate edges, in Apollo's order.
    candidates = []
    for i, j in walk:
        if edge[i] < max_dis and edge[i] / total_len < 0.5:
            continue
        if j not in bounds:
            if side[j] < 0:
                candidates.append(i)
        elif (i, j) in span:
            if has_out:
                candidates.append(i)
        elif side[i] < 0:
            candidates.append(i)
    return candidates


def best_boxes(
    every: NDArray[np.float64],
    counts: list[int],
    edges: list[list[int]],
) -> list[tuple[float, float, float, float, tuple[float, float, float]] | None]:
    """Per cluster, the minimum-area box over its candidate edges, or None.

    ``every`` holds all clusters' polygons one after another (``counts`` vertices each),
    ``edges`` each cluster's candidate edges in Apollo's order; the smallest area wins
    (strict ``<``: the first one on ties), zero-length edges never.

    Returns
    -------
    list of (length, width, center_x, center_y, direction) or None
    """
    fits = _boxes_along_edges(every[:, 0], every[:, 1], counts, edges)
    result: list[tuple[float, float, float, float, tuple[float, float, float]] | None] = []
    candidate = 0
    for cluster_edges in edges:
        best = None
        for _ in cluster_edges:
            found = fits[candidate]
            candidate += 1
            if found is not None and (best is None or found[0] < best[0]):
                best = found
        if best is None:
            result.append(None)
            continue
        _, length, width, cx, cy, ux, uy = best
        norm = math.hypot(ux, uy)
        if norm > 0:
            ux, uy = ux / norm, uy / norm
        result.append((length, width, cx, cy, (ux, uy, 0.0)))
    return result


def _boxes_along_edges(
    x: NDArray[np.float64], y: NDArray[np.float64], counts: list[int], edges: list[list[int]]
) -> list[tuple[float, float, float, float, float, float, float] | None]:
    """``ComputeAreaAlongOneEdge`` for every candidate edge of every cluster at once.

    The box with one side on the edge: every other vertex is projected onto the edge's
    line; the width is the largest vertex-to-line distance (the first strictly positive
    maximum), the length the largest distance between projected points. Apollo finds that
    pair by trying all pairs ``i < j`` and keeping the first strictly longer one; the
    projected points are collinear, so that pair is the two extremes along the line and,
    on exact ties, the lowest index among both extremes paired with the lowest index at
    the other extreme. That rule is applied here (ties within 1e-9 of the edge scale).
    The arithmetic is Apollo's, element by element in float64, so the boxes are the same
    as one edge at a time in Python (``math.hypot`` is kept for the length: numpy's
    ``hypot`` differs from it in the last bit for ~0.6 % of inputs).

    Returns
    -------
    list of (area, length, width, center_x, center_y, direction_x, direction_y) or None
        One per candidate edge, clusters in order; ``direction`` unnormalised, along the
        length; None for a zero-length edge (where Apollo divides by zero and builds a NaN
        box).
    """
    per_cluster = np.array([len(cluster_edges) for cluster_edges in edges], dtype=np.intp)
    if not per_cluster.any():
        return []
    count = np.array(counts, dtype=np.intp)
    start = np.cumsum(count) - count
    # One row per candidate edge, one column per vertex of its polygon (padded).
    k = np.repeat(count, per_cluster)[:, None]
    base = np.repeat(start, per_cluster)[:, None]
    first = np.array([edge for cluster_edges in edges for edge in cluster_edges])[:, None]
    second = (first + 1) % k
    column = np.arange(int(k.max()))[None, :]
    valid = column < k
    vertex = np.where(valid, base + column, base)
    ox, oy = x[vertex], y[vertex]
    bx, by = x[base + first], y[base + first]
    ax, ay = x[base + second], y[base + second]
    dx, dy = bx - ax, by - ay
    squared = dx * dx + dy * dy
    norm = np.sqrt(squared)
    degenerate = norm == 0.0
    squared[degenerate] = norm[degenerate] = 1.0  # rows dropped below; no 0 / 0 warnings
    k_along = -((ax - ox) * dx + (ay - oy) * dy) / squared
    nx, ny = dx * k_along + ax, dy * k_along + ay  # foot of the perpendicular from each vertex
    height = np.abs((ox - bx) * (ay - by) - (ax - bx) * (oy - by)) / norm
    own = (column == first) | (column == second)  # the edge's ends project onto themselves
    px, py = np.where(own, ox, nx), np.where(own, oy, ny)
    rows = np.arange(len(k))
    # The first vertex of the largest height, when that height is > 0; else none (zeros).
    height = np.where(valid & ~own, height, -1.0)
    widest = height.argmax(axis=1)
    wid = height[rows, widest]
    has = wid > 0.0
    wid = np.where(has, wid, 0.0)
    vx, vy = (np.where(has, values[rows, widest], 0.0) for values in (ox, oy))
    vnx, vny = (np.where(has, values[rows, widest], 0.0) for values in (nx, ny))
    along = ((px - ax) * dx + (py - ay) * dy) / norm
    low = np.where(valid, along, np.inf).min(axis=1, keepdims=True)
    high = np.where(valid, along, -np.inf).max(axis=1, keepdims=True)
    tolerance = 1e-9 * (1.0 + np.maximum(np.abs(low), np.abs(high)))
    first_low = (valid & (along <= low + tolerance)).argmax(axis=1)
    first_high = (valid & (along >= high - tolerance)).argmax(axis=1)
    p1, p2 = np.minimum(first_low, first_high), np.maximum(first_low, first_high)
    x1, y1, x2, y2 = px[rows, p1], py[rows, p1], px[rows, p2], py[rows, p2]
    length = np.array(list(map(math.hypot, (x2 - x1).tolist(), (y2 - y1).tolist())))
    # The box's four corners: the two extremes and their copies moved out to the
    # widest vertex.
    cx = (2 * vx - 2 * vnx + 2 * x1 + 2 * x2) / 4
    cy = (2 * vy - 2 * vny + 2 * y1 + 2 * y2) / 4
    longer = length > wid
    ux = np.where(longer, x2 - x1, vx - vnx)
    uy = np.where(longer, y2 - y1, vy - vny)
    long_side = np.where(longer, length, wid)
    short_side = np.where(longer, wid, length)
    columns = (long_side * short_side, long_side, short_side, cx, cy, ux, uy)
    fits = list(zip(*(values.tolist() for values in columns), strict=True))
    return [None if bad else fit for fit, bad in zip(fits, degenerate[:, 0].tolist(), strict=True)]
