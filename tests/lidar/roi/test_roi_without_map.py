"""ROIs for recordings without Apollo's HD map: a Lanelet2 lane map (Autoware's format), an
ego corridor, the whole sweep."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.io.lanelet2 import read_lanelet2
from pytest_metamorphic.lidar.roi import corridor_roi, lanelet2_roi, whole_sweep_roi


def _node(i: int, x: float, y: float) -> str:
    return (
        f'<node id="{i}" lat="0" lon="0"><tag k="local_x" v="{x}"/>'
        f'<tag k="local_y" v="{y}"/><tag k="ele" v="0"/></node>'
    )


def _way(i: int, nodes: list[int]) -> str:
    refs = "".join(f'<nd ref="{n}"/>' for n in nodes)
    return f'<way id="{i}">{refs}<tag k="type" v="line_thin"/></way>'


def _lanelet(i: int, left: int, right: int, subtype: str) -> str:
    return (
        f'<relation id="{i}"><member type="way" role="left" ref="{left}"/>'
        f'<member type="way" role="right" ref="{right}"/>'
        f'<tag k="type" v="lanelet"/><tag k="subtype" v="{subtype}"/></relation>'
    )


def _write_map(path: Path) -> Path:
    """Two road lanes along x from 100 to 200 m east (y 50-53.5 and 53.5-57, the right
    bound of the first stored backwards) and a crosswalk across them at x 150."""
    nodes = [
        _node(1, 100, 50), _node(2, 200, 50), _node(3, 100, 53.5), _node(4, 200, 53.5),
        _node(5, 100, 57), _node(6, 200, 57),
        _node(7, 148, 48), _node(8, 148, 59), _node(9, 152, 48), _node(10, 152, 59),
    ]  # fmt: skip
    ways = [
        _way(11, [2, 1]), _way(12, [3, 4]), _way(13, [5, 6]), _way(14, [7, 8]), _way(15, [9, 10])
    ]  # fmt: skip
    relations = [
        _lanelet(21, 12, 11, "road"), _lanelet(22, 13, 12, "road"),
        _lanelet(23, 14, 15, "crosswalk"),
    ]  # fmt: skip
    path.write_text(
        '<?xml version="1.0"?><osm version="0.6">' + "".join(nodes + ways + relations) + "</osm>"
    )
    return path


def test_a_lanelet2_map_gives_its_road_lanes_in_the_sensor_frame(tmp_path: Path) -> None:
    path = _write_map(tmp_path / "lanelet2_map.osm")
    lanelets = read_lanelet2(path)
    assert [(lane.id, lane.subtype) for lane in lanelets] == [
        (21, "road"), (22, "road"), (23, "crosswalk")
    ]  # fmt: skip
    # The backwards right bound was turned: the area is a proper rectangle.
    assert np.allclose(lanelets[0].polygon(), [[100, 53.5], [200, 53.5], [200, 50], [100, 50]])
    # The sensor at (120, 51.75), heading east: the lanes run from 20 m behind to 80 m ahead.
    roi = lanelet2_roi(path, pose=(120.0, 51.75, 0.0))
    inside = roi.contains([[10, 0], [10, 4.5], [10, 6], [-19, 0], [81, 0]], method="exact")
    assert inside.tolist() == [True, True, False, True, False]
    # Heading north instead: ahead (+x) is the map's +y, across the lanes.
    turned = lanelet2_roi(lanelets, pose=(120.0, 51.75, math.pi / 2))
    assert turned.contains([[0, 10], [4, 0], [6, 0]], method="exact").tolist() == [
        True,
        True,
        False,
    ]
    # The crosswalk is not road unless asked for.
    assert len(roi.polygons) == 2
    assert len(lanelet2_roi(lanelets, pose=(120, 51.75, 0), subtypes={"crosswalk"}).polygons) == 1


def test_bad_lanelet2_maps_and_poses_are_named(tmp_path: Path) -> None:
    broken = tmp_path / "broken.osm"
    broken.write_text(
        '<osm version="0.6">' + _node(1, 0, 0) + _node(2, 1, 0) + _way(11, [1, 2])
        + _lanelet(21, 11, 99, "road") + "</osm>"
    )  # fmt: skip
    with pytest.raises(DataError, match=r"broken.osm.*lanelet 21: its right way 99"):
        read_lanelet2(broken)
    empty = tmp_path / "empty.osm"
    empty.write_text('<osm version="0.6">' + _node(1, 0, 0) + "</osm>")
    with pytest.raises(DataError, match="no lanelet"):
        read_lanelet2(empty)
    path = _write_map(tmp_path / "map.osm")
    with pytest.raises(InvalidArgument, match="pose"):
        lanelet2_roi(path, pose=(1.0, 2.0))
    with pytest.raises(InvalidArgument, match="no lanelet"):
        lanelet2_roi(path, pose=(5000.0, 0.0, 0.0))


def test_a_corridor_follows_the_ego_path_and_the_whole_sweep_is_explicit() -> None:
    straight = corridor_roi(width=7.0, ahead=60.0, behind=10.0)  # round ends: +3.5 m
    assert straight.contains([[30, 3], [30, 4], [-14, 0], [64, 0]], method="exact").tolist() == [
        True, False, False, False
    ]  # fmt: skip
    curve = corridor_roi([[0, 0], [20, 0], [40, 20]], width=4.0)
    assert curve.contains([[30, 10], [30, 0], [10, 0]], method="exact").tolist() == [
        True, False, True
    ]  # fmt: skip
    assert whole_sweep_roi(radius=80).contains([[79, -79], [0, 81]], method="exact").tolist() == [
        True, False
    ]  # fmt: skip
    with pytest.raises(InvalidArgument, match="path"):
        corridor_roi([[0, 0]])
    with pytest.raises(InvalidArgument, match="width"):
        corridor_roi(width=-1)


def test_a_hostile_lanelet2_file_is_refused_by_name(tmp_path: Path) -> None:
    bomb = tmp_path / "bomb.osm"
    bomb.write_text(
        '<?xml version="1.0"?><!DOCTYPE osm [<!ENTITY a "aaaaaaaaaa">]>'
        '<osm version="0.6"><node id="1" lat="0" lon="0"><tag k="x" v="&a;"/></node></osm>'
    )
    with pytest.raises(DataError, match=r"bomb\.osm.*DOCTYPE"):
        read_lanelet2(bomb)
    fifo = tmp_path / "map.fifo"
    os.mkfifo(fifo)
    with pytest.raises(DataError, match=r"map\.fifo"):
        read_lanelet2(fifo)


WHOLE_SWEEP_MR1 = """
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from pytest_metamorphic import metamorphic
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.roi import whole_sweep_roi
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.synthetic import Obstacle, Scene, render
from pytest_metamorphic.relations.lidar import mr1_subset

