"""A hardened reader for OpenStreetMap XML (``.osm`` and ``.osm.bz2``): roads and street graphs.

OSM files come from anywhere, so the parser is the standard library's expat with every
feature that lets a document reach beyond itself switched off: a DOCTYPE, an entity
declaration (internal or external, the "billion laughs" expansion bomb) or an external
entity reference is rejected with a :class:`~pytest_metamorphic.core.errors.DataError`
naming the file. Decompressed input is capped (``max_bytes``) against bz2 bombs.

Coordinates are projected to local metres with an equirectangular projection about the
data's centre (``x`` east, ``y`` north). Over the extent of a city-district extract (2 km)
it is within about 0.3 m of a proper transverse Mercator projection, far below OSM's own
accuracy. Pass ``origin=`` to put several files into one frame.

Public API::

    data = read_osm(path)                      # nodes, ways, bounds
    roads = load_roads(path, highway=DRIVABLE_HIGHWAYS)
    graph = street_graph(path)                 # nodes/edges with lengths, for routing
    nodes, length = graph.shortest_path(graph.nearest((0, 0)), graph.nearest((150, 80)))
"""

from __future__ import annotations

import bz2
import math
import re
import xml.parsers.expat
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import IO, Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument

__all__ = [
    "DRIVABLE_HIGHWAYS",
    "EARTH_RADIUS_M",
    "HIGHWAY_DEFAULTS",
    "LocalProjection",
    "OsmData",
    "OsmNode",
    "OsmWay",
    "Road",
    "StreetGraph",
    "load_roads",
    "parse_lanes",
    "parse_oneway",
    "parse_width",
    "read_osm",
    "street_graph",
]

#: Mean Earth radius (IUGG), metres.
EARTH_RADIUS_M = 6_371_008.8

_CHUNK = 1 << 20
_DEFAULT_MAX_BYTES = 512 << 20

#: ``highway=*`` values a car may drive on.
DRIVABLE_HIGHWAYS = frozenset(
    {
        "motorway", "motorway_link", "trunk", "trunk_link", "primary", "primary_link",
        "secondary", "secondary_link", "tertiary", "tertiary_link", "unclassified",
        "residential", "living_street", "service", "road", "busway",
    }
)  # fmt: skip


@dataclass(frozen=True)
class HighwayDefaults:
    """Per-class assumptions used when a way has no ``width`` tag.

    ``lane_width`` in metres; ``lanes`` for a two-way way and ``oneway_lanes`` for a one-way
    way (OSM's ``lanes`` counts both directions, so one-way roads default to fewer lanes).
    """

    lane_width: float
    lanes: int
    oneway_lanes: int


_ROAD = HighwayDefaults(3.0, 2, 1)
_PATH = HighwayDefaults(2.0, 1, 1)

#: Default lane width and lane counts per ``highway`` class (``*_link`` uses its base class).
#: Typical European/US design values; anything unlisted uses the ``residential`` entry.
HIGHWAY_DEFAULTS: Mapping[str, HighwayDefaults] = MappingProxyType(
    {
        "motorway": HighwayDefaults(3.75, 4, 2),
        "trunk": HighwayDefaults(3.5, 4, 2),
        "primary": HighwayDefaults(3.5, 2, 1),
        "secondary": HighwayDefaults(3.25, 2, 1),
        "tertiary": HighwayDefaults(3.0, 2, 1),
        "unclassified": _ROAD,
        "residential": _ROAD,
        "road": _ROAD,
        "living_street": HighwayDefaults(3.0, 1, 1),
        "service": HighwayDefaults(3.0, 1, 1),
        "busway": HighwayDefaults(3.5, 1, 1),
        "track": HighwayDefaults(2.5, 1, 1),
        "pedestrian": HighwayDefaults(3.0, 1, 1),
        "footway": _PATH,
        "path": _PATH,
        "bridleway": _PATH,
        "steps": _PATH,
        "corridor": _PATH,
        "cycleway": HighwayDefaults(1.5, 1, 1),
    }
)


# ---------------------------------------------------------------------------------------
# Projection


