# Copyright 2026 The pytest-metamorphic Authors
# Derived from Apollo (https://github.com/ApolloAuto/apollo), Copyright 2017-2018 The Apollo
# Authors, licensed under the Apache License, Version 2.0.
# What it derives from: the HD-map ROI filter (hdmap_roi_filter.cc).
# Changed: re-implemented in Python and NumPy, with the differences stated below. See NOTICE.
# SPDX-License-Identifier: Apache-2.0
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

import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.roi.arguments import (
    _finite_float,
    _grid_arguments,
    _non_negative_int,
    _positive_float,
)
from pytest_metamorphic.lidar.roi.polygon import (
    _as_xy,
    _points_in_polygon,
    _segment_distance,
    _signed_area,
    validate_polygon,
)
from pytest_metamorphic.lidar.roi.raster import (
    CellSet,
    _dilate,
    _fill_runs,
    _Grid,
    _scan_intervals,
)
from pytest_metamorphic.lidar.roi.roads import _road_pieces

__all__ = ["ROI", "ContainmentMethod"]

ContainmentMethod = Literal["raster", "exact"]


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
        cell_size, raster_range = _grid_arguments(cell_size, raster_range)
        extend_dist = _finite_float(extend_dist, "extend_dist")
        if extend_dist < 0:
            raise InvalidArgument(f"extend_dist={extend_dist} must be >= 0")
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

        Notes
        -----
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
        return self._moved(lambda p: p @ np.array([[c, -s], [s, c]]).T)

    def mirrored(self) -> ROI:
        """The ROI reflected in the sensor's x axis (y -> -y), rasterised afresh.

        Vertex order is reversed so every polygon keeps its orientation.
        """
        return self._moved(lambda p: (p * np.array([1.0, -1.0]))[::-1])

    def translated(self, dx: float, dy: float) -> ROI:
        """The ROI shifted by ``(dx, dy)`` metres."""
        shift = np.array([_finite_float(dx, "dx"), _finite_float(dy, "dy")])
        return self._moved(lambda p: p + shift)

    def _moved(self, move: Any) -> ROI:
        """The ROI of the moved polygons, with the same raster settings (rasterised afresh)."""
        polygons = tuple(np.ascontiguousarray(move(p)) for p in self.polygons)
        return ROI(
            polygons,
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
        # Converted to float64 block by block in the lookup (NaN compares False: outside).
        points = _as_xy(xy, convert=False)
        if method == "raster":
            return self._grid.lookup(points, self._flat_bitmap)[1][0]
        if method == "exact":
            return self._contains_exact(points)
        raise InvalidArgument(f"method={method!r} must be 'raster' or 'exact'")

    def _contains_exact(self, xy: NDArray[Any]) -> NDArray[np.bool_]:
        touched, centre_inside = self._exact_grids
        exists, (result, crossed) = self._grid.lookup(xy, centre_inside.ravel(), touched.ravel())
        # A cell no edge touches lies wholly inside or wholly outside: its centre decides.
        undecided = np.flatnonzero(crossed | ~exists)
        if len(undecided):
            subset = np.asarray(xy[undecided, :2], dtype=np.float64)
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
        return self._grid.lower_edges(np.stack([np.asarray(ix), np.asarray(iy)], axis=-1))

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

    @property
    def _flat_bitmap(self) -> NDArray[np.bool_]:
        """The bitmap row-major as one vector (a view), for :meth:`_Grid.cells` indices."""
        return self.bitmap.reshape(-1)

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

    def cells(
        self,
        which: Literal["free", "interior"],
        *,
        margin_cells: int = 1,
        max_range: float | None = None,
    ) -> CellSet:
        """The free or interior cells, for sampling points in them.

        Parameters
        ----------
        which : {"free", "interior"}
          Cells of :meth:`free_cells` or :meth:`interior_cells`.
        margin_cells : int
        max_range : float, optional
          Keep only cells that reach within this distance of the sensor (the origin).

        Returns
        -------
        CellSet
          In row-major cell order; cached per arguments.
        """
        if which not in ("free", "interior"):
            raise InvalidArgument(f"which={which!r} must be 'free' or 'interior'")
        limit = None if max_range is None else _positive_float(max_range, "max_range")
        key = ("cells", which, margin_cells, limit)
        found = self._cache.get(key)
        if found is None:
            if which == "free":
                cells = self.free_cells(margin_cells=margin_cells)
            else:
                cells = self.interior_cells(margin_cells=margin_cells)
            if limit is not None:
                # Closest point of each cell to the origin, per axis: the range test is
                # one (size, size) comparison instead of one per cell.
                lower = self._grid.lower_edges(np.arange(self.grid_size))
                squared = np.clip(0.0, lower, lower + self.cell_size) ** 2
                cells = cells & (squared[:, None] + squared[None, :] <= limit**2)
            found = self._cache[key] = CellSet(np.flatnonzero(cells), self._grid)
        return found

    def cell_origins(
        self,
        which: Literal["free", "interior"],
        *,
        margin_cells: int = 1,
        max_range: float | None = None,
    ) -> NDArray[np.float64]:
        """Lower-left corners of the free or interior cells (see :meth:`cells`).

        Returns
        -------
        (k, 2) float64
          In row-major cell order; cached per arguments, read-only.
        """
        return self.cells(which, margin_cells=margin_cells, max_range=max_range).origins()

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
