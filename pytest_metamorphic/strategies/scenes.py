"""Strategies for synthetic LiDAR scenes and the frames rendered from them.

:func:`scenes` draws a small :class:`~pytest_metamorphic.lidar.scene.Scene`: an ROI, a
sensor height, a list of obstacles on the road (class sizes from
:data:`~pytest_metamorphic.lidar.obstacles.SIZE_PRIORS`, headings in 5 degree steps) and
a list of background objects outside the ROI (poles, trees, buildings).

Obstacles occupy distinct *slots*: points of an 8 m lattice through (10, 0) that lie deep
inside the ROI, ordered by distance from (10, 0), each jittered by up to ±0.5 m. Distinct
slots cannot overlap (the largest car fits in a 2.8 m circle), so no obstacle is ever
dropped for colliding with another (an obstacle drawn onto a taken slot moves to the next
free one): deleting an obstacle never deletes others, and failures shrink cleanly toward
fewer obstacles, then toward a car of average size, heading along x, 10 m ahead, on a
straight road.

:func:`scene_frames` renders drawn scenes with the HDL-64E model into
:class:`~pytest_metamorphic.lidar.frame.Frame` objects that carry their ground truth.
"""

from __future__ import annotations

import functools
import math
import sys
import types
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.obstacles import LABELS, SIZE_PRIORS, Box, Label
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.scene import (
    BackgroundObject,
    CastEngine,
    MeshShape,
    Obstacle,
    Scene,
    render,
)
from pytest_metamorphic.strategies.roi import rois

__all__ = ["scene_frames", "scenes"]

_SIZE_STEPS = 5  # size = mean +- k/5 of the way to the prior's bound
_YAW_STEP_DEG = 5
_EGO_CLEARANCE = 4.0  # metres kept free around the sensor (the ego vehicle)
_SLOT_SPACING = 8.0  # metres between obstacle slots
_JITTER_STEP = 0.25  # metres
_JITTER_STEPS = 2  # up to +-0.5 m: slots stay >= 6.5 m apart, obstacles >= 0.9 m apart
# Largest footprint radius of any prior (a 5.2 x 2.0 m car).
_MAX_RADIUS = max(math.hypot(p.high[0], p.high[1]) / 2.0 for p in SIZE_PRIORS.values())
_BACKGROUND_RANGE = 80.0
_HEIGHT_STEP = 0.01
_DEFAULT_HEIGHT = 1.73  # KITTI's HDL-64E
# Background kinds: (length, width, height) bounds in metres; shrink to the lower bound.
_BACKGROUND_SIZES: Mapping[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "pole": ((0.2, 0.2, 4.0), (0.5, 0.5, 10.0)),
    "tree": ((2.0, 2.0, 4.0), (6.0, 6.0, 12.0)),
    "building": ((6.0, 6.0, 4.0), (20.0, 14.0, 15.0)),
}
_BACKGROUND_ORDER = ("pole", "tree", "building")


@functools.lru_cache(maxsize=16)
def _obstacle_slots(roi: ROI, max_distance: float) -> NDArray[np.float64]:
    """Lattice points where an obstacle may stand, nearest to (10, 0) first."""
    steps = math.ceil((max_distance + 10.0) / _SLOT_SPACING)
    i, j = np.meshgrid(np.arange(-steps, steps + 1), np.arange(-steps, steps + 1), indexing="ij")
    slots = np.stack([10.0 + _SLOT_SPACING * i.ravel(), _SLOT_SPACING * j.ravel()], axis=1)
    distance = np.hypot(slots[:, 0], slots[:, 1])
    jitter = _JITTER_STEPS * _JITTER_STEP * math.sqrt(2.0)
    # Clear of the ego vehicle whatever the obstacle's size, jitter and heading.
    near = _EGO_CLEARANCE + _MAX_RADIUS + jitter
    slots = slots[(distance >= near) & (distance <= max_distance - jitter)]
    # Deep inside the ROI: the jittered centre stays in interior cells.
    margin = math.ceil(jitter / roi.cell_size) + 1
    interior = roi.interior_cells(margin_cells=margin)
    ix, iy = roi.cell_index(slots)
    inside = (ix >= 0) & (ix < roi.grid_size) & (iy >= 0) & (iy < roi.grid_size)
    inside[inside] = interior[ix[inside], iy[inside]]
    slots = slots[inside]
    order = np.argsort(np.hypot(slots[:, 0] - 10.0, slots[:, 1]), kind="stable")
    return np.ascontiguousarray(slots[order])