@dataclass(frozen=True)
class LocalProjection:
    """Equirectangular projection about ``(lat0, lon0)``: ``x`` east, ``y`` north, metres."""

    lat0: float
    lon0: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lat0) and -90.0 < self.lat0 < 90.0):
            raise InvalidArgument(f"lat0={self.lat0!r} must be a latitude in (-90, 90)")
        if not (math.isfinite(self.lon0) and -180.0 <= self.lon0 <= 180.0):
            raise InvalidArgument(f"lon0={self.lon0!r} must be a longitude in [-180, 180]")

    @classmethod
    def about(cls, lat: Iterable[float], lon: Iterable[float]) -> LocalProjection:
        """The projection about the centre of the bounding box of the given coordinates."""
        lat_arr = np.asarray(list(lat) if not isinstance(lat, np.ndarray) else lat, float)
        lon_arr = np.asarray(list(lon) if not isinstance(lon, np.ndarray) else lon, float)
        if lat_arr.size == 0:
            raise InvalidArgument("cannot centre a projection on zero coordinates")
        return cls(
            float((lat_arr.min() + lat_arr.max()) / 2), float((lon_arr.min() + lon_arr.max()) / 2)
        )

    def to_local(self, lat: Any, lon: Any) -> NDArray[np.float64]:
        """Project latitudes/longitudes (degrees) to ``(..., 2)`` local metres."""
        lat_arr = np.asarray(lat, dtype=np.float64)
        lon_arr = np.asarray(lon, dtype=np.float64)
        # Wrap longitude differences so data straddling the antimeridian stays local.
        dlon = (lon_arr - self.lon0 + 180.0) % 360.0 - 180.0
        x = np.radians(dlon) * EARTH_RADIUS_M * math.cos(math.radians(self.lat0))
        y = np.radians(lat_arr - self.lat0) * EARTH_RADIUS_M
        return np.stack([x, y], axis=-1)

    def to_geographic(self, xy: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Inverse of :meth:`to_local`: ``(lat, lon)`` in degrees for ``(..., 2)`` metres."""
        points = np.asarray(xy, dtype=np.float64)
        if points.shape[-1:] != (2,):
            raise InvalidArgument(f"xy must have shape (..., 2), got {points.shape}")
        lat = self.lat0 + np.degrees(points[..., 1] / EARTH_RADIUS_M)
        lon = self.lon0 + np.degrees(
            points[..., 0] / (EARTH_RADIUS_M * math.cos(math.radians(self.lat0)))
        )
        return lat, lon


# ---------------------------------------------------------------------------------------
# Raw OSM data


@dataclass(frozen=True)
class OsmNode:
    """An OSM node: id, WGS84 latitude/longitude in degrees, tags."""

    id: int
    lat: float
    lon: float
    tags: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class OsmWay:
    """An OSM way: id, the ordered node ids it references, tags."""

    id: int
    node_ids: tuple[int, ...]
    tags: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class OsmData:
    """Everything :func:`read_osm` keeps from a file.

    Attributes
    ----------
    path : str
    nodes : mapping of node id -> OsmNode
    ways : tuple of OsmWay, in file order
    bounds : (minlat, minlon, maxlat, maxlon) or None
        The file's ``<bounds>`` element, when present.
    relation_count : int
        Relations are counted, not kept.
    """

    path: str
    nodes: Mapping[int, OsmNode]
    ways: tuple[OsmWay, ...]
    bounds: tuple[float, float, float, float] | None
    relation_count: int

    def projection(self) -> LocalProjection:
        """The local projection about the centre of the nodes' bounding box."""
        if not self.nodes:
            raise DataError("has no nodes to centre a projection on", path=self.path)
        lat = np.fromiter((n.lat for n in self.nodes.values()), float, len(self.nodes))
        lon = np.fromiter((n.lon for n in self.nodes.values()), float, len(self.nodes))
        return LocalProjection.about(lat, lon)


class _Handler:
    """expat callbacks building :class:`OsmData`; refuses anything entity-related."""

    def __init__(self, path: str, parser: xml.parsers.expat.XMLParserType) -> None:
        self.path = path
        self.parser = parser
        self.nodes: dict[int, OsmNode] = {}
        self.ways: list[OsmWay] = []
        self.bounds: tuple[float, float, float, float] | None = None
        self.relation_count = 0
        self.depth = 0
        self.root_seen = False
        # The element whose <tag>/<nd> children are being collected.
        self.current: str | None = None
        self.current_attrs: dict[str, str] = {}
        self.current_tags: dict[str, str] = {}
        self.current_refs: list[int] = []

    # -- hostile constructs ------------------------------------------------------------
    def _refuse(self, what: str) -> None:
        raise DataError(
            f"{what} at line {self.parser.CurrentLineNumber}: OSM XML never needs one, and "
            "entity expansion or external entities are refused for safety",
            path=self.path,
        )

    def doctype(self, name: str, *_: Any) -> None:
        self._refuse(f"DOCTYPE declaration <!DOCTYPE {name}>")

    def entity_decl(self, name: str, *_: Any) -> None:
        self._refuse(f"entity declaration <!ENTITY {name}>")

    def external_entity(self, *_: Any) -> int:
        self._refuse("external entity reference")
        return 0

    # -- content -----------------------------------------------------------------------
    def _error(self, message: str) -> DataError:
        return DataError(f"line {self.parser.CurrentLineNumber}: {message}", path=self.path)

    def _int(self, attrs: Mapping[str, str], key: str, element: str) -> int:
        try:
            return int(attrs[key])
        except KeyError:
            raise self._error(f"<{element}> has no {key!r} attribute") from None
        except ValueError:
            raise self._error(f"<{element}> {key}={attrs[key]!r} is not an integer") from None

    def _float(self, attrs: Mapping[str, str], key: str, element: str) -> float:
        try:
            value = float(attrs[key])
        except KeyError:
            raise self._error(f"<{element}> has no {key!r} attribute") from None
        except ValueError:
            raise self._error(f"<{element}> {key}={attrs[key]!r} is not a number") from None
        if not math.isfinite(value):
            raise self._error(f"<{element}> {key}={attrs[key]!r} is not finite")
        return value

    def start(self, name: str, attrs: dict[str, str]) -> None:
        self.depth += 1
        if self.depth == 1:
            if name != "osm":
                raise self._error(f"root element is <{name}>, not <osm>: not an OSM XML file")
            self.root_seen = True
            return
        if name in ("node", "way", "relation") and self.depth == 2:
            self.current = name
            self.current_attrs = attrs
            self.current_tags = {}
            self.current_refs = []
        elif name == "tag" and self.current is not None:
            if "k" not in attrs or "v" not in attrs:
                raise self._error(f"<tag> in a <{self.current}> needs both k and v")
            self.current_tags[attrs["k"]] = attrs["v"]
        elif name == "nd" and self.current == "way":
            self.current_refs.append(self._int(attrs, "ref", "nd"))
        elif name == "bounds" and self.depth == 2:
            self.bounds = tuple(  # type: ignore[assignment]
                self._float(attrs, key, "bounds")
                for key in ("minlat", "minlon", "maxlat", "maxlon")
            )

    def end(self, name: str) -> None:
        if self.depth == 2 and name == self.current:
            self._finish(name)
            self.current = None
        self.depth -= 1

    def _finish(self, name: str) -> None:
        attrs = self.current_attrs
        # Deleted or invisible objects appear in editor and history files; they are not map data.
        if attrs.get("action") == "delete" or attrs.get("visible") == "false":
            return
        if name == "relation":
            self.relation_count += 1
            return
        element_id = self._int(attrs, "id", name)
        tags = MappingProxyType(self.current_tags)
        if name == "node":
            lat = self._float(attrs, "lat", "node")
            lon = self._float(attrs, "lon", "node")
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                raise self._error(f"node {element_id} has lat={lat}, lon={lon} out of range")
            if element_id in self.nodes:
                raise self._error(f"node id {element_id} appears twice")
            self.nodes[element_id] = OsmNode(element_id, lat, lon, tags)
        else:
            self.ways.append(OsmWay(element_id, tuple(self.current_refs), tags))


def _open(path: Path) -> IO[bytes]:
    with open(path, "rb") as probe:
        magic = probe.read(3)
    if path.suffix == ".bz2" or magic == b"BZh":
        return bz2.open(path, "rb")
    return open(path, "rb")


def _chunks(stream: IO[bytes], path: Path, max_bytes: int) -> Iterator[bytes]:
    total = 0
    while True:
        try:
            chunk = stream.read(_CHUNK)
        except (OSError, EOFError, ValueError) as error:
            raise DataError(f"cannot decompress: {error}", path=path) from None
        if not chunk:
            return
        total += len(chunk)
        if total > max_bytes:
            raise DataError(
                f"is larger than max_bytes={max_bytes} once decompressed; pass a larger "
                "max_bytes if the file is trusted",
                path=path,
            )
        yield chunk


def read_osm(path: str | Path, *, max_bytes: int = _DEFAULT_MAX_BYTES) -> OsmData:
    """Parse an OSM XML file (plain or bz2-compressed) with a hardened expat parser.

    Parameters
    ----------
    path : str or Path
        ``.osm`` or ``.osm.bz2`` (bz2 is also recognised by its magic bytes).
    max_bytes : int
        Refuse files larger than this once decompressed (default 512 MiB).

    Raises
    ------
    DataError
        The file is missing, not OSM XML, malformed, or contains a DOCTYPE, an entity
        declaration or an external entity reference. The message names the file and line.
    """
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, int) or max_bytes <= 0:
        raise InvalidArgument(f"max_bytes={max_bytes!r} must be a positive int")
    path = Path(path)
    if not path.is_file():
        raise DataError("no such file", path=path)
    parser = xml.parsers.expat.ParserCreate()
    handler = _Handler(str(path), parser)
    parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
    parser.StartDoctypeDeclHandler = handler.doctype
    parser.EntityDeclHandler = handler.entity_decl
    parser.UnparsedEntityDeclHandler = handler.entity_decl
    parser.ExternalEntityRefHandler = handler.external_entity
    parser.StartElementHandler = handler.start
    parser.EndElementHandler = handler.end
    parser.buffer_text = True
    try:
        with _open(path) as stream:
            for chunk in _chunks(stream, path, max_bytes):
                parser.Parse(chunk, False)
            parser.Parse(b"", True)
    except xml.parsers.expat.ExpatError as error:
        raise DataError(
            f"malformed XML at line {error.lineno}, column {error.offset}: "
            f"{xml.parsers.expat.ErrorString(error.code)}",
            path=path,
        ) from None
    if not handler.root_seen:
        raise DataError("is empty: no <osm> root element", path=path)
    return OsmData(
        str(path),
        MappingProxyType(handler.nodes),
        tuple(handler.ways),
        handler.bounds,
        handler.relation_count,
    )


