"""Road geometry: arc length, lateral offsets, lanes, projection back onto the centreline."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.driving.osm import load_roads
from pytest_metamorphic.driving.roads import RoadGeometry

L_SHAPE = RoadGeometry(np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0]]), 7.0, 2, "L")


def test_straight_road_frame() -> None:
    road = RoadGeometry.straight(length=200, width=10, heading=math.pi / 2, origin=(5, -3))
    assert road.length == pytest.approx(200)
    np.testing.assert_allclose(road.position(50), [5, 47])
    np.testing.assert_allclose(road.to_world(50, 2), [3, 47])  # left of north is west
    assert road.heading(10) == pytest.approx(math.pi / 2)
    s, d = road.to_frenet(np.array([3.0, 47.0]))
    assert (s, d) == pytest.approx((50, 2))
    # Extrapolation before the start and beyond the end.
    assert road.to_frenet(np.array([5.0, -13.0]))[0] == pytest.approx(-10)
    np.testing.assert_allclose(road.to_world(210, 0), [5, 207])


def test_lanes_from_the_right_edge() -> None:
    road = RoadGeometry.straight(width=9, lanes=3)
    assert road.lane_width == 3
    assert road.lane_bounds(0) == (-4.5, -1.5)
    assert road.lane_center(2) == 3.0
    assert [road.lane_at(d) for d in (-4.5, -1.0, 4.4, 4.6)] == [0, 1, 2, None]
    with pytest.raises(InvalidArgument, match="lane=3"):
        road.lane_bounds(3)


def test_polyline_arc_length_and_corners() -> None:
    assert L_SHAPE.length == pytest.approx(150)
    np.testing.assert_allclose(L_SHAPE.position([0, 100, 125]), [[0, 0], [100, 0], [100, 25]])
    np.testing.assert_allclose(L_SHAPE.normal(120), [-1, 0])
    assert L_SHAPE.heading(99.9) == pytest.approx(0.0)
    assert L_SHAPE.heading(100.1) == pytest.approx(math.pi / 2)
    # The chord over a 2.7 m wheelbase turns smoothly through the corner: 45 degrees at it.
    assert L_SHAPE.chord_heading(100, 2.7) == pytest.approx(math.pi / 4)
    s, d = L_SHAPE.to_frenet(np.array([[50.0, -2.0], [97.0, 30.0]]))
    np.testing.assert_allclose(s, [50, 130])
    np.testing.assert_allclose(d, [-2, 3])
    assert L_SHAPE.contains(np.array([[50, 3.4], [50, 3.6], [-1, 0]])).tolist() == [
        True,
        False,
        False,
    ]


@given(
    s=st.floats(0, 150),
    d=st.floats(-3.5, 3.5),
)
def test_point_matches_vectorised_path_and_frenet_inverts(s: float, d: float) -> None:
    x, y, heading = L_SHAPE.point(s, d)
    np.testing.assert_allclose([x, y], L_SHAPE.to_world(s, d), atol=1e-9)
    assert heading == pytest.approx(float(L_SHAPE.heading(s)))
    # Away from the inside of the corner the projection is unique.
    if abs(s - 100) > abs(d) + 1e-6:
        s2, d2 = L_SHAPE.to_frenet(np.array([x, y]))
        assert (s2, d2) == pytest.approx((s, d), abs=1e-6)


@given(
    heading=st.floats(-math.pi, math.pi),
    s=st.floats(-20, 220),
    d=st.floats(-20, 20),
)
def test_straight_roads_invert_exactly_everywhere(heading: float, s: float, d: float) -> None:
    road = RoadGeometry.straight(length=200, width=8, heading=heading, origin=(3, 4))
    assert road.to_frenet(road.to_world(s, d)) == pytest.approx((s, d), abs=1e-6)


def test_osm_road_geometry(shared_data: Path) -> None:
    roads = load_roads(shared_data / "osm_osmnx/West-Oakland.osm.bz2")
    eighth = max((r for r in roads if r.name == "8th Street"), key=lambda r: r.length)
    geometry = RoadGeometry.from_osm(eighth)
    assert geometry.name == "8th Street" and geometry.width == 9.0 and geometry.lanes == 2
    assert geometry.margins == (1.5, 1.5)  # its painted cycle lanes
    assert geometry.length == pytest.approx(eighth.length)
    s, d = geometry.to_frenet(eighth.centerline)
    np.testing.assert_allclose(d, 0, atol=1e-9)
    assert np.all(np.diff(s) > 0)
    assert RoadGeometry.from_osm(eighth, width=10, lanes=1, margins=(0, 0)).lane_width == 10


def test_margins_sit_between_the_kerbs_and_the_lanes() -> None:
    road = RoadGeometry.straight(length=50, width=10, lanes=2, margins=(2.0, 1.0))
    assert road.lane_width == 3.5
    assert road.lane_bounds(0) == (-3.0, 0.5) and road.lane_bounds(1) == (0.5, 4.0)
    assert road.lane_center(0) == pytest.approx(-1.25)
    assert [road.lane_at(d) for d in (-4.5, -2.9, 0.6, 4.5, 5.5)] == [None, 0, 1, None, None]
    assert "margins 2 / 1 m" in road.describe()
    assert not road.equals(RoadGeometry.straight(length=50, width=10, lanes=2))
    assert road.contains([[10.0, -4.9]]).all()  # a cycle lane is on the carriageway


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"centerline": [[0, 0]], "width": 5}, "k >= 2"),
        ({"centerline": [[0, 0], [0, 0], [1, 0]], "width": 5}, "coincide"),
        ({"centerline": [[0, 0], [np.nan, 0]], "width": 5}, "NaN"),
        ({"centerline": [[0, 0], [1, 0]], "width": 0}, "width"),
        ({"centerline": [[0, 0], [1, 0]], "width": 5, "lanes": 0}, "lanes"),
        ({"centerline": [[0, 0], [1, 0]], "width": 5, "lanes": 1.5}, "lanes"),
        ({"centerline": [[0, 0], [1, 0]], "width": 5, "margins": (3, 2)}, "no room for lanes"),
        ({"centerline": [[0, 0], [1, 0]], "width": 5, "margins": (-1, 0)}, "margins"),
        ({"centerline": [[0, 0], [1, 0]], "width": 5, "margins": 1.5}, r"\(right, left\)"),
    ],
)
def test_bad_geometry_is_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidArgument, match=message):
        RoadGeometry(**kwargs)


def test_parking_lanes_lie_at_the_kerbs_inside_the_margins() -> None:
    road = RoadGeometry.straight(
        width=10.0, lanes=2, margins=(3.5, 0.0), parking=(2.0, 0.0), sidewalks=(2.0, 0.0)
    )
    assert road.kerb("right") == -5.0 and road.kerb("left") == 5.0
    assert road.parking_lane("right") == (-5.0, -3.0) and road.parking_lane("left") is None
    assert road.lane_at(-3.5) is None  # the cycle lane between parking and traffic
    assert "parking 2 / 0 m" in road.describe() and "sidewalks 2 / 0 m" in road.describe()
    assert not road.equals(RoadGeometry.straight(width=10.0, lanes=2, margins=(3.5, 0.0)))
    with pytest.raises(InvalidArgument, match="part of the margin"):
        RoadGeometry.straight(width=10.0, margins=(1.0, 0.0), parking=(2.0, 0.0))
    with pytest.raises(InvalidArgument, match="sidewalks"):
        RoadGeometry.straight(width=10.0, sidewalks=(-1.0, 0.0))
    with pytest.raises(InvalidArgument, match="side"):
        road.kerb("middle")
