"""Regions of interest: HD-map road and junction polygons, exact and Apollo-rasterised.

One concept per module: :mod:`.region` (the :class:`ROI` type and its containment
methods), :mod:`.polygon` (validation and vectorised polygon geometry), :mod:`.raster`
(Apollo's scan conversion into a 0.25 m bitmap), :mod:`.roads` (corridors and
junctions built from road centre lines), :mod:`.lanelet2` (road lanelets of a Lanelet2
HD map, Autoware's format) and :mod:`.without_map` (an ego corridor or the whole sweep,
for recordings without an HD map).
"""

from pytest_metamorphic.lidar.roi.lanelet2 import ROAD_SUBTYPES, lanelet2_roi
from pytest_metamorphic.lidar.roi.polygon import validate_polygon
from pytest_metamorphic.lidar.roi.raster import CellSet
from pytest_metamorphic.lidar.roi.region import ROI, ContainmentMethod
from pytest_metamorphic.lidar.roi.without_map import corridor_roi, whole_sweep_roi

__all__ = [
    "ROAD_SUBTYPES",
    "ROI",
    "CellSet",
    "ContainmentMethod",
    "corridor_roi",
    "lanelet2_roi",
    "validate_polygon",
    "whole_sweep_roi",
]