# ---------------------------------------------------------------------------------------
# Tag interpretation

_NUMBER = r"(\d+(?:\.\d+)?|\.\d+)"
_METRES = re.compile(rf"^{_NUMBER}\s*(m|meters?|metres?)?$")
_FEET = re.compile(rf"^{_NUMBER}\s*(ft|feet|foot|')$")
_FEET_INCHES = re.compile(rf"^{_NUMBER}\s*(?:'|ft)\s*{_NUMBER}\s*(?:\"|in|'')$")
_FOOT_M = 0.3048
_INCH_M = 0.0254


def parse_width(value: str | None) -> float | None:
    """A ``width=*`` tag in metres, or None when it is absent or not understood.

    Handles the forms mappers use: ``5``, ``5.5``, ``5,5`` (decimal comma), ``5 m``,
    ``5.5 metres``, ``16'``, ``16 ft``, ``12'6"``. Values outside (0, 100] m are
    treated as mistakes (None), so the per-class default applies instead.
    """
    if value is None:
        return None
    text = value.strip().lower().lstrip("~").strip()
    # A single comma between digits is a decimal comma ("5,5"); "5,500" is ambiguous: refuse.
    if re.fullmatch(r"\d+,\d{1,2}(\s*\D.*)?", text):
        text = text.replace(",", ".", 1)
    metres: float | None = None
    if match := _METRES.match(text):
        metres = float(match.group(1))
    elif match := _FEET.match(text):
        metres = float(match.group(1)) * _FOOT_M
    elif match := _FEET_INCHES.match(text):
        metres = float(match.group(1)) * _FOOT_M + float(match.group(2)) * _INCH_M
    if metres is None or not 0.0 < metres <= 100.0:
        return None
    return metres


