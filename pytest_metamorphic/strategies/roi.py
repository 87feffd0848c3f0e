"""Strategies for regions of interest: road corridors, junctions, random simple polygons.

Every strategy draws a few small integers (widths in 0.5 m steps, angles in degrees,
curvature steps) and builds an :class:`~pytest_metamorphic.lidar.roi.ROI` from them, so
failures shrink toward a plain straight road: a 7 m wide rectangle along x through the
sensor. :func:`rois` mixes all kinds and shrinks toward that rectangle too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.roi import ROI

__all__ = ["junctions", "road_corridors", "rois", "simple_polygons"]

RoiKind = Literal["corridor", "curved", "junction", "polygon"]
_KINDS: tuple[RoiKind, ...] = ("corridor", "curved", "junction", "polygon")
_MIN_WIDTH = 7.0  # two narrow lanes
_WIDTH_STEP = 0.5
# Curvature in steps of 1/500 m^-1: up to 1/50 m^-1 (a 50 m radius bend).
_CURVATURE_STEP = 1.0 / 500.0
_MAX_CURVATURE_STEPS = 10


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


def _width_steps(min_width: float, max_width: float) -> int:
    if max_width < min_width:
        raise InvalidArgument(f"max_width={max_width} must be >= min_width={min_width}")
    return int((max_width - min_width) / _WIDTH_STEP)


def _rotate(points: NDArray[np.float64], degrees: float) -> NDArray[np.float64]:
    theta = math.radians(degrees)
    c, s = math.cos(theta), math.sin(theta)
    return points @ np.array([[c, -s], [s, c]]).T


def _corridor_polygon(
    width: float, length: float, offset: float, heading_deg: float, curvature: float
) -> NDArray[np.float64]:
    """Left boundary then reversed right boundary of a road (Apollo's road polygon)."""
    if curvature == 0.0:
        s = np.array([-length / 2.0, length / 2.0])
        centre = np.stack([s, np.zeros(2)], axis=1)
        normal = np.tile([0.0, 1.0], (2, 1))
    else:
        # An arc of constant curvature through (0, 0) heading +x, at most half a turn.
        half = min(length / 2.0, math.pi / (2.0 * abs(curvature)))
        s = np.linspace(-half, half, 41)
        angle = s * curvature
        centre = np.stack([np.sin(angle) / curvature, (1.0 - np.cos(angle)) / curvature], axis=1)
        normal = np.stack([-np.sin(angle), np.cos(angle)], axis=1)
    # The sensor sits `offset` metres left of the centreline.
    centre = centre - np.array([0.0, offset])
    left = centre + normal * width / 2.0
    right = centre - normal * width / 2.0
    return _rotate(np.concatenate([left, right[::-1]]), heading_deg)


@st.composite
def _corridor(
    draw: Any,
    *,
    curved: bool,
    width_steps: int,
    min_width: float,
    length: float,
    options: dict[str, float],
) -> ROI:
    width = min_width + _WIDTH_STEP * draw(st.integers(0, width_steps))
    # Sensor within the road, at least 1 m from its edge, in 0.5 m steps.
    room = max(int((width / 2.0 - 1.0) / 0.5), 0)
    offset = 0.5 * draw(st.integers(-room, room))
    heading = float(draw(st.integers(-90, 90)))
    steps = draw(st.integers(-_MAX_CURVATURE_STEPS, _MAX_CURVATURE_STEPS)) if curved else 0
    polygon = _corridor_polygon(width, length, offset, heading, steps * _CURVATURE_STEP)
    return ROI.from_polygons([polygon], **options)


def road_corridors(
    *,
    curved: bool = True,
    min_width: float = _MIN_WIDTH,
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

    The sensor is inside the road, at least 1 m from its edges; heading is drawn in whole
    degrees in [-90, 90] and shrinks to 0 (road along x).
    """
    options = _raster_options(cell_size, extend_dist, raster_range)
    min_width = _check_length(min_width, "min_width", 2.0)
    max_width = _check_length(max_width, "max_width", 2.0)
    length = _check_length(length, "length", 2.0)
    return _corridor(
        curved=bool(curved),
        width_steps=_width_steps(min_width, max_width),
        min_width=min_width,
        length=length,
        options=options,
    )


@st.composite
def _junction(
    draw: Any, *, width_steps: int, min_width: float, length: float, options: dict[str, float]
) -> ROI:
    arms = draw(st.integers(3, 4))
    width = min_width + _WIDTH_STEP * draw(st.integers(0, width_steps))
    # Junction centre ahead of the sensor in whole metres; the sensor stays on an arm.
    ahead = float(draw(st.integers(0, 40)))
    heading = float(draw(st.integers(-90, 90)))
    skews = [5.0 * draw(st.integers(-6, 6)) for _ in range(arms)]
    half = width / 2.0
    polygons = []
    for arm in range(arms):
        # Arm 0 runs back past the sensor, so the sensor is always on the road.
        base = (180.0, 90.0, -90.0, 0.0)[arm]
        angle = base + (0.0 if arm == 0 else skews[arm])
        rectangle = np.array([[half, -half], [length, -half], [length, half], [half, half]])
        polygons.append(_rotate(rectangle, angle) + np.array([ahead, 0.0]))
    # The junction itself: a square joining the arms (Apollo keeps junctions separate).
    square = np.array([[-half, -half], [half, -half], [half, half], [-half, half]]) * 1.5
    polygons.append(square + np.array([ahead, 0.0]))
    return ROI.from_polygons([_rotate(p, heading) for p in polygons], **options)


def junctions(
    *,
    min_width: float = _MIN_WIDTH,
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
    options = _raster_options(cell_size, extend_dist, raster_range)
    min_width = _check_length(min_width, "min_width", 2.0)
    max_width = _check_length(max_width, "max_width", 2.0)
    length = _check_length(length, "length", 2.0)
    return _junction(
        width_steps=_width_steps(min_width, max_width),
        min_width=min_width,
        length=length,
        options=options,
    )


@st.composite
def _star_polygon(
    draw: Any,
    *,
    min_vertices: int,
    max_vertices: int,
    min_radius: float,
    max_radius: float,
    options: dict[str, float],
) -> ROI:
    count = draw(st.integers(min_vertices, max_vertices))
    radius_steps = int(max_radius - min_radius)
    sector = 2.0 * math.pi / count
    # Angular gaps of at most 0.8 pi: the polygon is star-shaped around the sensor, hence
    # simple, and its edges pass at least min_radius * cos(0.4 pi) from the sensor.
    spread = min(0.9, 0.4 * count - 1.0)
    vertices = []
    for i in range(count):
        jitter = spread / 9.0 * sector * draw(st.integers(0, 9))
        radius = min_radius + draw(st.integers(0, radius_steps))
        angle = i * sector + jitter
        vertices.append((radius * math.cos(angle), radius * math.sin(angle)))
    return ROI.from_polygons([np.array(vertices)], **options)


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
        options=options,
    )


def rois(
    *,
    kinds: Sequence[RoiKind] = _KINDS,
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
    kinds = tuple(kinds) if not isinstance(kinds, str) else (kinds,)
    unknown = [kind for kind in kinds if kind not in _KINDS]
    if unknown or not kinds:
        raise InvalidArgument(f"kinds={kinds!r} must be a non-empty subset of {_KINDS}")
    options = {"cell_size": cell_size, "extend_dist": extend_dist, "raster_range": raster_range}
    # Ordered simplest first: st.one_of shrinks toward its first branch.
    builders = {
        "corridor": lambda: road_corridors(curved=False, **options),
        "curved": lambda: road_corridors(curved=True, **options),
        "junction": lambda: junctions(**options),
        "polygon": lambda: simple_polygons(**options),
    }
    return st.one_of([builders[kind]() for kind in _KINDS if kind in kinds])
