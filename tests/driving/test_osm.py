"""The hardened OSM reader: real osmnx extracts, tag interpretation, graphs, hostile XML."""

from __future__ import annotations

import bz2
import math
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic import DataError, InvalidArgument
from pytest_metamorphic.driving.osm import (
    DRIVABLE_HIGHWAYS,
    EARTH_RADIUS_M,
    LocalProjection,
    load_roads,
    parse_lanes,
    parse_margins,
    parse_oneway,
    parse_parking,
    parse_sidewalks,
    parse_width,
    read_osm,
    street_graph,
)

PLANET = "osm_osmnx/planet_10.068,48.135_10.071,48.137.osm"
OAKLAND = "osm_osmnx/West-Oakland.osm.bz2"


def _haversine(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.asin(math.sqrt(a))


def _write(tmp_path: Path, body: str, name: str = "map.osm") -> Path:
    path = tmp_path / name
    path.write_text(f"<?xml version='1.0' encoding='UTF-8'?>\n{body}", encoding="utf-8")
    return path


# -- real files --------------------------------------------------------------------------


def test_planet_extract_counts_match_sources_md(shared_data: Path) -> None:
    data = read_osm(shared_data / PLANET)
    assert (len(data.nodes), len(data.ways), data.relation_count) == (281, 56, 2)
    assert data.bounds == (48.135, 10.068, 48.137, 10.071)
    highways = [w for w in data.ways if "highway" in w.tags]
    assert len(highways) == 19


def test_oakland_bz2_counts_match_sources_md(shared_data: Path) -> None:
    data = read_osm(shared_data / OAKLAND)
    assert (len(data.nodes), len(data.ways), data.relation_count) == (446, 66, 23)
    assert sum("highway" in w.tags for w in data.ways) == 31


def test_planet_roads_and_widths(shared_data: Path) -> None:
    roads = load_roads(shared_data / PLANET)
    names = {r.name for r in roads if r.name}
    # Beethovenstraße and Schwendier Weg are clipped to one node by the extract: skipped.
    assert names == {"Goethestraße", "Haydnstraße", "Richard-Wagner-Straße"}
    goethe = next(r for r in roads if r.name == "Goethestraße")
    assert goethe.highway == "residential" and not goethe.oneway
    assert (goethe.width, goethe.lanes, goethe.width_source) == (6.0, 2, "default")
    assert goethe.centerline.shape == (9, 2) and goethe.centerline.dtype == np.float64
    assert 110 < goethe.length < 116
    # The extract is ~220 m x 220 m around its centre.
    everything = np.vstack([r.centerline for r in roads])
    assert np.abs(everything).max() < 160


def test_oakland_lanes_oneway_and_filter(shared_data: Path) -> None:
    roads = load_roads(shared_data / OAKLAND, highway=DRIVABLE_HIGHWAYS)
    assert not any(r.highway in ("footway", "cycleway") for r in roads)
    seventh = [r for r in roads if r.name == "7th Street"]
    assert all(r.oneway for r in seventh)
    three = [r for r in seventh if r.lanes == 3]
    assert three and all(r.width == pytest.approx(3 * 3.25) for r in three)
    assert all(r.width_source == "lanes" for r in three)
    untagged = [r for r in seventh if "lanes" not in r.tags]
    # One-way secondary without a lanes tag: one lane of 3.25 m.
    assert untagged and all((r.lanes, r.width) == (1, 3.25) for r in untagged)
    footways = load_roads(shared_data / OAKLAND, highway="footway")
    assert len(footways) == 7 and all(r.width == 2.0 for r in footways)


def test_projection_distances_match_haversine(shared_data: Path) -> None:
    data = read_osm(shared_data / OAKLAND)
    projection = data.projection()
    nodes = list(data.nodes.values())
    rng = np.random.default_rng(0)
    for _ in range(50):
        a, b = (nodes[i] for i in rng.choice(len(nodes), 2, replace=False))
        xy = projection.to_local([a.lat, b.lat], [a.lon, b.lon])
        planar = float(np.linalg.norm(xy[1] - xy[0]))
        true = _haversine(a.lat, a.lon, b.lat, b.lon)
        # Equirectangular over ~1.5 km: well within 0.3 m.
        assert planar == pytest.approx(true, abs=0.3)
    lat, lon = projection.to_geographic(projection.to_local(a.lat, a.lon))
    assert (float(lat), float(lon)) == pytest.approx((a.lat, a.lon), abs=1e-12)


def test_shared_origin_puts_two_files_in_one_frame(shared_data: Path) -> None:
    origin = LocalProjection(48.136, 10.0695)
    roads = load_roads(shared_data / PLANET, origin=origin)
    again = load_roads(shared_data / PLANET, origin=(48.136, 10.0695))
    assert all(r.projection == origin for r in roads)
    pairs = zip(roads, again, strict=True)
    assert all(np.array_equal(a.centerline, b.centerline) for a, b in pairs)


def test_street_graph_routes_on_real_streets(shared_data: Path) -> None:
    graph = street_graph(shared_data / OAKLAND)
    assert len(graph.edges) == len(graph.lengths) == len(graph.way_ids)
    seg = graph.xy[graph.edges[:, 1]] - graph.xy[graph.edges[:, 0]]
    np.testing.assert_allclose(np.linalg.norm(seg, axis=1), graph.lengths)
    source = graph.nearest(graph.xy.min(axis=0))
    target = graph.nearest(graph.xy.max(axis=0))
    undirected = street_graph(shared_data / OAKLAND, directed=False)
    route, length = undirected.shortest_path(
        undirected.index_of(int(graph.node_ids[source])),
        undirected.index_of(int(graph.node_ids[target])),
    )
    xy = undirected.path_xy(route)
    assert length == pytest.approx(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())
    assert length >= np.linalg.norm(xy[-1] - xy[0])
    matrix = undirected.csgraph()
    assert (matrix != matrix.T).nnz == 0


# -- tags ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "metres"),
    [
        ("5", 5.0),
        ("5.5", 5.5),
        ("5,5", 5.5),
        ("5,5 m", 5.5),
        ("7 m", 7.0),
        ("7m", 7.0),
        ("6.5 metres", 6.5),
        ("~4", 4.0),
        ("16'", 16 * 0.3048),
        ("16 ft", 16 * 0.3048),
        ("12'6\"", 12 * 0.3048 + 6 * 0.0254),
        (None, None),
        ("wide", None),
        ("0", None),
        ("-3", None),
        ("5,500", None),
        ("3-4", None),
        ("250", None),
    ],
)
def test_parse_width(text: str | None, metres: float | None) -> None:
    got = parse_width(text)
    assert got == (None if metres is None else pytest.approx(metres))


