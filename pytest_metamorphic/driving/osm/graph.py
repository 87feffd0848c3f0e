"""Street graphs from OSM ways: nodes and edges with lengths, shortest paths, nearest nodes."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.driving.osm.projection import LocalProjection
from pytest_metamorphic.driving.osm.reader import _DEFAULT_MAX_BYTES, read_osm
from pytest_metamorphic.driving.osm.roads import (
    _highway_filter,
    _resolve_projection,
    _selected_ways,
)
from pytest_metamorphic.driving.osm.tags import DRIVABLE_HIGHWAYS, parse_oneway

__all__ = ["StreetGraph", "street_graph"]


@dataclass(frozen=True, eq=False)
class StreetGraph:
    """The street network as a graph of OSM nodes joined by way segments.

    Nodes are every OSM node on a selected way (ways meet where they share a node), so
    edge geometry is exact and no simplification is needed. Use :meth:`csgraph` with
    :mod:`scipy.sparse.csgraph`, or :meth:`shortest_path` directly.

    Attributes
    ----------
    node_ids : (n,) int64
        OSM node id of each graph node.
    xy : (n, 2) float64
        Local metres.
    edges : (m, 2) int64
        ``(from, to)`` indices into ``node_ids``. In a directed graph one-way ways only
        have edges in their direction of travel; two-way ways have both.
    lengths : (m,) float64
        Edge lengths in metres.
    way_ids : (m,) int64
        The OSM way each edge comes from.
    directed : bool
    projection : LocalProjection
    """

    node_ids: NDArray[np.int64]
    xy: NDArray[np.float64]
    edges: NDArray[np.int64]
    lengths: NDArray[np.float64]
    way_ids: NDArray[np.int64]
    directed: bool
    projection: LocalProjection

    def __len__(self) -> int:
        return len(self.node_ids)

    def index_of(self, node_id: int) -> int:
        """Graph index of an OSM node id."""
        found = np.flatnonzero(self.node_ids == node_id)
        if found.size == 0:
            raise InvalidArgument(f"node_id={node_id} is not in the street graph")
        return int(found[0])

    def nearest(self, xy: Any) -> int:
        """Index of the graph node closest to a point ``(2,)`` in local metres."""
        point = np.asarray(xy, dtype=np.float64)
        if point.shape != (2,) or not np.isfinite(point).all():
            raise InvalidArgument(f"xy={xy!r} must be a finite (x, y) pair")
        return int(np.argmin(((self.xy - point) ** 2).sum(axis=1)))

    def csgraph(self) -> Any:
        """An ``(n, n)`` ``scipy.sparse.csr_array`` of edge lengths (parallel edges: the shortest).

        For ``directed=False`` graphs it is symmetric; pass ``directed=False`` to scipy's
        routines either way if you want to ignore one-way restrictions.
        """
        from scipy.sparse import csr_array

        n = len(self.node_ids)
        if len(self.edges) == 0:
            return csr_array((n, n), dtype=np.float64)
        # csr construction sums duplicates; keep the minimum over parallel edges instead.
        order = np.lexsort((self.lengths, self.edges[:, 1], self.edges[:, 0]))
        edges, lengths = self.edges[order], self.lengths[order]
        first = np.ones(len(edges), dtype=bool)
        first[1:] = (edges[1:] != edges[:-1]).any(axis=1)
        edges, lengths = edges[first], lengths[first]
        return csr_array((lengths, (edges[:, 0], edges[:, 1])), shape=(n, n))

    def shortest_path(self, source: int, target: int) -> tuple[list[int], float]:
        """Node indices of a shortest route from ``source`` to ``target`` and its length.

        Raises :class:`InvalidArgument` for bad indices and :class:`DataError` when the
        target cannot be reached (disconnected network, or only against one-way streets).
        """
        from scipy.sparse.csgraph import dijkstra

        n = len(self.node_ids)
        for name, value in (("source", source), ("target", target)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise InvalidArgument(f"{name}={value!r} must be a node index (int)")
            if not 0 <= value < n:
                raise InvalidArgument(f"{name}={value} is out of range for {n} nodes")
        distances, predecessors = dijkstra(
            self.csgraph(), directed=self.directed, indices=int(source), return_predecessors=True
        )
        if not np.isfinite(distances[target]):
            raise DataError(
                f"node {int(self.node_ids[target])} cannot be reached from node "
                f"{int(self.node_ids[source])}"
            )
        route = [int(target)]
        while route[-1] != source:
            route.append(int(predecessors[route[-1]]))
        return route[::-1], float(distances[target])

    def path_xy(self, route: Iterable[int]) -> NDArray[np.float64]:
        """``(k, 2)`` coordinates of a route of node indices (e.g. to build a road from it)."""
        return self.xy[np.asarray(list(route), dtype=np.int64)]


def street_graph(
    path: str | Path,
    *,
    highway: str | Iterable[str] | None = DRIVABLE_HIGHWAYS,
    directed: bool = True,
    origin: LocalProjection | tuple[float, float] | None = None,
    max_bytes: int = _DEFAULT_MAX_BYTES,
) -> StreetGraph:
    """The street graph of an OSM file, for routing.

    Parameters
    ----------
    path : str or Path
    highway : str or collection of str, optional
        Classes to include; default :data:`DRIVABLE_HIGHWAYS`; None for every highway.
    directed : bool
        Respect one-way streets (default). With False every segment is usable both ways
        (walking).
    origin : LocalProjection or (lat, lon), optional
        See :func:`load_roads`.
    """
    if not isinstance(directed, bool):
        raise InvalidArgument(f"directed={directed!r} must be a bool")
    wanted = _highway_filter(highway)
    data = read_osm(path, max_bytes=max_bytes)
    projection = _resolve_projection(data, origin)
    index: dict[int, int] = {}
    starts: list[int] = []
    ends: list[int] = []
    ways: list[int] = []
    for way, node_ids in _selected_ways(data, wanted):
        for node_id in node_ids:
            index.setdefault(node_id, len(index))
        oneway, reverse = parse_oneway(way.tags)
        if reverse:
            node_ids = node_ids[::-1]
        a = [index[n] for n in node_ids[:-1]]
        b = [index[n] for n in node_ids[1:]]
        starts += a
        ends += b
        ways += [way.id] * len(a)
        if not (directed and oneway):
            starts += b
            ends += a
            ways += [way.id] * len(a)
    node_ids_arr = np.fromiter(index, dtype=np.int64, count=len(index))
    lat = np.array([data.nodes[int(n)].lat for n in node_ids_arr])
    lon = np.array([data.nodes[int(n)].lon for n in node_ids_arr])
    xy = projection.to_local(lat, lon).reshape(-1, 2)
    edges = np.column_stack([starts, ends]).astype(np.int64).reshape(-1, 2)
    lengths = np.linalg.norm(xy[edges[:, 1]] - xy[edges[:, 0]], axis=1)
    return StreetGraph(
        node_ids=node_ids_arr,
        xy=xy,
        edges=edges,
        lengths=lengths,
        way_ids=np.asarray(ways, dtype=np.int64),
        directed=directed,
        projection=projection,
    )
