"""ROI strategies: valid ROIs around the sensor, and shrinking toward a plain rectangle."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.strategies import junctions, road_corridors, rois, simple_polygons
from tests.deterministic import find

ORIGIN = np.zeros((1, 2))
NO_DB = settings(database=None, deadline=None)


@settings(max_examples=40)
@given(roi=rois())
def test_every_roi_is_valid_and_holds_the_sensor(roi):
    assert isinstance(roi, ROI)
    # Apollo refuses frames whose sensor is outside the ROI ("Car is not in roi").
    assert roi.contains(ORIGIN)[0]
    assert roi.contains(ORIGIN, method="exact")[0]
    assert roi.bitmap.any()
    assert (roi.cell_size, roi.raster_range) == (0.25, 120.0)


@settings(max_examples=15)
@given(roi=road_corridors(min_width=8.0, max_width=10.0))
def test_corridors_have_the_requested_width(roi):
    assert len(roi.polygons) == 1
    # Probing across the road at the sensor: the road is 8-10 m wide there.
    polygon = roi.polygons[0]
    k = len(polygon) // 2
    width = np.linalg.norm(polygon[k // 2] - polygon[len(polygon) - 1 - k // 2])
    assert 8.0 - 1e-6 <= width <= 10.0 + 1e-6


def test_rois_shrink_to_a_plain_straight_road():
    roi = find(rois(), lambda roi: True, settings=NO_DB)
    assert len(roi.polygons) == 1
    polygon = roi.polygons[0]
    assert sorted(map(tuple, polygon)) == [(-120, -3.5), (-120, 3.5), (120, -3.5), (120, 3.5)]


def test_shrinking_keeps_only_what_the_failure_needs():
    straight = road_corridors(curved=False)
    wide = find(straight, lambda roi: roi.area() > 240 * 10, settings=NO_DB)
    assert wide.area() == pytest.approx(240 * 10.5)  # the next 0.5 m step
    assert sorted(wide.polygons[0][:, 1]) == [-5.25, -5.25, 5.25, 5.25]  # heading 0
    bend = find(road_corridors(), lambda roi: len(roi.polygons[0]) > 4, settings=NO_DB)
    # The smallest bend: curvature 1/500 m^-1, a 7 m road along x.
    assert len(bend.polygons[0]) == 82
    assert bend.bounds[1, 1] == pytest.approx(3.5 + 120**2 / 1000, abs=0.3)
    many = find(rois(), lambda roi: len(roi.polygons) >= 5, settings=NO_DB)
    assert len(many.polygons) == 5  # a crossroads: 4 arms + junction
    triangle = find(simple_polygons(), lambda roi: True, settings=NO_DB)
    assert len(triangle.polygons[0]) == 3
    assert np.allclose(np.hypot(*triangle.polygons[0].T), 5.0)


@settings(max_examples=15)
@given(roi=junctions(), data=st.data())
def test_junctions_connect_the_arms(roi, data):
    assert 4 <= len(roi.polygons) <= 5
    # Every arm's far end is reachable: the union holds a point on each arm 60 m out.
    centre = roi.polygons[-1].mean(axis=0)
    for arm in roi.polygons[:-1]:
        far = arm[[1, 2]].mean(axis=0)
        direction = (far - centre) / np.linalg.norm(far - centre)
        assert roi.contains((centre + 60 * direction)[None], method="exact")[0]


def test_extend_dist_and_cell_size_are_passed_through():
    roi = find(rois(cell_size=0.5, extend_dist=0.2), lambda roi: True, settings=NO_DB)
    assert (roi.cell_size, roi.extend_dist) == (0.5, 0.2)


@pytest.mark.parametrize(
    ("factory", "options", "message"),
    [
        (rois, {"kinds": ("motorway",)}, "kinds"),
        (rois, {"kinds": ()}, "kinds"),
        (rois, {"cell_size": -1}, "cell_size"),
        (road_corridors, {"min_width": 10, "max_width": 8}, "max_width"),
        (road_corridors, {"length": float("inf")}, "length"),
        (junctions, {"raster_range": 0}, "raster_range"),
        (simple_polygons, {"min_vertices": 2}, "min_vertices"),
        (simple_polygons, {"min_radius": 9, "max_radius": 5}, "max_radius"),
    ],
)
def test_bad_arguments_fail_early(factory, options, message):
    with pytest.raises(InvalidArgument, match=message):
        factory(**options)