def test_parse_lanes_and_oneway() -> None:
    assert parse_lanes("2") == 2 and parse_lanes(" 3 ") == 3
    assert parse_lanes("2;3") is None and parse_lanes("0") is None and parse_lanes(None) is None
    assert parse_oneway({"oneway": "yes"}) == (True, False)
    assert parse_oneway({"oneway": "-1"}) == (True, True)
    assert parse_oneway({"oneway": "no", "highway": "motorway"}) == (False, False)
    assert parse_oneway({"highway": "motorway"}) == (True, False)
    assert parse_oneway({"highway": "residential", "junction": "roundabout"}) == (True, False)
    assert parse_oneway({"highway": "residential"}) == (False, False)


MAP = """<osm version="0.6">
  <node id="1" lat="0.0" lon="0.0"/>
  <node id="2" lat="0.0" lon="0.001"/>
  <node id="3" lat="0.001" lon="0.001"/>
  <way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/>
    <tag k="width" v="8,5 m"/><tag k="lanes" v="4"/></way>
  <way id="11"><nd ref="2"/><nd ref="3"/><tag k="highway" v="primary"/>
    <tag k="oneway" v="-1"/></way>
  <way id="12"><nd ref="1"/><nd ref="99"/><nd ref="2"/><nd ref="3"/>
    <tag k="highway" v="service"/></way>
  <way id="13"><nd ref="1"/><nd ref="3"/><tag k="highway" v="pedestrian"/>
    <tag k="area" v="yes"/></way>
  <way id="14"><nd ref="1"/><nd ref="3"/><tag k="building" v="yes"/></way>
</osm>"""