@functools.lru_cache(maxsize=16)
def _background_sites(roi: ROI, kind: str) -> NDArray[np.float64]:
    """Centres of free cells far enough from the ROI for the largest object of a kind."""
    (_, _, _), (length, width, _) = _BACKGROUND_SIZES[kind]
    radius = math.hypot(length, width) / 2.0
    margin = math.ceil((radius + 0.5) / roi.cell_size)
    limit = min(_BACKGROUND_RANGE, roi.raster_range)
    origins = roi.cell_origins("free", margin_cells=margin, max_range=limit)
    return origins + roi.cell_size / 2.0


def _prior_size(label: Label, steps: Sequence[int]) -> tuple[float, float, float]:
    prior = SIZE_PRIORS[label]
    size = []
    for k, mean, low, high in zip(steps, prior.mean, prior.low, prior.high, strict=True):
        bound = high if k > 0 else low
        size.append(mean + abs(k) / _SIZE_STEPS * (bound - mean))
    return (size[0], size[1], size[2])


def _digits(value: int, radices: Sequence[int]) -> list[int]:
    """Mixed-radix digits of ``value``, least significant first.

    One integer per object instead of one per attribute: Hypothesis' shrinker deletes list
    elements reliably only when each element is a few choices (with eight it was seen to
    stop at [car, car, car, pedestrian] for "has a pedestrian"), and 0 decodes to the
    simplest object.
    """
    digits = []
    for radix in radices:
        value, digit = divmod(value, radix)
        digits.append(digit)
    return digits


