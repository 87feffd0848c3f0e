"""Drivable OSM ways as :class:`Road` geometries: centre lines in local metres, widths, lanes."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.osm.projection import LocalProjection
from pytest_metamorphic.driving.osm.reader import (
    _DEFAULT_MAX_BYTES,
    OsmData,
    OsmNode,
    OsmWay,
    read_osm,
)
from pytest_metamorphic.driving.osm.tags import (
    _defaults,
    parse_lanes,
    parse_margins,
    parse_oneway,
    parse_parking,
    parse_sidewalks,
    parse_width,
)

__all__ = ["Road", "load_roads"]


@dataclass(frozen=True, eq=False)
class Road:
    """One OSM way with a ``highway`` tag, in local metres.

    Attributes
    ----------
    way_id : int
    name : str
        ``name`` tag, else ``ref``, else ``""``.
    highway : str
        The ``highway`` class (``residential``, ``secondary``, ...).
    centerline : (k, 2) float64
        Vertices in local metres (x east, y north), k >= 2, in the direction of travel
        for one-way roads (``oneway=-1`` ways are reversed).
    width : float
        Carriageway width in metres (kerb to kerb).
    lanes : int
        Number of traffic lanes (both directions).
    oneway : bool
    width_source : {"width", "lanes", "default"}
        Where ``width`` came from: the ``width`` tag, ``lanes`` x the class's lane width,
        or the class's default lane count x lane width.
    node_ids : tuple of int
        The OSM nodes of ``centerline``, in the same order.
    tags : mapping
    projection : LocalProjection
        The frame of ``centerline``.
    margins : (float, float)
        Cycle and parking lanes on the carriageway, right / left of the direction of
        ``centerline`` (:func:`~pytest_metamorphic.driving.osm.tags.parse_margins`).
    parking : (float, float)
        The parking lanes among ``margins`` (at the kerbs; :func:`parse_parking`).
    sidewalks : (float, float)
        Footways beyond the right / left kerb (0: none mapped; :func:`parse_sidewalks`).
    """

    way_id: int
    name: str
    highway: str
    centerline: NDArray[np.float64]
    width: float
    lanes: int
    oneway: bool
    width_source: Literal["width", "lanes", "default"]
    node_ids: tuple[int, ...]
    tags: Mapping[str, str]
    projection: LocalProjection
    margins: tuple[float, float] = (0.0, 0.0)
    parking: tuple[float, float] = (0.0, 0.0)
    sidewalks: tuple[float, float] = (0.0, 0.0)

    @property
    def length(self) -> float:
        """Length of the centreline in metres."""
        return float(np.linalg.norm(np.diff(self.centerline, axis=0), axis=1).sum())

    @property
    def lane_width(self) -> float:
        return (self.width - sum(self.margins)) / self.lanes

    def describe(self) -> str:
        label = self.name or f"way {self.way_id}"
        direction = "one-way" if self.oneway else "two-way"
        strips = ""
        if any(self.margins):
            strips = ", cycle/parking lanes {:g} / {:g} m".format(*self.margins)
        return (
            f"{label} ({self.highway}, {self.length:.0f} m, {self.width:.2f} m wide from "
            f"{self.width_source}, {self.lanes} lane(s){strips}, {direction})"
        )

    def __repr__(self) -> str:
        return f"Road(way_id={self.way_id}, {self.describe()})"

    def with_tags(self, extra: Mapping[str, str]) -> Road:
        """This way as if its tags also held ``extra`` (e.g. a parking lane the map lacks).

        Width, lanes, cycle and parking lanes and sidewalks are derived again from the
        merged tags; the geometry stays. Used to state a scenario's assumptions about a
        street openly instead of editing the map.
        """
        if not isinstance(extra, Mapping) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in extra.items()
        ):
            raise InvalidArgument(f"extra={extra!r} must map tag names to tag values (str)")
        tags = MappingProxyType({**self.tags, **extra})
        oneway, reverse = parse_oneway(tags)
        cross = _cross_section(tags, self.highway, oneway, reverse)
        return dataclasses.replace(self, tags=tags, oneway=oneway, **cross)  # type: ignore[arg-type]


def _highway_filter(highway: str | Iterable[str] | None) -> frozenset[str] | None:
    if highway is None:
        return None
    if isinstance(highway, str):
        return frozenset({highway})
    try:
        values = frozenset(highway)
    except TypeError:
        raise InvalidArgument(
            f"highway={highway!r} must be None, a highway class or a collection of them"
        ) from None
    if not all(isinstance(value, str) for value in values):
        raise InvalidArgument(f"highway={highway!r} must contain only strings")
    return values


def _resolve_projection(
    data: OsmData, origin: LocalProjection | tuple[float, float] | None
) -> LocalProjection:
    if origin is None:
        return data.projection()
    if isinstance(origin, LocalProjection):
        return origin
    try:
        lat0, lon0 = (float(v) for v in origin)
    except (TypeError, ValueError):
        raise InvalidArgument(
            f"origin={origin!r} must be None, a LocalProjection or a (lat, lon) pair"
        ) from None
    return LocalProjection(lat0, lon0)


def _longest_present_run(way: OsmWay, nodes: Mapping[int, OsmNode]) -> tuple[int, ...]:
    """The longest run of consecutive node refs present in the file (extracts clip ways)."""
    best: list[int] = []
    run: list[int] = []
    for node_id in way.node_ids:
        if node_id in nodes:
            run.append(node_id)
            if len(run) > len(best):
                best = list(run)
        else:
            run = []
    return tuple(best)


def _selected_ways(
    data: OsmData, wanted: frozenset[str] | None
) -> Iterator[tuple[OsmWay, tuple[int, ...]]]:
    for way in data.ways:
        highway = way.tags.get("highway")
        if highway is None or way.tags.get("area") == "yes":
            continue
        if wanted is not None and highway not in wanted:
            continue
        node_ids = _longest_present_run(way, data.nodes)
        # Drop repeated consecutive nodes: they make zero-length segments.
        node_ids = tuple(n for i, n in enumerate(node_ids) if i == 0 or n != node_ids[i - 1])
        if len(node_ids) >= 2:
            yield way, node_ids


# A ``width`` tag that leaves less than this per lane beside the tagged cycle and parking
# lanes measured the traffic lanes only: the strips are added to it.
_MIN_TAGGED_LANE = 2.5


def _road_width(
    tags: Mapping[str, str], highway: str, oneway: bool, margins: tuple[float, float]
) -> tuple[float, int, str]:
    defaults = _defaults(highway)
    lanes_tag = parse_lanes(tags.get("lanes"))
    lanes = lanes_tag or (defaults.oneway_lanes if oneway else defaults.lanes)
    width_tag = parse_width(tags.get("width"))
    if width_tag is not None:
        if width_tag - sum(margins) < _MIN_TAGGED_LANE * lanes:
            width_tag += sum(margins)
        return width_tag, lanes, "width"
    source = "lanes" if lanes_tag else "default"
    return lanes * defaults.lane_width + sum(margins), lanes, source


def _cross_section(
    tags: Mapping[str, str], highway: str, oneway: bool, reverse: bool
) -> dict[str, object]:
    """A way's carriageway from its tags: width, lanes, margins, parking, sidewalks."""
    margins = parse_margins(tags, oneway=oneway, reverse=reverse)
    width, lanes, source = _road_width(tags, highway, oneway, margins)
    return {
        "width": float(width),
        "lanes": int(lanes),
        "width_source": source,
        "margins": margins,
        "parking": parse_parking(tags, reverse=reverse),
        "sidewalks": parse_sidewalks(tags, reverse=reverse),
    }