def test_width_precedence_oneway_reversal_and_clipped_ways(tmp_path: Path) -> None:
    roads = {r.way_id: r for r in load_roads(_write(tmp_path, MAP))}
    assert set(roads) == {10, 11, 12}  # area and non-highway skipped
    assert (roads[10].width, roads[10].lanes, roads[10].width_source) == (8.5, 4, "width")
    # oneway=-1: one lane by default, geometry reversed to the direction of travel.
    assert (roads[11].lanes, roads[11].width, roads[11].oneway) == (1, 3.5, True)
    assert roads[11].node_ids == (3, 2)
    assert roads[11].centerline[0, 1] > roads[11].centerline[1, 1]
    # Node 99 is missing: the longest run of present nodes (2, 3) is kept.
    assert roads[12].node_ids == (2, 3)
    assert roads[10].length == pytest.approx(_haversine(0, 0, 0, 0.001), rel=1e-6)


def test_directed_graph_respects_oneway_and_reports_unreachable(tmp_path: Path) -> None:
    path = _write(tmp_path, MAP)
    graph = street_graph(path, highway="primary")
    n1, n3 = graph.index_of(1), graph.index_of(3)
    route, length = graph.shortest_path(n3, n1)
    assert [int(graph.node_ids[i]) for i in route] == [3, 2, 1]
    with pytest.raises(DataError, match="cannot be reached"):
        graph.shortest_path(n1, n3)  # only against the one-way street
    walking = street_graph(path, highway="primary", directed=False)
    assert walking.shortest_path(walking.index_of(1), walking.index_of(3))[1] == pytest.approx(
        length
    )
    with pytest.raises(InvalidArgument, match="source"):
        graph.shortest_path(-1, n1)
    with pytest.raises(InvalidArgument, match="node_id"):
        graph.index_of(12345)


# -- hostile and broken input ----------------------------------------------------------------

BILLION_LAUGHS = """<!DOCTYPE osm [
  <!ENTITY lol "lol">
  <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
  <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
]>
<osm version="0.6"><node id="1" lat="0" lon="0"><tag k="name" v="&lol3;"/></node></osm>"""

EXTERNAL = """<!DOCTYPE osm [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<osm version="0.6"><node id="1" lat="0" lon="0"><tag k="name" v="&xxe;"/></node></osm>"""

PARAMETER = """<!DOCTYPE osm [<!ENTITY % remote SYSTEM "http://example.invalid/x.dtd"> %remote;]>
<osm version="0.6"/>"""

EXTERNAL_DTD = """<!DOCTYPE osm SYSTEM "http://example.invalid/osm.dtd">
<osm version="0.6"/>"""


@pytest.mark.parametrize(
    "body", [BILLION_LAUGHS, EXTERNAL, PARAMETER, EXTERNAL_DTD], ids=["laughs", "xxe", "pe", "dtd"]
)
def test_entity_tricks_are_refused_naming_the_file(tmp_path: Path, body: str) -> None:
    path = _write(tmp_path, body, "evil.osm")
    with pytest.raises(DataError, match=r"evil\.osm.*DOCTYPE") as info:
        read_osm(path)
    assert info.value.path == str(path)
    with pytest.raises(DataError, match="DOCTYPE"):
        load_roads(path)


def test_hostile_bz2_is_refused_too(tmp_path: Path) -> None:
    path = tmp_path / "evil.osm.bz2"
    path.write_bytes(bz2.compress(("<?xml version='1.0'?>" + EXTERNAL).encode()))
    with pytest.raises(DataError, match=r"evil\.osm\.bz2.*DOCTYPE"):
        read_osm(path)


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("<osm><node id='1' lat='0' lon='0'><tag k='a' v='&undef;'/></node></osm>", "undefined"),
        ("<osm><node id='1' lat='0' lon='0'>", "line"),
        ("<gpx version='1.1'/>", "not an OSM XML file"),
        ("<osm><node id='1' lat='91' lon='0'/></osm>", "out of range"),
        ("<osm><node id='1' lat='x' lon='0'/></osm>", "not a number"),
        ("<osm><node id='1' lat='nan' lon='0'/></osm>", "not finite"),
        ("<osm><node lat='1' lon='0'/></osm>", "no 'id'"),
        ("<osm><node id='1' lat='1' lon='0'/><node id='1' lat='1' lon='0'/></osm>", "twice"),
        ("<osm><way id='1'><nd ref='a'/></way></osm>", "not an integer"),
        ("<osm><way id='1'><tag k='highway'/></way></osm>", "needs both k and v"),
    ],
)  # fmt: skip
def test_malformed_files_raise_data_error(tmp_path: Path, body: str, message: str) -> None:
    path = _write(tmp_path, body, "broken.osm")
    with pytest.raises(DataError, match=message) as info:
        read_osm(path)
    assert "broken.osm" in str(info.value)