def _decode(value: int, radices: Sequence[int]) -> list[int]:
    """:func:`_digits` mapped 0, 1, 2, 3, 4, ... -> 0, +1, -1, +2, -2, ... (0 stays simplest)."""
    return [(d + 1) // 2 if d % 2 else -(d // 2) for d in _digits(value, radices)]


def _check_count(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise InvalidArgument(f"{name}={value!r} must be a non-negative int")
    return value


def _user_shapes(shapes: Any, labels: Sequence[Label]) -> dict[str, tuple[MeshShape, ...]]:
    if shapes is None:
        return {}
    if not isinstance(shapes, Mapping):
        raise InvalidArgument(f"shapes must map labels to lists of MeshShape, got {shapes!r}")
    result = {}
    for label, items in shapes.items():
        if label not in LABELS:
            raise InvalidArgument(f"shapes has label {label!r}; labels are {LABELS}")
        items = (items,) if isinstance(items, MeshShape) else tuple(items)
        for item in items:
            if not isinstance(item, MeshShape):
                raise InvalidArgument(
                    f"shapes[{label!r}] holds {item!r}; load meshes with MeshShape.from_file"
                )
        result[label] = items
    return result


_HEIGHTS = st.integers(-10, 17)
_SLOT_CHOICES = 2**16  # slot index modulo the ROI's slot count; shrinks to the nearest
_CLUTTER_RADICES = (18, 11, 11, 11)  # yaw in 10 degree steps, then size steps


def _obstacle_radices(shape_count: int) -> tuple[int, ...]:
    """Radices of an obstacle's "variation" integer, least significant first: shape,
    heading, size (length, width, height), jitter (x, y). See :func:`_decode`."""
    return (
        shape_count,
        2 * (180 // _YAW_STEP_DEG) + 1,
        *(2 * _SIZE_STEPS + 1,) * 3,
        *(2 * _JITTER_STEPS + 1,) * 2,
    )


@st.composite
def _scenes(
    draw: Any,
    *,
    roi_strategy: st.SearchStrategy[ROI],
    obstacle_lists: st.SearchStrategy[list[tuple[Label, int, int]]],
    clutter_lists: st.SearchStrategy[list[tuple[str, int, int]]],
    min_obstacles: int,
    shapes: dict[str, tuple[MeshShape, ...]],
    max_distance: float,
) -> Scene:
    # Strategies are built once in scenes(): building them per draw costs Hypothesis
    # more than the scene itself.
    roi = draw(roi_strategy)
    height = _DEFAULT_HEIGHT + _HEIGHT_STEP * draw(_HEIGHTS)
    slots = _obstacle_slots(roi, max_distance)
    specs = draw(obstacle_lists)
    # Too few slots in this ROI for the obstacles asked for: reject (rare; the default
    # roads have 10 or more slots).
    assume(len(slots) >= max(len(specs), min_obstacles))
    radices = _obstacle_radices(1 + max((len(v) for v in shapes.values()), default=0))
    obstacles = []
    taken: set[int] = set()
    for label, drawn_slot, variation in specs:
        # A taken slot passes the obstacle on to the next free one. (Not unique_by: the
        # shrinker cannot delete the first of two unique elements, and dropping the
        # obstacle instead would let deletions resurrect others.)
        slot = drawn_slot % len(slots)
        while slot in taken:
            slot = (slot + 1) % len(slots)
        taken.add(slot)
        shape_index, yaw_steps, *size_steps, dx, dy = _decode(variation, radices)
        size = _prior_size(label, size_steps)
        x = float(slots[slot, 0]) + _JITTER_STEP * dx
        y = float(slots[slot, 1]) + _JITTER_STEP * dy
        yaw = math.radians(_YAW_STEP_DEG * yaw_steps)
        box = Box((x, y, -height + size[2] / 2.0), size, yaw, label)
        choices = ("auto", *shapes.get(label, ()))
        obstacles.append(Obstacle(box, shape=choices[abs(shape_index) % len(choices)]))
    background: list[BackgroundObject] = []
    items = draw(clutter_lists)
    for kind, site, variation in items:
        candidates = _background_sites(roi, kind)
        if len(candidates) == 0:
            continue
        yaw_steps, *size_steps = _digits(variation, _CLUTTER_RADICES)
        low, high = _BACKGROUND_SIZES[kind]
        size = tuple(
            lo + k / 10.0 * (hi - lo) for k, lo, hi in zip(size_steps, low, high, strict=True)
        )
        if kind != "building":
            size = (size[0], size[0], size[2])  # round things
        x, y = candidates[site % len(candidates)]
        item = BackgroundObject(kind, (float(x), float(y)), size, yaw=math.radians(10 * yaw_steps))
        # Background objects may overlap each other (a tree against a building): dropping
        # one for colliding with another would make shrinking order-dependent.
        background.append(item)
    return Scene(
        sensor_height=round(height, 6),
        roi=roi,
        obstacles=tuple(obstacles),
        background=tuple(background),
        name="generated",
    )


def scenes(
    *,
    roi: ROI | st.SearchStrategy[ROI] | None = None,
    min_obstacles: int = 0,
    max_obstacles: int = 6,
    labels: Sequence[Label] = LABELS,
    max_background: int = 6,
    shapes: Mapping[Label, Sequence[MeshShape]] | None = None,
    max_distance: float = 50.0,
) -> st.SearchStrategy[Scene]:
    """Small synthetic scenes: ROI, sensor height, obstacles on the road, clutter beside it.

    Parameters
    ----------
    roi : ROI or strategy of ROI, optional
      A fixed ROI or where to draw one; default: straight and curved roads and junctions
      from :mod:`pytest_metamorphic.strategies.roi`.
    min_obstacles, max_obstacles : int
      Obstacles per scene. They stand deep inside the ROI within ``max_distance`` metres
      of the sensor, at least 0.9 m apart and 4 m from the sensor (the ego vehicle).
      Scenes whose ROI has fewer slots than ``min_obstacles`` are rejected.
    labels : sequence of {"car", "pedestrian", "cyclist", "unknown"}
      Classes to draw, simplest first (shrinking moves toward ``labels[0]``).
    max_background : int
      Poles, trees and buildings outside the ROI (never touching it).
    shapes : mapping of label to MeshShape list, optional
      User meshes (e.g. a car model file) drawn alongside the built-in shapes.
    max_distance : float
      Farthest obstacle centre, metres.

    Sensor height is 1.73 m (KITTI) +10/-17 cm in 1 cm steps.
    """
    min_obstacles = _check_count(min_obstacles, "min_obstacles")
    max_obstacles = _check_count(max_obstacles, "max_obstacles")
    max_background = _check_count(max_background, "max_background")
    if max_obstacles < min_obstacles:
        raise InvalidArgument(
            f"max_obstacles={max_obstacles} must be >= min_obstacles={min_obstacles}"
        )
    labels = (labels,) if isinstance(labels, str) else tuple(labels)
    if not labels or any(label not in LABELS for label in labels):
        raise InvalidArgument(f"labels={labels!r} must be a non-empty subset of {LABELS}")
    if isinstance(max_distance, bool) or not isinstance(max_distance, (int, float)):
        raise InvalidArgument(f"max_distance={max_distance!r} must be a number of metres")
    if not (math.isfinite(max_distance) and max_distance > _EGO_CLEARANCE + 2):
        raise InvalidArgument(f"max_distance={max_distance!r} must be > {_EGO_CLEARANCE + 2} m")
    if roi is None:
        roi_strategy = rois(kinds=("corridor", "curved", "junction"))
    elif isinstance(roi, ROI):
        roi_strategy = st.just(roi)
    elif isinstance(roi, st.SearchStrategy):
        roi_strategy = roi
    else:
        raise InvalidArgument(f"roi must be an ROI, a strategy of ROI or None, got {roi!r}")
    user_shapes = _user_shapes(shapes, labels)
    radices = _obstacle_radices(1 + max((len(v) for v in user_shapes.values()), default=0))
    obstacle = st.tuples(
        st.sampled_from(labels),
        st.integers(0, _SLOT_CHOICES - 1),
        st.integers(0, math.prod(radices) - 1),
    )
    clutter = st.tuples(
        st.sampled_from(_BACKGROUND_ORDER),
        st.integers(0, 2**24),
        st.integers(0, math.prod(_CLUTTER_RADICES) - 1),
    )
    return _scenes(
        roi_strategy=roi_strategy,
        obstacle_lists=st.lists(obstacle, min_size=min_obstacles, max_size=max_obstacles),
        clutter_lists=st.lists(clutter, max_size=max_background),
        min_obstacles=min_obstacles,
        shapes=user_shapes,
        max_distance=float(max_distance),
    )


def scene_frames(
    scene_strategy: st.SearchStrategy[Scene] | None = None,
    *,
    beams: BeamLayout = HDL64E,
    seed: int = 0,
    range_noise: float | None = None,
    engine: CastEngine = "auto",
) -> st.SearchStrategy[Frame]:
    """Frames rendered from drawn scenes (default: :func:`scenes` with its defaults).

    Rendering is deterministic (``seed`` fixes the range noise), so a failing example
    replays exactly; each frame's ``boxes`` are its obstacles with point counts.
    """
    if scene_strategy is None:
        scene_strategy = scenes()
    if not isinstance(scene_strategy, st.SearchStrategy):
        raise InvalidArgument(f"scene_strategy must be a strategy of Scene, got {scene_strategy!r}")
    if not isinstance(beams, BeamLayout):
        raise InvalidArgument(f"beams must be a BeamLayout, got {beams!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InvalidArgument(f"seed={seed!r} must be a non-negative int")
    if engine not in ("auto", "embree", "numpy"):
        raise InvalidArgument(f"engine={engine!r} must be 'auto', 'embree' or 'numpy'")
    return scene_strategy.map(
        functools.partial(render, beams=beams, seed=seed, range_noise=range_noise, engine=engine)
    )


class _CallableModule(types.ModuleType):
    """This module, callable as :func:`scenes`.

    ``pytest_metamorphic.strategies`` looks strategies up lazily by name, but importing
    this submodule binds the package attribute ``scenes`` to the *module* (the same name
    as the function). Calling the module forwards to the function, so ``mst.scenes(...)``
    works whatever was imported first (as ``strategies.frames`` does).
    """

    def __call__(self, *args: Any, **kwargs: Any) -> st.SearchStrategy[Scene]:
        return scenes(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
