"""Polygon checks and vectorised geometry: validation, even-odd containment, edge distances."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument

__all__ = ["validate_polygon"]

# Vertices closer than this (metres) are merged; map polygons repeat points.
_DUPLICATE_TOLERANCE = 1e-9
# Points x edges per block in the vectorised polygon tests (bounds temporary memory).
_BLOCK_ELEMENTS = 1 << 20


def validate_polygon(
    vertices: ArrayLike, *, name: str = "polygon", path: str | Path | None = None
) -> NDArray[np.float64]:
    """Check that ``vertices`` form a simple polygon and return them normalised.

    Parameters
    ----------
    vertices : (k, 2) or (k, 3) array_like
      x, y[, z] in metres; z is dropped. A closing vertex equal to the first and
      consecutive repeated vertices are removed.
    name : str
      How the polygon is called in error messages, e.g. ``"polygons[2]"``.
    path : str or Path, optional
      The file the polygon came from; errors are then :class:`DataError` naming it
      (otherwise :class:`InvalidArgument`).

    Returns
    -------
    (k, 2) float64
      Contiguous vertices, in their original orientation.
    """

    def fail(message: str) -> Exception:
        if path is not None:
            return DataError(f"{name}: {message}", path=path)
        return InvalidArgument(f"{name}: {message}")

    try:
        array = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise fail(f"cannot be converted to a float array ({error})") from None
    if array.ndim != 2 or array.shape[1] not in (2, 3):
        raise fail(f"vertices must have shape (k, 2) or (k, 3), got {array.shape}")
    if not np.isfinite(array).all():
        row = int(np.flatnonzero(~np.isfinite(array).all(axis=1))[0])
        raise fail(f"vertex {row} is not finite: {array[row].tolist()}")
    xy = array[:, :2]
    if len(xy):
        step = np.abs(np.diff(xy, axis=0, append=xy[:1])).max(axis=1)
        xy = xy[step > _DUPLICATE_TOLERANCE] if len(xy) > 1 else xy
    if len(xy) < 3:
        raise fail(f"needs at least 3 distinct vertices, got {len(xy)}")
    xy = np.ascontiguousarray(xy)
    spread = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    if spread[-1] <= 1e-12 * max(float(spread[0]), 1.0):
        raise fail("has zero area (all vertices are collinear)")
    crossing = _first_self_intersection(xy)
    if crossing is not None:
        i, j = crossing
        k = len(xy)
        raise fail(
            f"is self-intersecting: edge {i} {_edge_text(xy, i, k)} meets edge {j} "
            f"{_edge_text(xy, j, k)}; ROI polygons must be simple"
        )
    return xy


def _edge_text(xy: NDArray[np.float64], i: int, k: int) -> str:
    a, b = xy[i], xy[(i + 1) % k]
    return f"({a[0]:.3f}, {a[1]:.3f})-({b[0]:.3f}, {b[1]:.3f})"


def _signed_area(xy: NDArray[np.float64]) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _orientation(
    ax: NDArray[np.float64],
    ay: NDArray[np.float64],
    bx: NDArray[np.float64],
    by: NDArray[np.float64],
    cx: NDArray[np.float64],
    cy: NDArray[np.float64],
) -> NDArray[np.float64]:
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def _first_self_intersection(xy: NDArray[np.float64]) -> tuple[int, int] | None:
    """Indices (i, j) of the first two edges that meet where they should not, or None."""
    k = len(xy)
    start, end = xy, np.roll(xy, -1, axis=0)
    # Edge i (rows) against every edge j > i (columns), a block of rows at a time.
    block = max(1, _BLOCK_ELEMENTS // k)
    j = np.arange(k)[None, :]
    cx, cy, dx, dy = start[None, :, 0], start[None, :, 1], end[None, :, 0], end[None, :, 1]
    for begin in range(0, k, block):
        i = np.arange(begin, min(begin + block, k))[:, None]
        ax, ay = start[i[:, 0], 0][:, None], start[i[:, 0], 1][:, None]
        bx, by = end[i[:, 0], 0][:, None], end[i[:, 0], 1][:, None]
        o1 = _orientation(ax, ay, bx, by, cx, cy)
        o2 = _orientation(ax, ay, bx, by, dx, dy)
        o3 = _orientation(cx, cy, dx, dy, ax, ay)
        o4 = _orientation(cx, cy, dx, dy, bx, by)
        proper = (o1 * o2 < 0) & (o3 * o4 < 0)
        # A vertex of one edge lying on the other edge (collinear touching or overlap).
        touch = (
            ((o1 == 0) & _on_segment(ax, ay, bx, by, cx, cy))
            | ((o2 == 0) & _on_segment(ax, ay, bx, by, dx, dy))
            | ((o3 == 0) & _on_segment(cx, cy, dx, dy, ax, ay))
            | ((o4 == 0) & _on_segment(cx, cy, dx, dy, bx, by))
        )
        following = j == i + 1
        wrap = (i == 0) & (j == k - 1)
        # Neighbours always share a vertex; they are bad only when they fold back over each
        # other (collinear, pointing in opposite directions from the shared vertex).
        back = np.where(
            following,
            (ax - bx) * (dx - cx) + (ay - by) * (dy - cy),
            (bx - ax) * (cx - dx) + (by - ay) * (cy - dy),
        )
        fold = (o1 == 0) & (o2 == 0) & (back > 0)
        bad = np.where(following | wrap, fold, proper | touch) & (j > i)
        if bad.any():
            row, column = np.argwhere(bad)[0]
            return int(i[row, 0]), int(column)
    return None


def _on_segment(ax: Any, ay: Any, bx: Any, by: Any, px: Any, py: Any) -> NDArray[np.bool_]:
    return (
        (np.minimum(ax, bx) <= px)
        & (px <= np.maximum(ax, bx))
        & (np.minimum(ay, by) <= py)
        & (py <= np.maximum(ay, by))
    )


def _as_xy(xy: ArrayLike, name: str = "xy", *, convert: bool = True) -> NDArray[Any]:
    """Normalise query points: (n, >=2) array_like or PointCloud -> (n, 2) float64.

    ``convert=False``: only checked, returned as the (n, >=2) numeric array it is (for
    callers that convert block by block).
    """
    points = getattr(xy, "points", xy)
    try:
        array = np.asarray(points)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"{name} cannot be converted to an array: {error}") from None
    if array.ndim == 1 and array.shape == (2,):
        array = array[None, :]
    if array.ndim != 2 or array.shape[1] < 2:
        raise InvalidArgument(f"{name} must have shape (n, 2) or (n, >=2), got {array.shape}")
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise InvalidArgument(f"{name} must be numeric, got dtype {array.dtype}")
    if not convert:
        return array
    return np.asarray(array[:, :2], dtype=np.float64)


def _points_in_polygon(xy: NDArray[np.float64], polygon: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Even-odd test of (n, 2) points against one polygon, vectorised over points and edges.

    A horizontal ray from a point can only cross edges whose y range holds the point's y,
    so edges are bucketed into horizontal bands and each point is tested against the
    edges of its band only (a few, instead of all k).
    """
    inside = np.zeros(len(xy), dtype=bool)
    low, high = polygon.min(axis=0), polygon.max(axis=0)
    candidates = np.flatnonzero(
        (xy[:, 0] >= low[0]) & (xy[:, 0] <= high[0]) & (xy[:, 1] >= low[1]) & (xy[:, 1] <= high[1])
    )
    if len(candidates) == 0:
        return inside
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    bands = max(1, min(len(polygon), 256))
    height = (high[1] - low[1]) / bands or 1.0
    # Bands each edge spans (inclusive); edges are listed band by band.
    first = np.clip(((np.minimum(y0, y1) - low[1]) / height).astype(np.intp), 0, bands - 1)
    last = np.clip(((np.maximum(y0, y1) - low[1]) / height).astype(np.intp), 0, bands - 1)
    spans = last - first + 1
    edge_of = np.repeat(np.arange(len(polygon)), spans)
    band_of = np.repeat(first, spans) + (
        np.arange(int(spans.sum())) - np.repeat(np.cumsum(spans) - spans, spans)
    )
    order = np.argsort(band_of, kind="stable")
    edge_of = edge_of[order]
    per_band = np.bincount(band_of, minlength=bands)
    band_start = np.cumsum(per_band) - per_band
    # Point-edge pairs: each candidate with every edge of its band.
    point_band = np.clip(((xy[candidates, 1] - low[1]) / height).astype(np.intp), 0, bands - 1)
    counts = per_band[point_band]
    hits_per_point = np.zeros(len(candidates), dtype=np.int64)
    # Blocks of points keep the pair arrays bounded.
    cumulative = np.cumsum(counts)
    begin = 0
    while begin < len(candidates):
        limit = (cumulative[begin - 1] if begin else 0) + _BLOCK_ELEMENTS
        end = max(begin + 1, int(np.searchsorted(cumulative, limit, side="right")))
        rows = np.arange(begin, end)
        n_pairs = counts[rows]
        pair_point = np.repeat(rows, n_pairs)
        offsets = np.arange(int(n_pairs.sum())) - np.repeat(np.cumsum(n_pairs) - n_pairs, n_pairs)
        pair_edge = edge_of[np.repeat(band_start[point_band[rows]], n_pairs) + offsets]
        px = xy[candidates[pair_point], 0]
        py = xy[candidates[pair_point], 1]
        ex0, ey0, ex1, ey1 = x0[pair_edge], y0[pair_edge], x1[pair_edge], y1[pair_edge]
        # Half-open in y so that a vertex on the ray is counted once.
        straddles = (ey0 <= py) != (ey1 <= py)
        dy = np.where(ey1 != ey0, ey1 - ey0, 1.0)
        cross_x = ex0 + (py - ey0) * (ex1 - ex0) / dy
        hits = straddles & (px < cross_x)
        hits_per_point[begin:end] = np.bincount(pair_point[hits] - begin, minlength=end - begin)
        begin = end
    inside[candidates] = (hits_per_point & 1).astype(bool)
    return inside


def _segment_distance(xy: NDArray[np.float64], polygon: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from (n, 2) points to the closest edge of one polygon."""
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    ab = b - a
    length2 = np.maximum((ab**2).sum(axis=1), 1e-300)
    best = np.full(len(xy), np.inf)
    block = max(1, _BLOCK_ELEMENTS // len(polygon))
    for begin in range(0, len(xy), block):
        p = xy[begin : begin + block, None, :]
        t = np.clip(((p - a) * ab).sum(axis=2) / length2, 0.0, 1.0)
        closest = a + t[..., None] * ab
        best[begin : begin + block] = np.sqrt(((p - closest) ** 2).sum(axis=2)).min(axis=1)
    return best