def load_roads(
    path: str | Path,
    *,
    highway: str | Iterable[str] | None = None,
    origin: LocalProjection | tuple[float, float] | None = None,
    max_bytes: int = _DEFAULT_MAX_BYTES,
) -> list[Road]:
    """Read the roads (ways with a ``highway`` tag) of an OSM file, in local metres.

    Parameters
    ----------
    path : str or Path
        ``.osm`` or ``.osm.bz2``.
    highway : str or collection of str, optional
        Keep only these ``highway`` classes, e.g. :data:`DRIVABLE_HIGHWAYS`. Default: every
        linear way with a ``highway`` tag (``area=yes`` squares are skipped).
    origin : LocalProjection or (lat, lon), optional
        Projection centre; default the centre of the file's nodes.
    max_bytes : int
        See :func:`read_osm`.

    Returns
    -------
    list of Road
        In file order. Extracts clip ways at their bounding box and may reference nodes
        the file does not contain: such a way keeps its longest run of present nodes, and
        ways left with fewer than two nodes are skipped.

    Notes
    -----
    Width: the ``width`` tag (see :func:`parse_width`), else ``lanes`` x the class's lane
    width, else the class's default lane count (fewer for one-way roads) x lane width
    (:data:`HIGHWAY_DEFAULTS`); plus, without a ``width`` tag, the cycle and parking lanes
    on the carriageway (:func:`parse_margins`), which the traffic lanes do not include.
    """
    wanted = _highway_filter(highway)
    data = read_osm(path, max_bytes=max_bytes)
    projection = _resolve_projection(data, origin)
    roads = []
    for way, node_ids in _selected_ways(data, wanted):
        oneway, reverse = parse_oneway(way.tags)
        if reverse:
            node_ids = node_ids[::-1]
        lat = np.array([data.nodes[n].lat for n in node_ids])
        lon = np.array([data.nodes[n].lon for n in node_ids])
        highway_class = way.tags["highway"]
        roads.append(
            Road(
                way_id=way.id,
                name=way.tags.get("name") or way.tags.get("ref") or "",
                highway=highway_class,
                centerline=projection.to_local(lat, lon),
                oneway=oneway,
                node_ids=node_ids,
                tags=way.tags,
                projection=projection,
                **_cross_section(way.tags, highway_class, oneway, reverse),  # type: ignore[arg-type]
            )
        )
    return roads
