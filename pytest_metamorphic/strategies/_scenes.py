"""Strategies for synthetic LiDAR scenes and the frames rendered from them.

:func:`scenes` draws a small :class:`~pytest_metamorphic.lidar.synthetic.Scene`: an ROI, a
sensor height, a list of obstacles on the road (class sizes from
:data:`~pytest_metamorphic.lidar.model.obstacles.box.SIZE_PRIORS`, headings in 5 degree steps) and
a list of background objects outside the ROI (poles, trees, buildings).

Obstacles occupy distinct *slots*: points of an 8 m lattice through (10, 0) that lie deep
inside the ROI, ordered by distance from (10, 0), each jittered by up to ±0.5 m. Distinct
slots cannot overlap (the largest car fits in a 2.8 m circle), so no obstacle is ever
dropped for colliding with another (an obstacle drawn onto a taken slot moves to the next
free one): deleting an obstacle never deletes others, and failures shrink cleanly toward
fewer obstacles, then toward a car of average size, heading along x, 10 m ahead, on a
straight road.

:func:`scene_frames` renders drawn scenes with the HDL-64E model into
:class:`~pytest_metamorphic.lidar.model.frame.Frame` objects that carry their ground truth.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from typing import Any, cast

from hypothesis import assume
from hypothesis import strategies as st

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E
from pytest_metamorphic.lidar.model.obstacles import LABELS, Label
from pytest_metamorphic.lidar.model.sensors import ScanPattern, as_sensor
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic import (
    CastEngine,
    MeshShape,
    Scene,
    render,
)
from pytest_metamorphic.lidar.synthetic.layout import (
    BACKGROUND_ORDER,
    EGO_CLEARANCE,
    HEIGHT_STEPS,
    MAX_DISTANCE,
    SITE_CHOICES,
    SLOT_CHOICES,
    ClutterSpec,
    ObstacleSpec,
    TooFewSlots,
    clutter_radices,
    layout_scene,
    obstacle_radices,
)
from pytest_metamorphic.strategies._roi import rois

__all__ = ["scene_frames", "scenes"]


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


_HEIGHTS = st.integers(*HEIGHT_STEPS)


@st.composite
def _scenes(
    draw: st.DrawFn,
    *,
    roi_strategy: st.SearchStrategy[ROI],
    obstacle_lists: st.SearchStrategy[list[ObstacleSpec]],
    clutter_lists: st.SearchStrategy[list[ClutterSpec]],
    min_obstacles: int,
    shapes: dict[str, tuple[MeshShape, ...]],
    max_distance: float,
) -> Scene:
    # Strategies are built once in scenes(): building them per draw costs Hypothesis
    # more than the scene itself.
    roi = draw(roi_strategy)
    height_steps = draw(_HEIGHTS)
    try:
        return layout_scene(
            roi,
            height_steps=height_steps,
            obstacles=draw(obstacle_lists),
            clutter=draw(clutter_lists),
            min_obstacles=min_obstacles,
            shapes=shapes,
            max_distance=max_distance,
        )
    except TooFewSlots:
        # Too few slots in this ROI for the obstacles asked for: reject (rare; the
        # default roads have 10 or more slots).
        assume(False)
        raise  # unreachable: assume(False) raises


def scenes(
    *,
    roi: ROI | st.SearchStrategy[ROI] | None = None,
    min_obstacles: int = 0,
    max_obstacles: int = 6,
    labels: Sequence[Label] = LABELS,
    max_background: int = 6,
    shapes: Mapping[Label, Sequence[MeshShape]] | None = None,
    max_distance: float = MAX_DISTANCE,
) -> st.SearchStrategy[Scene]:
    """Small synthetic scenes: ROI, sensor height, obstacles on the road, clutter beside it.

    Parameters
    ----------
    roi : ROI or strategy of ROI, optional
      A fixed ROI or where to draw one; default: straight and curved roads and junctions
      from :func:`~pytest_metamorphic.strategies.rois`.
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
      Farthest obstacle centre, metres; by default 100 m, near the HDL-64E's 120 m
      range (sensor faults and edits that act only far away are exercised too).

    Notes
    -----
    Sensor height is 1.73 m (KITTI) +10/-17 cm in 1 cm steps.
    """
    min_obstacles = _check_count(min_obstacles, "min_obstacles")
    max_obstacles = _check_count(max_obstacles, "max_obstacles")
    max_background = _check_count(max_background, "max_background")
    if max_obstacles < min_obstacles:
        raise InvalidArgument(
            f"max_obstacles={max_obstacles} must be >= min_obstacles={min_obstacles}"
        )
    chosen: tuple[Label, ...] = (cast(Label, labels),) if isinstance(labels, str) else tuple(labels)
    if not chosen or any(label not in LABELS for label in chosen):
        raise InvalidArgument(f"labels={labels!r} must be a non-empty subset of {LABELS}")
    if isinstance(max_distance, bool) or not isinstance(max_distance, (int, float)):
        raise InvalidArgument(f"max_distance={max_distance!r} must be a number of metres")
    if not (math.isfinite(max_distance) and max_distance > EGO_CLEARANCE + 2):
        raise InvalidArgument(f"max_distance={max_distance!r} must be > {EGO_CLEARANCE + 2} m")
    if roi is None:
        roi_strategy = rois(kinds=("corridor", "curved", "junction"))
    elif isinstance(roi, ROI):
        roi_strategy = st.just(roi)
    elif isinstance(roi, st.SearchStrategy):
        roi_strategy = roi
    else:
        raise InvalidArgument(f"roi must be an ROI, a strategy of ROI or None, got {roi!r}")
    user_shapes = _user_shapes(shapes, chosen)
    radices = obstacle_radices(1 + max((len(v) for v in user_shapes.values()), default=0))
    obstacle = st.builds(
        ObstacleSpec,
        st.sampled_from(chosen),
        st.integers(0, SLOT_CHOICES - 1),
        st.integers(0, math.prod(radices) - 1),
    )
    clutter = st.builds(
        ClutterSpec,
        st.sampled_from(BACKGROUND_ORDER),
        st.integers(0, SITE_CHOICES),
        st.integers(0, math.prod(clutter_radices()) - 1),
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
    beams: ScanPattern = HDL64E,
    seed: int = 0,
    range_noise: float | None = None,
    engine: CastEngine = "auto",
    sensor: ScanPattern | str | None = None,
) -> st.SearchStrategy[Frame]:
    """Frames rendered from drawn scenes (default: :func:`scenes` with its defaults).

    Rendering is deterministic (``seed`` fixes the range noise), so a failing example
    replays exactly; each frame's ``boxes`` are its obstacles with point counts.
    ``sensor`` (a model of :mod:`pytest_metamorphic.lidar.model.sensors` or its key, e.g.
    ``"vlp16"``, ``"os1-128"``, ``"livox-mid40"``) renders with that sensor instead of
    ``beams`` (the HDL-64E); the frames carry it as ``frame.sensor``.
    """
    if sensor is not None:
        beams = _sensor_argument(sensor)
    if scene_strategy is None:
        scene_strategy = scenes()
    if not isinstance(scene_strategy, st.SearchStrategy):
        raise InvalidArgument(f"scene_strategy must be a strategy of Scene, got {scene_strategy!r}")
    if not isinstance(beams, ScanPattern):
        raise InvalidArgument(f"beams must be a sensor model (lidar.model.sensors), got {beams!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InvalidArgument(f"seed={seed!r} must be a non-negative int")
    if engine not in ("auto", "embree", "numpy"):
        raise InvalidArgument(f"engine={engine!r} must be 'auto', 'embree' or 'numpy'")
    return scene_strategy.map(
        functools.partial(render, beams=beams, seed=seed, range_noise=range_noise, engine=engine)
    )


def _sensor_argument(sensor: ScanPattern | str) -> ScanPattern:
    chosen = as_sensor(sensor)
    if chosen is None:
        raise InvalidArgument("sensor=None: pass a sensor model or a catalogue key")
    return chosen
