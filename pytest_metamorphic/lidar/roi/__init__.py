"""Regions of interest: HD-map road and junction polygons, exact and Apollo-rasterised.

One concept per module: :mod:`.region` (the :class:`ROI` type and its containment
methods), :mod:`.polygon` (validation and vectorised polygon geometry), :mod:`.raster`
(Apollo's scan conversion into a 0.25 m bitmap), :mod:`.roads` (corridors and
junctions built from road centre lines) and :mod:`.without_map` (an ego corridor or the
whole sweep, for recordings without an HD map).
"""

from pytest_metamorphic.lidar.roi.polygon import validate_polygon
from pytest_metamorphic.lidar.roi.raster import CellSet
from pytest_metamorphic.lidar.roi.region import ROI, ContainmentMethod
from pytest_metamorphic.lidar.roi.without_map import corridor_roi, whole_sweep_roi

__all__ = [
    "ROI",
    "CellSet",
    "ContainmentMethod",
    "corridor_roi",
    "validate_polygon",
    "whole_sweep_roi",
]
