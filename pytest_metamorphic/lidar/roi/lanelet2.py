"""An ROI from a lane-level HD map in Lanelet2's format, as Apollo builds its ROI from the
HD map's road polygons: every drivable lanelet near the sensor, in the sensor's frame."""

from __future__ import annotations

import math
import os
from collections.abc import Collection, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.io.lanelet2 import Lanelet, read_lanelet2
from pytest_metamorphic.lidar.roi.region import ROI

__all__ = ["ROAD_SUBTYPES", "lanelet2_roi"]

ROAD_SUBTYPES = frozenset({"road", "highway", "play_street", "bus_lane", "emergency_lane", ""})
"""Lanelet subtypes that are road (crosswalks, walkways, stairs and bicycle lanes are not)."""


def _sensor_pose(pose: ArrayLike) -> NDArray[np.float64]:
    """A (3, 3) map-from-sensor transform from ``(x, y, yaw)`` or a (4, 4) matrix."""
    try:
        matrix = np.asarray(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidArgument(f"pose={pose!r} must be (x, y, yaw) or a (4, 4) matrix") from None
    if matrix.shape == (3,):
        x, y, yaw = matrix
        c, s = math.cos(yaw), math.sin(yaw)
        matrix = np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])
    elif matrix.shape == (4, 4):
        matrix = np.array(
            [[*matrix[0, :2], matrix[0, 3]], [*matrix[1, :2], matrix[1, 3]], [0.0, 0.0, 1.0]]
        )
    else:
        raise InvalidArgument(
            f"pose must be (x, y, yaw) or a (4, 4) matrix, got shape {matrix.shape}"
        )
    if not np.isfinite(matrix).all():
        raise InvalidArgument("pose has NaN or infinite entries")
    return matrix


def lanelet2_roi(
    lanelets: str | os.PathLike[str] | Sequence[Lanelet],
    *,
    pose: ArrayLike = (0.0, 0.0, 0.0),
    subtypes: Collection[str] = ROAD_SUBTYPES,
    raster_range: float = 120.0,
    origin: tuple[float, float] | None = None,
) -> ROI:
    """The road lanelets of a Lanelet2 map within ``raster_range`` of the sensor, as an ROI
    in the sensor's frame.

    Parameters
    ----------
    lanelets : path or sequence of Lanelet
        A Lanelet2 ``.osm`` file (:func:`~pytest_metamorphic.lidar.io.lanelet2.read_lanelet2`)
        or its lanelets, read once for many frames.
    pose : (x, y, yaw) or (4, 4) array_like
        The sensor's pose in the map's local frame (metres, radians; a 4 x 4
        sensor-to-map matrix, e.g. ``Frame.pose`` in the map's frame).
    subtypes : collection of str
        Which lanelets are road (:data:`ROAD_SUBTYPES`).
    raster_range : float
        The ROI's bitmap half-width; lanelets wholly beyond it are left out.
    origin : (lat, lon), optional
        For a path: see :func:`~pytest_metamorphic.lidar.io.lanelet2.read_lanelet2`.
    """
    if isinstance(lanelets, (str, os.PathLike)):
        lanelets = read_lanelet2(lanelets, origin=origin)
    chosen = frozenset(subtypes)
    map_from_sensor = _sensor_pose(pose)
    sensor_from_map = np.linalg.inv(map_from_sensor)
    polygons = []
    for lanelet in lanelets:
        if not isinstance(lanelet, Lanelet):
            raise InvalidArgument(f"lanelets must be Lanelet objects or a path, got {lanelet!r}")
        if lanelet.subtype not in chosen:
            continue
        vertices = lanelet.polygon()
        local = vertices @ sensor_from_map[:2, :2].T + sensor_from_map[:2, 2]
        # Kept when its bounding box meets the bitmap's square around the sensor.
        low, high = local.min(axis=0), local.max(axis=0)
        if (low <= raster_range).all() and (high >= -raster_range).all():
            polygons.append(local)
    if not polygons:
        raise InvalidArgument(
            f"no lanelet of subtypes {sorted(chosen)} lies within {raster_range} m of the "
            f"sensor at pose {np.asarray(pose).tolist()}"
        )
    return ROI.from_polygons(polygons, raster_range=raster_range)
