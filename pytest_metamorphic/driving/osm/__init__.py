"""OpenStreetMap for AEB scenarios: a hardened reader, tag interpretation, roads and street graphs.

One concept per module: :mod:`.reader` (expat with every way out of the document switched
off, size caps against bz2 bombs), :mod:`.projection` (local metres about the data's
centre), :mod:`.tags` (``width``, ``lanes``, ``oneway``, cycle and parking lanes,
sidewalks, defaults),
:mod:`.roads` (drivable ways as :class:`Road` geometries) and :mod:`.graph` (street graphs
for routing).

Public API::

    data = read_osm(path)                      # nodes, ways, bounds
    roads = load_roads(path, highway=DRIVABLE_HIGHWAYS)
    graph = street_graph(path)                 # nodes/edges with lengths, for routing
    nodes, length = graph.shortest_path(graph.nearest((0, 0)), graph.nearest((150, 80)))
"""

from pytest_metamorphic.driving.osm.graph import StreetGraph, street_graph
from pytest_metamorphic.driving.osm.projection import EARTH_RADIUS_M, LocalProjection
from pytest_metamorphic.driving.osm.reader import OsmData, OsmNode, OsmRelation, OsmWay, read_osm
from pytest_metamorphic.driving.osm.roads import Road, load_roads
from pytest_metamorphic.driving.osm.tags import (
    CYCLE_LANE_WIDTH,
    DRIVABLE_HIGHWAYS,
    HIGHWAY_DEFAULTS,
    PARKING_LANE_WIDTHS,
    SIDEWALK_WIDTH,
    HighwayDefaults,
    parse_lanes,
    parse_margins,
    parse_oneway,
    parse_parking,
    parse_sidewalks,
    parse_width,
)

__all__ = [
    "CYCLE_LANE_WIDTH",
    "DRIVABLE_HIGHWAYS",
    "EARTH_RADIUS_M",
    "HIGHWAY_DEFAULTS",
    "PARKING_LANE_WIDTHS",
    "SIDEWALK_WIDTH",
    "HighwayDefaults",
    "LocalProjection",
    "OsmData",
    "OsmNode",
    "OsmRelation",
    "OsmWay",
    "Road",
    "StreetGraph",
    "load_roads",
    "parse_lanes",
    "parse_margins",
    "parse_oneway",
    "parse_parking",
    "parse_sidewalks",
    "parse_width",
    "read_osm",
    "street_graph",
]