def parse_lanes(value: str | None) -> int | None:
    """A ``lanes=*`` tag as a positive int, or None when absent or not understood."""
    if value is None:
        return None
    text = value.strip()
    if not text.isdigit():
        return None
    lanes = int(text)
    return lanes if 1 <= lanes <= 20 else None


def parse_oneway(tags: Mapping[str, str]) -> tuple[bool, bool]:
    """``(oneway, reversed)`` from a way's tags.

    ``oneway=yes/true/1`` is one-way along the node order, ``-1``/``reverse`` against it;
    ``no/false/0`` is two-way; without a tag, motorways and roundabouts are one-way
    (OSM's implied values) and everything else is two-way.
    """
    value = tags.get("oneway", "").strip().lower()
    if value in ("yes", "true", "1", "reversible", "alternating"):
        return True, False
    if value in ("-1", "reverse"):
        return True, True
    if value in ("no", "false", "0"):
        return False, False
    implied = tags.get("highway") in ("motorway", "motorway_link") or tags.get("junction") in (
        "roundabout",
        "circular",
    )
    return implied, False


def _defaults(highway: str) -> HighwayDefaults:
    base = highway[: -len("_link")] if highway.endswith("_link") else highway
    return HIGHWAY_DEFAULTS.get(base, HIGHWAY_DEFAULTS["residential"])


