"""Strategies for regions of interest: road corridors, junctions, random simple polygons.

Every strategy draws a few small integers (widths in 0.5 m steps, angles in degrees,
curvature steps) and builds an :class:`~pytest_metamorphic.lidar.roi.ROI` from them, so
failures shrink toward a plain straight road: a 7 m wide rectangle along x through the
sensor. :func:`rois` mixes all kinds and shrinks toward that rectangle too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic.layout import (
    MIN_ROAD_WIDTH,
    ROAD_KINDS,
    WIDTH_STEP,
    Chooser,
    RoadKind,
    corridor_roi,
    junction_roi,
    star_roi,
)

__all__ = ["junctions", "road_corridors", "rois", "simple_polygons"]

_KINDS: tuple[RoadKind, ...] = ROAD_KINDS


def _integers(draw: st.DrawFn) -> Chooser:
    """The layout chooser backed by Hypothesis: every choice shrinks toward ``low``."""
    return lambda low, high: draw(st.integers(low, high))


def _raster_options(cell_size: Any, extend_dist: Any, raster_range: Any) -> dict[str, float]:
    # Build (and so validate) once, early, with a unit square.
    square = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
    ROI.from_polygons(
        [square], cell_size=cell_size, extend_dist=extend_dist, raster_range=raster_range
    )
    return {
        "cell_size": float(cell_size),
        "extend_dist": float(extend_dist),
        "raster_range": float(raster_range),
    }


def _check_length(value: Any, name: str, minimum: float = 0.0) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name}={value!r} must be a number of metres")
    if not (math.isfinite(value) and value > minimum):
        raise InvalidArgument(f"{name}={value!r} must be finite and > {minimum}")
    return float(value)


def _road_options(min_width: Any, max_width: Any, length: Any) -> dict[str, Any]:
    """Validated width range (as 0.5 m steps above ``min_width``) and length of a road."""
    min_width = _check_length(min_width, "min_width", 2.0)
    max_width = _check_length(max_width, "max_width", 2.0)
    length = _check_length(length, "length", 2.0)
    if max_width < min_width:
        raise InvalidArgument(f"max_width={max_width} must be >= min_width={min_width}")
    width_steps = int((max_width - min_width) / WIDTH_STEP)
    return {"min_width": min_width, "width_steps": width_steps, "length": length}


@st.composite
def _corridor(draw: st.DrawFn, /, **options: Any) -> ROI:
    return corridor_roi(_integers(draw), **options)


def road_corridors(
    *,
    curved: bool = True,
    min_width: float = MIN_ROAD_WIDTH,
    max_width: float = 20.0,
    length: float = 240.0,
    cell_size: float = 0.25,
    extend_dist: float = 0.0,
    raster_range: float = 120.0,
) -> st.SearchStrategy[ROI]:
    """A single road through the sensor, straight or bending with constant curvature.

    Parameters
    ----------
    curved : bool
      Also draw bends (radius down to 50 m); they shrink to straight roads.
    min_width, max_width : float
      Road width in metres, drawn in 0.5 m steps; shrinks to ``min_width``.
    length : float
      Length of the road in metres, centred on the sensor.
    cell_size, extend_dist, raster_range
      Passed to :meth:`ROI.from_polygons`.

    Notes
    -----
    The sensor is inside the road, at least 1 m from its edges; heading is drawn in whole
    degrees in [-90, 90] and shrinks to 0 (road along x).
    """
    options = _road_options(min_width, max_width, length)
    raster = _raster_options(cell_size, extend_dist, raster_range)
    return _corridor(curved=bool(curved), **options, **raster)


@st.composite
def _junction(draw: st.DrawFn, /, **options: Any) -> ROI:
    return junction_roi(_integers(draw), **options)


def junctions(
    *,
    min_width: float = MIN_ROAD_WIDTH,
    max_width: float = 16.0,
    length: float = 150.0,
    cell_size: float = 0.25,
    extend_dist: float = 0.0,
    raster_range: float = 120.0,
) -> st.SearchStrategy[ROI]:
    """T-junctions and crossroads: road polygons for 3 or 4 arms plus a junction polygon.

    The sensor is on the arm behind the junction (0-40 m before it). Arms deviate from
    right angles by up to 30 degrees in 5 degree steps; everything shrinks toward a
    straight T at the sensor's position.
    """
    options = _road_options(min_width, max_width, length)
    raster = _raster_options(cell_size, extend_dist, raster_range)
    return _junction(**options, **raster)


@st.composite
def _star_polygon(draw: st.DrawFn, /, **options: Any) -> ROI:
    return star_roi(_integers(draw), **options)


def simple_polygons(
    *,
    min_vertices: int = 3,
    max_vertices: int = 12,
    min_radius: float = 5.0,
    max_radius: float = 80.0,
    cell_size: float = 0.25,
    extend_dist: float = 0.0,
    raster_range: float = 120.0,
) -> st.SearchStrategy[ROI]:
    """Random simple polygons around the sensor (star-shaped, so always valid).

    Vertex radii are whole metres in ``[min_radius, max_radius]``; angles are jittered
    from a regular polygon. Shrinks toward a regular ``min_vertices``-gon of ``min_radius``.
    """
    options = _raster_options(cell_size, extend_dist, raster_range)
    for name, value in (("min_vertices", min_vertices), ("max_vertices", max_vertices)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 3:
            raise InvalidArgument(f"{name}={value!r} must be an int >= 3")
    if max_vertices < min_vertices:
        raise InvalidArgument(f"max_vertices={max_vertices} must be >= min_vertices={min_vertices}")
    min_radius = _check_length(min_radius, "min_radius", 0.0)
    max_radius = _check_length(max_radius, "max_radius", 0.0)
    if max_radius < min_radius:
        raise InvalidArgument(f"max_radius={max_radius} must be >= min_radius={min_radius}")
    return _star_polygon(
        min_vertices=min_vertices,
        max_vertices=max_vertices,
        min_radius=min_radius,
        max_radius=max_radius,
        **options,
    )


def rois(
    *,
    kinds: Sequence[RoadKind] = _KINDS,
    cell_size: float = 0.25,
    extend_dist: float = 0.0,
    raster_range: float = 120.0,
) -> st.SearchStrategy[ROI]:
    """Any of the ROI kinds; shrinks toward a straight 7 m road along x through the sensor.

    Parameters
    ----------
    kinds : sequence of {"corridor", "curved", "junction", "polygon"}
      Which strategies to mix ("corridor" is straight roads only).
    """
    chosen: tuple[str, ...] = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    unknown = [kind for kind in chosen if kind not in _KINDS]
    if unknown or not chosen:
        raise InvalidArgument(f"kinds={kinds!r} must be a non-empty subset of {_KINDS}")
    options: dict[str, Any] = {
        "cell_size": cell_size,
        "extend_dist": extend_dist,
        "raster_range": raster_range,
    }
    # Ordered simplest first: st.one_of shrinks toward its first branch.
    builders = {
        "corridor": lambda: road_corridors(curved=False, **options),
        "curved": lambda: road_corridors(curved=True, **options),
        "junction": lambda: junctions(**options),
        "polygon": lambda: simple_polygons(**options),
    }
    return st.one_of([builders[kind]() for kind in _KINDS if kind in chosen])