def test_an_unknown_declared_encoding_is_a_data_error(tmp_path: Path) -> None:
    # Found by the outside-data fuzz test: expat asks Python's codec registry and its
    # LookupError escaped raw.
    path = tmp_path / "odd.osm"
    path.write_bytes(b"<?xml version='1.0' encoding='UTF0'?>\n<osm/>")
    with pytest.raises(DataError, match=r"odd\.osm: declares an unknown text encoding.*UTF0"):
        read_osm(path)


def test_missing_empty_corrupt_and_oversized_files(tmp_path: Path) -> None:
    with pytest.raises(DataError, match=r"(?i)no such file"):
        read_osm(tmp_path / "nothing.osm")
    empty = tmp_path / "empty.osm"
    empty.write_bytes(b"")
    with pytest.raises(DataError, match=r"empty\.osm"):
        read_osm(empty)
    corrupt = tmp_path / "corrupt.osm.bz2"
    corrupt.write_bytes(b"BZh91AY&SY" + b"\x00" * 64)
    with pytest.raises(DataError, match="cannot decompress"):
        read_osm(corrupt)
    bomb = tmp_path / "bomb.osm.bz2"
    bomb.write_bytes(bz2.compress(b"<osm>" + b" " * 3_000_000 + b"</osm>"))
    with pytest.raises(DataError, match="max_bytes"):
        read_osm(bomb, max_bytes=1_000_000)
    assert read_osm(bomb).nodes == {}
    with pytest.raises(InvalidArgument, match="max_bytes"):
        read_osm(bomb, max_bytes=0)


def test_bad_arguments() -> None:
    with pytest.raises(InvalidArgument, match="highway"):
        load_roads("x.osm", highway=3)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="lat0"):
        LocalProjection(95.0, 0.0)
    with pytest.raises(InvalidArgument, match="directed"):
        street_graph("x.osm", directed="yes")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("tags", "oneway", "reverse", "margins"),
    [
        ({}, False, False, (0.0, 0.0)),
        ({"cycleway": "lane"}, False, False, (1.5, 1.5)),
        ({"cycleway": "lane"}, True, False, (1.5, 0.0)),  # one-way: with the traffic
        ({"cycleway": "track"}, False, False, (0.0, 0.0)),  # off the carriageway
        ({"cycleway:right": "lane", "cycleway:left": "no"}, False, False, (1.5, 0.0)),
        ({"cycleway:right": "lane"}, True, True, (0.0, 1.5)),  # oneway=-1 swaps sides
        ({"cycleway:both": "lane", "cycleway": "no"}, False, False, (1.5, 1.5)),
        ({"parking:lane:both": "parallel"}, False, False, (2.0, 2.0)),
        ({"parking:lane:right": "diagonal"}, False, False, (4.5, 0.0)),
        ({"parking:lane:left": "no_stopping"}, False, False, (0.0, 0.0)),
        ({"parking:both": "lane"}, False, False, (2.0, 2.0)),
        ({"parking:right": "lane", "parking:right:orientation": "perpendicular"}, False, False,
         (5.0, 0.0)),
        ({"parking:both": "street_side"}, False, False, (0.0, 0.0)),
        ({"cycleway": "lane", "parking:lane:right": "parallel"}, False, False, (3.5, 1.5)),
    ],
)  # fmt: skip
def test_cycle_and_parking_lanes_on_the_carriageway(
    tags: dict[str, str], oneway: bool, reverse: bool, margins: tuple[float, float]
) -> None:
    assert parse_margins(tags, oneway=oneway, reverse=reverse) == margins


