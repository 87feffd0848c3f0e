"""Regions of interest for recordings without an HD map: a corridor along the ego path,
or an explicit choice of the whole sweep.

Every LiDAR relation judges obstacles in ``frame.roi``. A recording with an HD map gets
Apollo's road polygons (:meth:`ROI.from_apollo_poly`); OpenStreetMap roads give
:meth:`ROI.from_roads`; KITTI's labels give
:func:`~pytest_metamorphic.lidar.judging.evaluation.kitti_label_region`. Without any of
these, :func:`corridor_roi` is the road ahead as the ego vehicle drives it, and
:func:`whole_sweep_roi` says, explicitly, that every obstacle within a radius is judged
(MR1 then has no "outside" to put noise in, and reports that it tested nothing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.roi.region import ROI

__all__ = ["corridor_roi", "whole_sweep_roi"]


def _positive(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name}={value!r} must be a positive number of metres")
    if not (math.isfinite(value) and value > 0):
        raise InvalidArgument(f"{name}={value!r} must be a positive number of metres")
    return float(value)


@dataclass(frozen=True)
class _Path:
    centerline: NDArray[np.float64]
    width: float


def corridor_roi(
    path: ArrayLike | None = None,
    *,
    width: float = 7.0,
    ahead: float = 60.0,
    behind: float = 10.0,
    raster_range: float = 120.0,
) -> ROI:
    """The corridor ``width`` metres wide along the ego path: every point within
    ``width / 2`` of it (so its ends are rounded, reaching ``width / 2`` beyond the path's).

    Parameters
    ----------
    path : (k, 2) array_like, optional
        The ego vehicle's path in the sensor frame (x forward, y left), metres, k >= 2:
        from odometry, a planned trajectory, or the poses of the next frames. Default: the
        straight line from ``behind`` metres back to ``ahead`` metres forward.
    width : float
        Metres (7 m: two lanes of 3.5 m).
    ahead, behind : float
        The straight default path's extent, metres.
    raster_range : float
        Half-width of the ROI's bitmap (see :meth:`ROI.from_polygons`).
    """
    width = _positive(width, "width")
    if path is None:
        ahead, behind = _positive(ahead, "ahead"), _positive(behind, "behind")
        points = np.array([[-behind, 0.0], [ahead, 0.0]])
    else:
        try:
            points = np.asarray(path, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidArgument(f"path must be a (k, 2) array of metres, got {path!r}") from None
        if points.ndim != 2 or points.shape[1] < 2 or len(points) < 2:
            raise InvalidArgument(f"path must be a (k >= 2, 2) array, got shape {points.shape}")
        points = points[:, :2]
        if not np.isfinite(points).all():
            raise InvalidArgument("path has NaN or infinite coordinates")
    return ROI.from_roads([_Path(points, width)], raster_range=raster_range)


_SENSOR_RANGE = 120.0  # metres: the noise relations' default max_range (the HDL-64E's)


def whole_sweep_roi(*, radius: float = 100.0) -> ROI:
    """Every obstacle within ``radius`` metres of the sensor is judged (a square of side
    ``2 * radius``): the explicit choice for a recording without a map, when the
    detector is expected to keep every obstacle under the transforms.

    The bitmap reaches past the sensor's range (120 m, the noise relations' default) so
    that "outside" is defined wherever noise can go: with ``radius=100`` MR1's noise
    lands beyond the square (100-120 m, in its corners and beyond its sides); with a
    radius of 120 m or more nothing lies outside within range, and the noise relations
    report that they tested nothing, with the reason."""
    radius = _positive(radius, "radius")
    corners = [(-radius, -radius), (radius, -radius), (radius, radius), (-radius, radius)]
    return ROI.from_polygons([corners], raster_range=max(radius, _SENSOR_RANGE) + 1.0)