# ---------------------------------------------------------------------------------------
# Roads


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
        Carriageway width in metres.
    lanes : int
        Number of lanes (both directions).
    oneway : bool
    width_source : {"width", "lanes", "default"}
        Where ``width`` came from: the ``width`` tag, ``lanes`` x the class's lane width,
        or the class's default lane count x lane width.
    node_ids : tuple of int
        The OSM nodes of ``centerline``, in the same order.
    tags : mapping
    projection : LocalProjection
        The frame of ``centerline``.
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

    @property
    def length(self) -> float:
        """Length of the centreline in metres."""
        return float(np.linalg.norm(np.diff(self.centerline, axis=0), axis=1).sum())

    @property
    def lane_width(self) -> float:
        return self.width / self.lanes

    def describe(self) -> str:
        label = self.name or f"way {self.way_id}"
        direction = "one-way" if self.oneway else "two-way"
        return (
            f"{label} ({self.highway}, {self.length:.0f} m, {self.width:.2f} m wide from "
            f"{self.width_source}, {self.lanes} lane(s), {direction})"
        )

    def __repr__(self) -> str:
        return f"Road(way_id={self.way_id}, {self.describe()})"


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


def _road_width(tags: Mapping[str, str], highway: str, oneway: bool) -> tuple[float, int, str]:
    defaults = _defaults(highway)
    lanes_tag = parse_lanes(tags.get("lanes"))
    lanes = lanes_tag or (defaults.oneway_lanes if oneway else defaults.lanes)
    width_tag = parse_width(tags.get("width"))
    if width_tag is not None:
        return width_tag, lanes, "width"
    source = "lanes" if lanes_tag else "default"
    return lanes * defaults.lane_width, lanes, source


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
    (:data:`HIGHWAY_DEFAULTS`).
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
        width, lanes, source = _road_width(way.tags, highway_class, oneway)
        roads.append(
            Road(
                way_id=way.id,
                name=way.tags.get("name") or way.tags.get("ref") or "",
                highway=highway_class,
                centerline=projection.to_local(lat, lon),
                width=float(width),
                lanes=int(lanes),
                oneway=oneway,
                width_source=source,  # type: ignore[arg-type]
                node_ids=node_ids,
                tags=way.tags,
                projection=projection,
            )
        )
    return roads


# ---------------------------------------------------------------------------------------
# Street graph


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