ROI = whole_sweep_roi(radius=RADIUS)
CAR = Obstacle(Box((12.0, -2.5, -0.98), (4.3, 1.8, 1.5), 0.35, "car"))
SWEEP = render(Scene(roi=ROI, obstacles=(CAR,), name="street"))


@settings(max_examples=2, derandomize=True, database=None, deadline=None,
          suppress_health_check=list(HealthCheck))
@metamorphic(source=st.just(Frame(SWEEP.cloud, roi=ROI)), relations=[mr1_subset()])
def test_mr1(frame):
    return ReferencePerception()(frame)
"""


@pytest.mark.parametrize("radius", [100.0, 130.0])
def test_the_whole_sweep_roi_runs_mr1_and_says_when_it_tested_nothing(
    pytester: pytest.Pytester, radius: float
) -> None:
    # docs/your-recordings.md's route: whole_sweep_roi(radius=100) with MR1 crashed on the
    # bitmap's range (101 m < 120 m) and radius=130 on "no room". Within the sensor's
    # 120 m, radius=100 leaves room beyond the square for the noise; 130 leaves none, and
    # MR1 reports that it tested nothing, with the reason.
    pytester.makepyfile(test_mt=WHOLE_SWEEP_MR1.replace("RADIUS", repr(radius)))
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    if radius < 120:
        result.assert_outcomes(passed=1)
        assert "NOTHING TESTED" not in result.stdout.str()
        return
    result.assert_outcomes(passed=1, warnings=1)
    result.stdout.fnmatch_lines(
        ["*tested nothing: no follow-up could be made (noise outside the ROI: the ROI leaves "
         "no room outside it within 120 m*", "*NOTHING TESTED by 1 relation(s)*"]
    )  # fmt: skip


def test_a_node_far_outside_the_maps_frame_is_named(tmp_path: Path) -> None:
    # Before: a point at 1e308 made the lane's area overflow, refused as "zero area
    # (collinear)" naming neither the map nor the point.
    path = _write_map(tmp_path / "lanelet2_map.osm")
    path.write_text(path.read_text().replace('k="local_x" v="200"', 'k="local_x" v="1e308"', 1))
    with pytest.raises(DataError, match=r"lanelet2_map\.osm: node 2: .*\(1e\+308, 50\) lies more"):
        read_lanelet2(path)
