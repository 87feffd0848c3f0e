"""Regions of interest: HD-map road and junction polygons, exact and Apollo-rasterised.

Apollo's HD-map ROI filter does not test points against the polygons. It scan-converts
them into a bird's-eye bitmap of ``cell_size`` (0.25 m) cells covering
``[-raster_range, raster_range)`` around the sensor, and keeps a point when its cell is set
(``hdmap_roi_filter.cc``, ``polygon_mask.h``, ``bitmap2d.cc``). The scan conversion:

* the *major* axis is x when the polygons' clipped y extent is at least their x extent,
  else y; scan lines run across the major axis through the centre of every cell column;
* on each scan line the polygon's crossing intervals (even-odd) are widened by
  ``extend_dist`` on both ends (along the minor axis only) and every cell they overlap is set;
* a polygon whose major extent does not reach the next column centre is not drawn;
* points outside the bitmap are outside the ROI.

:class:`ROI` reproduces that (:meth:`ROI.contains` with ``method="raster"``) and also
answers exact even-odd containment in the union of the polygons (``method="exact"``).
Both are vectorised: the raster is a lookup of one cell per point, and the exact method
uses two more grids (cells touched by an edge, and whether each cell centre is inside) so
that only points in cells crossed by an edge need a polygon test.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import maximum_filter

from pytest_metamorphic.core.errors import DataError, InvalidArgument

__all__ = ["ROI", "ContainmentMethod", "validate_polygon"]

ContainmentMethod = Literal["raster", "exact"]

# Vertices closer than this (metres) are merged; map polygons repeat points.
_DUPLICATE_TOLERANCE = 1e-9
# Points x edges per block in the vectorised polygon tests (bounds temporary memory).
_BLOCK_ELEMENTS = 1 << 20
# Vertices of the polygon standing in for a round join between road segments.
_JOIN_SIDES = 16


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


def _as_xy(xy: ArrayLike, name: str = "xy") -> NDArray[np.float64]:
    """Normalise query points: (n, >=2) array_like or PointCloud -> (n, 2) float64."""
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


class _Grid:
    """The bitmap geometry: square cells over ``[-extent, extent)`` in x and y."""

    def __init__(self, extent: float, cell_size: float) -> None:
        self.extent = extent
        self.cell_size = cell_size
        # Apollo: dims = int((max - min) / cell) + 1 (one spare column and row).
        self.size = int(2.0 * extent / cell_size) + 1

    def index(self, values: NDArray[np.float64]) -> NDArray[np.intp]:
        return np.floor((values + self.extent) / self.cell_size).astype(np.intp)

    def exists(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        e = self.extent
        return (xy[:, 0] >= -e) & (xy[:, 0] < e) & (xy[:, 1] >= -e) & (xy[:, 1] < e)

    def centres(self, index: NDArray[np.integer]) -> NDArray[np.float64]:
        return (np.asarray(index, dtype=np.float64) + 0.5) * self.cell_size - self.extent


class ROI:
    """A region of interest: the union of simple polygons, with Apollo's rasterisation.

    Build one with :meth:`from_polygons`, :meth:`from_apollo_poly` or :meth:`from_roads`.
    Immutable; the bitmaps are computed on first use and cached.

    Attributes
    ----------
    polygons : tuple of (k, 2) float64
      Simple polygons in the sensor frame (x forward, y left), metres. A point is in the
      exact ROI when it is inside any of them (even-odd rule within each).
    cell_size : float
      Bitmap cell edge in metres (Apollo: 0.25).
    extend_dist : float
      Apollo's ``extend_dist``: scan intervals are widened by this much along the minor
      axis before rasterisation.
    raster_range : float
      Half-width of the bitmap (Apollo's ``range``); beyond it nothing is in the ROI.
    """

    __slots__ = ("_cache", "cell_size", "extend_dist", "polygons", "raster_range")

    def __init__(
        self,
        polygons: tuple[NDArray[np.float64], ...],
        *,
        cell_size: float,
        extend_dist: float,
        raster_range: float,
    ) -> None:
        # Private: use the from_* constructors, which validate.
        for polygon in polygons:
            polygon.setflags(write=False)
        self.polygons = polygons
        self.cell_size = cell_size
        self.extend_dist = extend_dist
        self.raster_range = raster_range
        self._cache: dict[Any, Any] = {}

    # -- construction ----------------------------------------------------------------------

    @classmethod
    def from_polygons(
        cls,
        polygons: Iterable[ArrayLike],
        *,
        cell_size: float = 0.25,
        extend_dist: float = 0.0,
        raster_range: float = 120.0,
    ) -> ROI:
        """An ROI from explicit vertices.

        Parameters
        ----------
        polygons : iterable of (k, 2) or (k, 3) array_like
          One array per polygon (roads and junctions alike). A single (k, 2) array is
          also accepted. Each must be simple, with at least 3 distinct finite vertices.
        cell_size : float
          Bitmap cell size in metres, > 0.
        extend_dist : float
          Apollo's interval widening in metres, >= 0.
        raster_range : float
          Half-width of the square bitmap around the sensor in metres (Apollo's ``range``;
          its default config uses 120 m, its unit test 70 m). At least one cell.
        """
        return cls._build(
            polygons, cell_size=cell_size, extend_dist=extend_dist, raster_range=raster_range
        )

    @classmethod
    def _build(
        cls,
        polygons: Any,
        *,
        cell_size: float,
        extend_dist: float,
        raster_range: float,
        path: str | Path | None = None,
    ) -> ROI:
        cell_size = _positive_float(cell_size, "cell_size")
        raster_range = _positive_float(raster_range, "raster_range")
        extend_dist = _finite_float(extend_dist, "extend_dist")
        if extend_dist < 0:
            raise InvalidArgument(f"extend_dist={extend_dist} must be >= 0")
        if raster_range <= cell_size:
            raise InvalidArgument(
                f"raster_range={raster_range} must be larger than cell_size={cell_size}"
            )
        if isinstance(polygons, np.ndarray) and polygons.ndim == 2:
            polygons = [polygons]
        if isinstance(polygons, (str, bytes)) or not isinstance(polygons, Iterable):
            raise InvalidArgument(
                f"polygons must be a list of (k, 2) vertex arrays, got {type(polygons).__name__}"
            )
        checked = tuple(
            validate_polygon(polygon, name=f"polygons[{index}]", path=path)
            for index, polygon in enumerate(polygons)
        )
        if not checked:
            raise (
                DataError("no polygons", path=path)
                if path
                else InvalidArgument("polygons is empty; an ROI needs at least one polygon")
            )
        return cls(checked, cell_size=cell_size, extend_dist=extend_dist, raster_range=raster_range)

    @classmethod
    def from_apollo_poly(
        cls,
        path: str | Path,
        *,
        cell_size: float = 0.25,
        extend_dist: float = 0.0,
        raster_range: float = 120.0,
    ) -> ROI:
        """An ROI from an Apollo ``.poly`` file (as in Apollo's ROI-filter unit test).

        The file is read by :func:`pytest_metamorphic.lidar.io.apollo.read_apollo_poly`;
        invalid polygons raise :class:`DataError` naming the file and the polygon.
        """
        from pytest_metamorphic.lidar.io.apollo import read_apollo_poly

        polygons = read_apollo_poly(path)
        return cls._build(
            polygons,
            cell_size=cell_size,
            extend_dist=extend_dist,
            raster_range=raster_range,
            path=path,
        )

    @classmethod
    def from_roads(
        cls,
        roads: Iterable[Any],
        *,
        cell_size: float = 0.25,
        extend_dist: float = 0.0,
        raster_range: float = 120.0,
    ) -> ROI:
        """An ROI from road centrelines buffered by half the road width on each side.

        Parameters
        ----------
        roads : iterable of road objects
          Each has ``centerline : (k, 2) float64`` (local metres, k >= 2) and
          ``width : float`` (metres, > 0), like the roads of
          :mod:`pytest_metamorphic.driving.osm`.

        Each segment becomes a rectangle and each vertex a 16-gon of the road's half-width
        (round joins and ends: every point within ``width / 2`` of the centreline, up to
        the 16-gon's 2 % chord error). Where roads meet, their buffers overlap and
        the union covers the junction.
        """
        pieces: list[NDArray[np.float64]] = []
        for index, road in enumerate(roads):
            pieces.extend(_road_pieces(road, f"roads[{index}]"))
        if not pieces:
            raise InvalidArgument("roads is empty; an ROI needs at least one road")
        return cls._build(
            pieces, cell_size=cell_size, extend_dist=extend_dist, raster_range=raster_range
        )

    # -- geometry ----------------------------------------------------------------------------

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 2) float64: ``[[xmin, ymin], [xmax, ymax]]`` of all polygons."""
        stacked = np.concatenate(self.polygons)
        return np.stack([stacked.min(axis=0), stacked.max(axis=0)])

    def rotated(self, theta: float) -> ROI:
        """The ROI rotated by ``theta`` radians counter-clockwise about the sensor (origin).

        The bitmap of the rotated ROI is rasterised afresh in the sensor frame, as Apollo
        does for every frame, so it is not the rotated bitmap near polygon edges.
        """
        theta = _finite_float(theta, "theta")
        c, s = math.cos(theta), math.sin(theta)
        rotation = np.array([[c, -s], [s, c]])
        return ROI(
            tuple(np.ascontiguousarray(p @ rotation.T) for p in self.polygons),
            cell_size=self.cell_size,
            extend_dist=self.extend_dist,
            raster_range=self.raster_range,
        )

    def translated(self, dx: float, dy: float) -> ROI:
        """The ROI shifted by ``(dx, dy)`` metres."""
        shift = np.array([_finite_float(dx, "dx"), _finite_float(dy, "dy")])
        return ROI(
            tuple(np.ascontiguousarray(p + shift) for p in self.polygons),
            cell_size=self.cell_size,
            extend_dist=self.extend_dist,
            raster_range=self.raster_range,
        )

    def area(self) -> float:
        """Sum of the polygon areas in m² (overlaps counted twice)."""
        return float(sum(abs(_signed_area(p)) for p in self.polygons))

    # -- containment -------------------------------------------------------------------------

    def contains(self, xy: ArrayLike, *, method: ContainmentMethod = "raster") -> NDArray[np.bool_]:
        """Which points are in the ROI.

        Parameters
        ----------
        xy : (n, 2) or (n, >=2) array_like, or a PointCloud
          Only the first two columns (x, y) are used.
        method : {"raster", "exact"}
          ``"raster"`` (default): Apollo's bitmap lookup, what the perception stack does.
          ``"exact"``: even-odd containment in any polygon; points exactly on an edge go
          to whichever side the half-open crossing rule gives.

        Returns
        -------
        (n,) bool
        """
        points = _as_xy(xy)
        if method == "raster":
            return self._contains_raster(points)
        if method == "exact":
            return self._contains_exact(points)
        raise InvalidArgument(f"method={method!r} must be 'raster' or 'exact'")

    def _contains_raster(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        grid = self._grid
        result = np.zeros(len(xy), dtype=bool)
        exists = grid.exists(xy)
        # NaN compares False above, so non-finite points are simply outside.
        rows = np.flatnonzero(exists)
        ix = grid.index(xy[rows, 0])
        iy = grid.index(xy[rows, 1])
        result[rows] = self.bitmap[ix, iy]
        return result

    def _contains_exact(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        grid = self._grid
        touched, centre_inside = self._exact_grids
        result = np.zeros(len(xy), dtype=bool)
        exists = grid.exists(xy)
        rows = np.flatnonzero(exists)
        ix = grid.index(xy[rows, 0])
        iy = grid.index(xy[rows, 1])
        # A cell no edge touches lies wholly inside or wholly outside: its centre decides.
        result[rows] = centre_inside[ix, iy]
        undecided = np.concatenate([rows[touched[ix, iy]], np.flatnonzero(~exists)])
        if len(undecided):
            subset = xy[undecided]
            finite = np.isfinite(subset).all(axis=1)
            hit = np.zeros(len(undecided), dtype=bool)
            for polygon in self.polygons:
                hit |= _points_in_polygon(subset, polygon)
            result[undecided] = hit & finite
        return result

    def boundary_distance(self, xy: ArrayLike) -> NDArray[np.float64]:
        """(n,) float64: Euclidean distance from each point to the nearest polygon edge."""
        points = _as_xy(xy)
        best = np.full(len(points), np.inf)
        for polygon in self.polygons:
            best = np.minimum(best, _segment_distance(points, polygon))
        return best

    # -- bitmaps -----------------------------------------------------------------------------

    @property
    def _grid(self) -> _Grid:
        grid = self._cache.get("grid")
        if grid is None:
            grid = self._cache["grid"] = _Grid(self.raster_range, self.cell_size)
        return grid

    @property
    def grid_size(self) -> int:
        """Cells per axis of the bitmaps (Apollo: ``int(2 * range / cell) + 1``)."""
        return self._grid.size

    def cell_index(self, xy: ArrayLike) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Bitmap indices ``(ix, iy)`` of points (meaningful only where inside the bitmap)."""
        points = _as_xy(xy)
        return self._grid.index(points[:, 0]), self._grid.index(points[:, 1])

    def cell_origin(self, ix: ArrayLike, iy: ArrayLike) -> NDArray[np.float64]:
        """(n, 2) float64: lower-left corners of cells ``(ix, iy)``."""
        grid = self._grid
        corner = np.stack([np.asarray(ix), np.asarray(iy)], axis=-1).astype(np.float64)
        return corner * grid.cell_size - grid.extent

    @property
    def major_axis(self) -> Literal["x", "y"]:
        """The axis Apollo's scan conversion steps along (scan lines run across it)."""
        low, high = self.bounds
        r = self.raster_range
        low, high = np.clip(low, -r, r), np.clip(high, -r, r)
        extent = high - low
        return "y" if extent[1] < extent[0] else "x"

    @property
    def bitmap(self) -> NDArray[np.bool_]:
        """(size, size) bool, indexed ``[ix, iy]``: Apollo's rasterised ROI. Read-only."""
        bitmap = self._cache.get("bitmap")
        if bitmap is None:
            bitmap = self._cache["bitmap"] = self._rasterise()
            bitmap.setflags(write=False)
        return bitmap

    def _rasterise(self) -> NDArray[np.bool_]:
        grid = self._grid
        size, cell, r = grid.size, grid.cell_size, grid.extent
        major = 0 if self.major_axis == "x" else 1
        columns: list[NDArray[np.intp]] = []
        lows: list[NDArray[np.float64]] = []
        highs: list[NDArray[np.float64]] = []
        for polygon in self.polygons:
            u, v = polygon[:, major], polygon[:, 1 - major]
            first = max(float(u.min()), -r)
            last = min(float(u.max()), r)
            first_column = int((first + r) / cell)
            first_centre = (first_column + 0.5) * cell - r
            if last < first_centre + cell:
                continue  # Apollo skips polygons thinner than one column ("Invalid range").
            count = int((last - first_centre) / cell)
            column, low, high = _scan_intervals(u, v, first_column, count, cell, r)
            columns.append(column)
            lows.append(low - self.extend_dist)
            highs.append(high + self.extend_dist)
        bitmap = np.zeros((size, size), dtype=bool)
        if not columns:
            return bitmap
        column = np.concatenate(columns)
        low = np.maximum(np.concatenate(lows), -r)
        high = np.minimum(np.concatenate(highs), r)
        keep = low <= high
        column, low, high = column[keep], low[keep], high[keep]
        _fill_runs(bitmap, column, grid.index(low), grid.index(high))
        return bitmap if major == 0 else np.ascontiguousarray(bitmap.T)

    @property
    def _exact_grids(self) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """(touched, centre_inside): cells an edge may cross; cells whose centre is inside."""
        grids = self._cache.get("exact")
        if grids is None:
            grids = self._cache["exact"] = (self._touched_cells(), self._centre_inside())
            for grid in grids:
                grid.setflags(write=False)
        return grids

    def _touched_cells(self) -> NDArray[np.bool_]:
        grid = self._grid
        size, cell = grid.size, grid.cell_size
        marked = np.zeros((size, size), dtype=bool)
        for polygon in self.polygons:
            a = polygon
            b = np.roll(polygon, -1, axis=0)
            length = np.sqrt(((b - a) ** 2).sum(axis=1))
            # Samples at most cell/2 apart: every cell the edge crosses holds a sample or
            # neighbours a cell that does, so marking samples and dilating by one cell
            # covers all crossed cells.
            steps = np.ceil(length / (0.5 * cell)).astype(np.intp) + 1
            edge = np.repeat(np.arange(len(a)), steps)
            offsets = np.arange(int(steps.sum())) - np.repeat(np.cumsum(steps) - steps, steps)
            t = offsets / np.maximum(steps[edge] - 1, 1)
            samples = a[edge] + t[:, None] * (b[edge] - a[edge])
            ix, iy = grid.index(samples[:, 0]), grid.index(samples[:, 1])
            keep = (ix >= -1) & (ix <= size) & (iy >= -1) & (iy <= size)
            ix, iy = ix[keep], iy[keep]
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    jx, jy = ix + dx, iy + dy
                    ok = (jx >= 0) & (jx < size) & (jy >= 0) & (jy < size)
                    marked[jx[ok], jy[ok]] = True
        return marked

    def _centre_inside(self) -> NDArray[np.bool_]:
        grid = self._grid
        size, cell, r = grid.size, grid.cell_size, grid.extent
        inside = np.zeros((size, size), dtype=bool)
        for polygon in self.polygons:
            x, y = polygon[:, 0], polygon[:, 1]
            first = max(int(np.floor((x.min() + r) / cell)), 0)
            last = min(int(np.floor((x.max() + r) / cell)), size - 1)
            if last < first:
                continue
            column, low, high = _scan_intervals(x, y, first, last - first + 1, cell, r)
            # Cells whose centre (on the scan line) lies inside [low, high].
            start = np.maximum(np.ceil((low + r) / cell - 0.5), 0).astype(np.intp)
            stop = np.minimum(np.floor((high + r) / cell - 0.5), size - 1).astype(np.intp)
            keep = start <= stop
            _fill_runs(inside, column[keep], start[keep], stop[keep])
        return inside

    def free_cells(self, *, margin_cells: int = 1) -> NDArray[np.bool_]:
        """(size, size) bool: cells at least ``margin_cells`` cells away from the ROI.

        A free cell contains no point of the exact ROI nor of the rasterised one, and the
        ``margin_cells`` rings of cells around it are not in the raster and not crossed by
        a polygon edge either. Points drawn in free cells are therefore outside the ROI by
        both methods, with a gap of at least ``margin_cells * cell_size`` metres to every
        raster cell that is set. Cached per margin; read-only.
        """
        margin = _non_negative_int(margin_cells, "margin_cells")
        key = ("free", margin)
        free = self._cache.get(key)
        if free is None:
            touched, centre_inside = self._exact_grids
            blocked = _dilate(self.bitmap | touched | centre_inside, margin)
            free = self._cache[key] = ~blocked
            free.setflags(write=False)
        return free

    def interior_cells(self, *, margin_cells: int = 1) -> NDArray[np.bool_]:
        """(size, size) bool: cells deep inside the ROI by both methods.

        A cell qualifies when it and the ``margin_cells`` rings around it are set in the
        raster, lie wholly inside the exact ROI and are crossed by no polygon edge.
        Cached per margin; read-only.
        """
        margin = _non_negative_int(margin_cells, "margin_cells")
        key = ("interior", margin)
        interior = self._cache.get(key)
        if interior is None:
            touched, centre_inside = self._exact_grids
            solid = self.bitmap & centre_inside & ~touched
            # The spare last column and row lie beyond raster_range: never in the raster.
            solid[-1, :] = False
            solid[:, -1] = False
            interior = self._cache[key] = ~_dilate(~solid, margin)
            interior.setflags(write=False)
        return interior

    def cell_origins(
        self,
        which: Literal["free", "interior"],
        *,
        margin_cells: int = 1,
        max_range: float | None = None,
    ) -> NDArray[np.float64]:
        """Lower-left corners of the free or interior cells, for sampling points in them.

        Parameters
        ----------
        which : {"free", "interior"}
          Cells of :meth:`free_cells` or :meth:`interior_cells`.
        margin_cells : int
        max_range : float, optional
          Keep only cells that reach within this distance of the sensor (the origin).

        Returns
        -------
        (k, 2) float64
          In row-major cell order; cached per arguments, read-only.
        """
        if which not in ("free", "interior"):
            raise InvalidArgument(f"which={which!r} must be 'free' or 'interior'")
        limit = None if max_range is None else _positive_float(max_range, "max_range")
        key = ("origins", which, margin_cells, limit)
        origins = self._cache.get(key)
        if origins is None:
            if which == "free":
                cells = self.free_cells(margin_cells=margin_cells)
            else:
                cells = self.interior_cells(margin_cells=margin_cells)
            # Lower cell edges per axis: the same values cell_origin() gives.
            index = np.arange(self.grid_size)
            lower = self.cell_origin(index, index)[:, 0]
            if limit is not None:
                # Closest point of each cell to the origin, per axis: the range test is
                # one (size, size) comparison instead of one per cell.
                squared = np.clip(0.0, lower, lower + self.cell_size) ** 2
                cells = cells & (squared[:, None] + squared[None, :] <= limit**2)
            ix, iy = np.nonzero(cells)
            origins = self._cache[key] = np.stack([lower[ix], lower[iy]], axis=1)
            origins.setflags(write=False)
        return origins

    # -- value semantics -------------------------------------------------------------------

    def equals(self, other: object) -> bool:
        """Same polygons (vertex for vertex) and the same rasterisation parameters."""
        if not isinstance(other, ROI):
            return False
        return (
            (self.cell_size, self.extend_dist, self.raster_range)
            == (other.cell_size, other.extend_dist, other.raster_range)
            and len(self.polygons) == len(other.polygons)
            and all(
                np.array_equal(a, b) for a, b in zip(self.polygons, other.polygons, strict=True)
            )
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ROI):
            return NotImplemented
        return self.equals(other)

    def __getstate__(self) -> dict[str, Any]:
        # Bitmaps are recomputed on demand; pickles (xdist, campaigns) stay small.
        return {name: getattr(self, name) for name in self.__slots__ if name != "_cache"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for name, value in state.items():
            object.__setattr__(self, name, value)
        self._cache = {}

    def __hash__(self) -> int:
        polygons = tuple(p.tobytes() for p in self.polygons)
        return hash((self.cell_size, self.extend_dist, self.raster_range, polygons))

    def describe(self) -> str:
        """Short description for failure messages."""
        counts = (
            "+".join(str(len(p)) for p in self.polygons)
            if len(self.polygons) <= 6
            else str(sum(len(p) for p in self.polygons))
        )
        (x0, y0), (x1, y1) = self.bounds
        return (
            f"ROI({len(self.polygons)} polygon(s), {counts} vertices, "
            f"x {x0:.1f}..{x1:.1f}, y {y0:.1f}..{y1:.1f}, cell {self.cell_size} m)"
        )

    def __repr__(self) -> str:
        return self.describe()


def _scan_intervals(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    first_column: int,
    count: int,
    cell: float,
    extent: float,
) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
    """Even-odd crossing intervals of one polygon on scan lines through column centres.

    Scan line ``c`` (``first_column <= c < first_column + count``) is ``u = (c + 0.5) *
    cell - extent``. Returns ``(column, low, high)``: one row per interval of ``v``.
    """
    u0, v0 = u, v
    u1, v1 = np.roll(u, -1), np.roll(v, -1)
    lo_u, hi_u = np.minimum(u0, u1), np.maximum(u0, u1)
    # Columns whose centre c satisfies lo_u <= c < hi_u (half-open: each vertex once).
    begin = np.ceil((lo_u + extent) / cell - 0.5).astype(np.intp)
    end = np.ceil((hi_u + extent) / cell - 0.5).astype(np.intp)
    begin = np.maximum(begin, first_column)
    end = np.minimum(end, first_column + count)
    spans = np.maximum(end - begin, 0)
    total = int(spans.sum())
    if total == 0:
        empty = np.empty(0)
        return np.empty(0, dtype=np.intp), empty, empty
    edge = np.repeat(np.arange(len(u)), spans)
    column = begin[edge] + (np.arange(total) - np.repeat(np.cumsum(spans) - spans, spans))
    centre = (column + 0.5) * cell - extent
    du = u1[edge] - u0[edge]
    crossing = v0[edge] + (centre - u0[edge]) * (v1[edge] - v0[edge]) / du
    order = np.lexsort((crossing, column))
    column, crossing = column[order], crossing[order]
    # Every scan line crosses a closed polygon an even number of times.
    return column[0::2], crossing[0::2], crossing[1::2]


def _fill_runs(
    grid: NDArray[np.bool_],
    row: NDArray[np.intp],
    start: NDArray[np.intp],
    stop: NDArray[np.intp],
) -> None:
    """Set ``grid[row, start:stop + 1]`` for every run, with a difference array."""
    if len(row) == 0:
        return
    size = grid.shape[1]
    start = np.clip(start, 0, size - 1)
    stop = np.clip(stop, 0, size - 1)
    diff = np.zeros((grid.shape[0], size + 1), dtype=np.int32)
    np.add.at(diff, (row, start), 1)
    np.add.at(diff, (row, stop + 1), -1)
    grid |= np.cumsum(diff[:, :size], axis=1) > 0


def _dilate(mask: NDArray[np.bool_], cells: int) -> NDArray[np.bool_]:
    """Square (Chebyshev) dilation by ``cells`` cells; outside the grid counts as empty."""
    if cells == 0:
        return mask.copy()
    return maximum_filter(mask, size=2 * cells + 1, mode="constant", cval=False)


def _road_pieces(road: Any, name: str) -> list[NDArray[np.float64]]:
    try:
        centerline = np.asarray(road.centerline, dtype=np.float64)
        width = float(road.width)
    except AttributeError:
        raise InvalidArgument(
            f"{name} needs .centerline ((k, 2) metres) and .width (metres), got "
            f"{type(road).__name__}"
        ) from None
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"{name}: bad centerline or width ({error})") from None
    if centerline.ndim != 2 or centerline.shape[1] != 2 or len(centerline) < 2:
        raise InvalidArgument(
            f"{name}.centerline must have shape (k >= 2, 2), got {centerline.shape}"
        )
    if not np.isfinite(centerline).all():
        raise InvalidArgument(f"{name}.centerline has non-finite values")
    if not (math.isfinite(width) and width > 0):
        raise InvalidArgument(f"{name}.width={width} must be a positive number of metres")
    half = width / 2.0
    keep = np.concatenate([[True], np.abs(np.diff(centerline, axis=0)).max(axis=1) > 1e-9])
    points = centerline[keep]
    if len(points) < 2:
        raise InvalidArgument(f"{name}.centerline has fewer than 2 distinct points")
    pieces = []
    for a, b in itertools.pairwise(points):
        direction = (b - a) / np.linalg.norm(b - a)
        normal = np.array([-direction[1], direction[0]]) * half
        pieces.append(np.stack([a - normal, b - normal, b + normal, a + normal]))
    angles = np.linspace(0.0, 2 * math.pi, _JOIN_SIDES, endpoint=False)
    circle = np.stack([np.cos(angles), np.sin(angles)], axis=1) * half
    pieces.extend(vertex + circle for vertex in points)
    return pieces


def _positive_float(value: Any, name: str) -> float:
    number = _finite_float(value, name)
    if number <= 0:
        raise InvalidArgument(f"{name}={value!r} must be > 0")
    return number


def _finite_float(value: Any, name: str) -> float:
    if isinstance(value, bool):
        raise InvalidArgument(f"{name}={value!r} must be a number")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidArgument(f"{name}={value!r} must be a number") from None
    if not math.isfinite(number):
        raise InvalidArgument(f"{name}={value!r} must be finite")
    return number


def _non_negative_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidArgument(f"{name}={value!r} must be a non-negative int")
    return int(value)