def test_cycle_lanes_widen_the_carriageway_beside_the_lanes(
    shared_data: Path, tmp_path: Path
) -> None:
    roads = {r.way_id: r for r in load_roads(shared_data / OAKLAND, highway=DRIVABLE_HIGHWAYS)}
    eighth = roads[6358365]  # 8th Street: cycleway=lane, no width tag
    assert (eighth.width, eighth.lanes, eighth.margins) == (9.0, 2, (1.5, 1.5))
    assert eighth.lane_width == 3.0 and "cycle/parking lanes 1.5 / 1.5 m" in eighth.describe()
    path = _write(
        tmp_path,
        """<osm version="0.6">
  <node id="1" lat="0" lon="0"/><node id="2" lat="0" lon="0.001"/>
  <way id="1"><nd ref="1"/><nd ref="2"/><tag k="highway" v="residential"/>
    <tag k="width" v="12"/><tag k="parking:lane:both" v="parallel"/></way>
  <way id="2"><nd ref="1"/><nd ref="2"/><tag k="highway" v="residential"/>
    <tag k="width" v="6"/><tag k="parking:lane:both" v="parallel"/></way>
</osm>""",
    )
    tagged, narrow = load_roads(path)
    # A width tag is kerb to kerb: the parking lanes are inside it ...
    assert (tagged.width, tagged.lane_width) == (12.0, 4.0)
    # ... unless it leaves under 2.5 m per lane: then it measured the traffic lanes only.
    assert (narrow.width, narrow.lane_width) == (10.0, 3.0)


def test_an_extract_too_large_to_parse_is_refused_by_name(tmp_path: Path) -> None:
    # Before: no cap (3 M nodes, 7 MB of bz2, took 1.1 GB).
    nodes = "".join(f'<node id="{i}" lat="48.0" lon="10.0"/>' for i in range(1, 2001))
    path = tmp_path / "big.osm"
    path.write_text(f'<?xml version="1.0"?><osm version="0.6">{nodes}</osm>')
    assert len(read_osm(path).nodes) == 2000
    with pytest.raises(DataError, match="more than max_elements=1000"):
        read_osm(path, max_elements=1000)
    with pytest.raises(InvalidArgument, match="max_elements"):
        read_osm(path, max_elements=0)


@pytest.mark.parametrize(
    ("tags", "reverse", "parking", "sidewalks"),
    [
        ({}, False, (0.0, 0.0), (0.0, 0.0)),
        ({"parking:both": "lane"}, False, (2.0, 2.0), (0.0, 0.0)),
        ({"parking:lane:right": "diagonal", "cycleway": "lane"}, False, (4.5, 0.0), (0.0, 0.0)),
        ({"parking:right": "lane"}, True, (0.0, 2.0), (0.0, 0.0)),  # oneway=-1 swaps sides
        ({"sidewalk": "both"}, False, (0.0, 0.0), (2.0, 2.0)),
        ({"sidewalk": "right"}, False, (0.0, 0.0), (2.0, 0.0)),
        ({"sidewalk": "separate"}, False, (0.0, 0.0), (0.0, 0.0)),  # its own way
        ({"sidewalk:left": "yes", "sidewalk:left:width": "3.5"}, False, (0.0, 0.0), (0.0, 3.5)),
        ({"sidewalk:both": "yes", "sidewalk:right": "no"}, False, (0.0, 0.0), (0.0, 2.0)),
    ],
)  # fmt: skip
def test_parking_lanes_and_sidewalks_per_side(
    tags: dict[str, str],
    reverse: bool,
    parking: tuple[float, float],
    sidewalks: tuple[float, float],
) -> None:
    assert parse_parking(tags, reverse=reverse) == parking
    assert parse_sidewalks(tags, reverse=reverse) == sidewalks


def test_assumed_tags_are_stated_not_edited_into_the_map(shared_data: Path) -> None:
    roads = {r.way_id: r for r in load_roads(shared_data / OAKLAND, highway=DRIVABLE_HIGHWAYS)}
    seventh = roads[202455451]  # one-way, lanes=2, sidewalk=right
    assert (seventh.width, seventh.parking, seventh.sidewalks) == (6.5, (0.0, 0.0), (2.0, 0.0))
    parked = seventh.with_tags({"parking:right": "lane"})
    assert (parked.width, parked.lanes, parked.margins, parked.parking) == (
        8.5, 2, (2.0, 0.0), (2.0, 0.0),
    )  # fmt: skip
    assert parked.tags["parking:right"] == "lane" and "parking:right" not in seventh.tags
    assert parked.centerline is seventh.centerline and parked.oneway
    with pytest.raises(InvalidArgument, match="extra"):
        seventh.with_tags({"parking:right": 2})  # type: ignore[dict-item]
