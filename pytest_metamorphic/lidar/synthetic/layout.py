"""Street layouts for synthetic scenes: road ROIs, obstacle slots, clutter off the road.

Everything here is built from a few small integers handed out by a *chooser*, a callable
``integer(low, high) -> int`` returning an int in ``[low, high]``. Two choosers drive the
same code:

- the Hypothesis strategies (:mod:`pytest_metamorphic.strategies`) pass one that draws
  ``st.integers(low, high)``, so failures shrink toward the simplest layout (a straight
  7 m road along x, a car of average size 10 m ahead);
- campaigns pass :func:`rng_chooser`, which draws uniformly from a seeded
  ``numpy.random.Generator``, so every source is an independent sample
  (:func:`random_scene`).

Obstacles occupy distinct *slots*: points of an 8 m lattice through (10, 0) that lie deep
inside the ROI, ordered by distance from (10, 0), each jittered by up to ±0.5 m. Distinct
slots cannot overlap (the largest car fits in a 2.8 m circle), so an obstacle never
collides with another and deleting one never moves the others.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, cast

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import LABELS, SIZE_PRIORS, Box, Label
from pytest_metamorphic.lidar.roi import ROI, CellSet
from pytest_metamorphic.lidar.synthetic import BackgroundObject, MeshShape, Obstacle, Scene

__all__ = [
    "BACKGROUND_ORDER",
    "MAX_DISTANCE",
    "Chooser",
    "ClutterSpec",
    "ObstacleSpec",
    "RoadKind",
    "TooFewSlots",
    "clutter_radices",
    "corridor_roi",
    "junction_roi",
    "layout_scene",
    "obstacle_radices",
    "obstacle_slots",
    "random_scene",
    "rng_chooser",
    "road_roi",
    "star_roi",
]

Chooser = Callable[[int, int], int]
"""``integer(low, high)``: an int in ``[low, high]`` (both inclusive)."""
RoadKind = Literal["corridor", "curved", "junction", "polygon"]
ROAD_KINDS: tuple[RoadKind, ...] = ("corridor", "curved", "junction", "polygon")

MIN_ROAD_WIDTH = 7.0  # two narrow lanes
WIDTH_STEP = 0.5
# Curvature in steps of 1/500 m^-1: up to 1/50 m^-1 (a 50 m radius bend).
_CURVATURE_STEP = 1.0 / 500.0
_MAX_CURVATURE_STEPS = 10

_SIZE_STEPS = 5  # size = mean +- k/5 of the way to the prior's bound
_YAW_STEP_DEG = 5
EGO_CLEARANCE = 4.0  # metres kept free around the sensor (the ego vehicle)
_SLOT_SPACING = 8.0  # metres between obstacle slots
_JITTER_STEP = 0.25  # metres
_JITTER_STEPS = 2  # up to +-0.5 m: slots stay >= 6.5 m apart, obstacles >= 0.9 m apart
# Largest footprint radius of any prior (a 5.2 x 2.0 m car).
_MAX_RADIUS = max(math.hypot(p.high[0], p.high[1]) / 2.0 for p in SIZE_PRIORS.values())
_BACKGROUND_RANGE = 80.0
#: Farthest obstacle centre of generated scenes by default (metres): near the HDL-64E's
#: 120 m range, so what a detector does far away is exercised too.
MAX_DISTANCE = 100.0
HEIGHT_STEP = 0.01
DEFAULT_HEIGHT = 1.73  # KITTI's HDL-64E
HEIGHT_STEPS = (-10, 17)  # sensor height 1.73 m -10/+17 cm
SLOT_CHOICES = 2**16  # slot index modulo the ROI's slot count; small values are near slots
SITE_CHOICES = 2**24
# Background kinds: (length, width, height) bounds in metres; shrink to the lower bound.
_BACKGROUND_SIZES: Mapping[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "pole": ((0.2, 0.2, 4.0), (0.5, 0.5, 10.0)),
    "tree": ((2.0, 2.0, 4.0), (6.0, 6.0, 12.0)),
    "building": ((6.0, 6.0, 4.0), (20.0, 14.0, 15.0)),
}
BACKGROUND_ORDER = ("pole", "tree", "building")
_CLUTTER_RADICES = (18, 11, 11, 11)  # yaw in 10 degree steps, then size steps


@dataclass(frozen=True)
class ObstacleSpec:
    """One obstacle as drawn: its class, a slot number and a mixed-radix "variation"
    integer (shape, heading, size, jitter; see :func:`obstacle_radices`)."""

    label: Label
    slot: int
    variation: int


@dataclass(frozen=True)
class ClutterSpec:
    """One background object as drawn: its kind, a site number and a variation integer
    (heading, size; see :func:`clutter_radices`)."""

    kind: str
    site: int
    variation: int


class TooFewSlots(InvalidArgument):
    """The ROI has fewer obstacle slots than obstacles were asked for."""


def rng_chooser(rng: np.random.Generator) -> Chooser:
    """A chooser drawing uniformly from ``rng`` (campaign mode)."""
    if not isinstance(rng, np.random.Generator):
        raise InvalidArgument(f"rng must be a numpy Generator, got {type(rng).__name__}")
    return lambda low, high: int(rng.integers(low, high, endpoint=True))


# --- Road ROIs ------------------------------------------------------------------------


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


def corridor_roi(
    integer: Chooser,
    *,
    curved: bool = True,
    min_width: float = MIN_ROAD_WIDTH,
    width_steps: int = 26,
    length: float = 240.0,
    **raster: float,
) -> ROI:
    """A single road through the sensor, straight or bending with constant curvature.

    Width is ``min_width`` plus 0.5 m steps (up to ``width_steps``); the sensor is inside
    the road, at least 1 m from its edges; heading in whole degrees in [-90, 90]; bends
    down to a 50 m radius when ``curved``. ``raster`` goes to :meth:`ROI.from_polygons`.
    """
    width = min_width + WIDTH_STEP * integer(0, width_steps)
    # Sensor within the road, at least 1 m from its edge, in 0.5 m steps.
    room = max(int((width / 2.0 - 1.0) / 0.5), 0)
    offset = 0.5 * integer(-room, room)
    heading = float(integer(-90, 90))
    steps = integer(-_MAX_CURVATURE_STEPS, _MAX_CURVATURE_STEPS) if curved else 0
    polygon = _corridor_polygon(width, length, offset, heading, steps * _CURVATURE_STEP)
    return ROI.from_polygons([polygon], **raster)


def junction_roi(
    integer: Chooser,
    *,
    min_width: float = MIN_ROAD_WIDTH,
    width_steps: int = 18,
    length: float = 150.0,
    **raster: float,
) -> ROI:
    """A T-junction or crossroads: one polygon per arm plus one for the junction.

    The sensor is on the arm behind the junction (0-40 m before it); the other arms
    deviate from right angles by up to 30 degrees in 5 degree steps.
    """
    arms = integer(3, 4)
    width = min_width + WIDTH_STEP * integer(0, width_steps)
    # Junction centre ahead of the sensor in whole metres; the sensor stays on an arm.
    ahead = float(integer(0, 40))
    heading = float(integer(-90, 90))
    skews = [5.0 * integer(-6, 6) for _ in range(arms)]
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
    return ROI.from_polygons([_rotate(p, heading) for p in polygons], **raster)


def star_roi(
    integer: Chooser,
    *,
    min_vertices: int = 3,
    max_vertices: int = 12,
    min_radius: float = 5.0,
    max_radius: float = 80.0,
    **raster: float,
) -> ROI:
    """A simple polygon around the sensor, star-shaped (so always valid)."""
    count = integer(min_vertices, max_vertices)
    radius_steps = int(max_radius - min_radius)
    sector = 2.0 * math.pi / count
    # Angular gaps of at most 0.8 pi: the polygon is star-shaped around the sensor, hence
    # simple, and its edges pass at least min_radius * cos(0.4 pi) from the sensor.
    spread = min(0.9, 0.4 * count - 1.0)
    vertices = []
    for i in range(count):
        jitter = spread / 9.0 * sector * integer(0, 9)
        radius = min_radius + integer(0, radius_steps)
        angle = i * sector + jitter
        vertices.append((radius * math.cos(angle), radius * math.sin(angle)))
    return ROI.from_polygons([np.array(vertices)], **raster)


def road_roi(
    integer: Chooser, *, kinds: Sequence[RoadKind] = ("corridor", "curved", "junction")
) -> ROI:
    """One ROI of a kind chosen among ``kinds`` (0.25 m cells, 120 m raster range)."""
    kinds = _check_kinds(kinds)
    kind = kinds[integer(0, len(kinds) - 1)]
    if kind == "junction":
        return junction_roi(integer)
    if kind == "polygon":
        return star_roi(integer)
    return corridor_roi(integer, curved=kind == "curved")


def _check_kinds(kinds: Sequence[RoadKind]) -> tuple[RoadKind, ...]:
    chosen = (cast(RoadKind, kinds),) if isinstance(kinds, str) else tuple(kinds)
    if not chosen or any(kind not in ROAD_KINDS for kind in chosen):
        raise InvalidArgument(f"kinds={kinds!r} must be a non-empty subset of {ROAD_KINDS}")
    return chosen


# --- Obstacles and clutter ---------------------------------------------------------------


# A few entries only: each keeps its ROI alive, and with it ~15 MB of bitmaps and cell
# sets; a scene's layout needs one ROI (campaigns draw a new one per source, tests
# usually share one).
@functools.lru_cache(maxsize=2)
def obstacle_slots(roi: ROI, max_distance: float) -> NDArray[np.float64]:
    """Lattice points where an obstacle may stand, nearest to (10, 0) first.

    Returns
    -------
    slots : (k, 2) float64
    """
    steps = math.ceil((max_distance + 10.0) / _SLOT_SPACING)
    i, j = np.meshgrid(np.arange(-steps, steps + 1), np.arange(-steps, steps + 1), indexing="ij")
    slots = np.stack([10.0 + _SLOT_SPACING * i.ravel(), _SLOT_SPACING * j.ravel()], axis=1)
    distance = np.hypot(slots[:, 0], slots[:, 1])
    jitter = _JITTER_STEPS * _JITTER_STEP * math.sqrt(2.0)
    # Clear of the ego vehicle whatever the obstacle's size, jitter and heading.
    near = EGO_CLEARANCE + _MAX_RADIUS + jitter
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


@functools.lru_cache(maxsize=len(BACKGROUND_ORDER) + 1)  # one ROI's kinds (see above)
def _background_sites(roi: ROI, kind: str) -> CellSet:
    """Free cells far enough from the ROI for the largest object of a kind."""
    (_, _, _), (length, width, _) = _BACKGROUND_SIZES[kind]
    radius = math.hypot(length, width) / 2.0
    margin = math.ceil((radius + 0.5) / roi.cell_size)
    limit = min(_BACKGROUND_RANGE, roi.raster_range)
    return roi.cells("free", margin_cells=margin, max_range=limit)


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


def obstacle_radices(shape_count: int) -> tuple[int, ...]:
    """Radices of an obstacle's variation integer, least significant first: shape,
    heading, size (length, width, height), jitter (x, y)."""
    return (
        shape_count,
        2 * (180 // _YAW_STEP_DEG) + 1,
        *(2 * _SIZE_STEPS + 1,) * 3,
        *(2 * _JITTER_STEPS + 1,) * 2,
    )


def clutter_radices() -> tuple[int, ...]:
    """Radices of a background object's variation integer: heading, then size steps."""
    return _CLUTTER_RADICES


def _obstacle(
    spec: ObstacleSpec,
    slot: NDArray[np.float64],
    height: float,
    radices: Sequence[int],
    shapes: Mapping[str, tuple[MeshShape, ...]],
) -> Obstacle:
    shape_index, yaw_steps, *size_steps, dx, dy = _decode(spec.variation, radices)
    size = _prior_size(spec.label, size_steps)
    x = float(slot[0]) + _JITTER_STEP * dx
    y = float(slot[1]) + _JITTER_STEP * dy
    yaw = math.radians(_YAW_STEP_DEG * yaw_steps)
    box = Box((x, y, -height + size[2] / 2.0), size, yaw, spec.label)
    choices: tuple[str | MeshShape, ...] = ("auto", *shapes.get(spec.label, ()))
    return Obstacle(box, shape=choices[abs(shape_index) % len(choices)])


def _clutter(spec: ClutterSpec, roi: ROI) -> BackgroundObject | None:
    candidates = _background_sites(roi, spec.kind)
    if len(candidates) == 0:
        return None
    yaw_steps, *size_steps = _digits(spec.variation, _CLUTTER_RADICES)
    low, high = _BACKGROUND_SIZES[spec.kind]
    size = tuple(lo + k / 10.0 * (hi - lo) for k, lo, hi in zip(size_steps, low, high, strict=True))
    if spec.kind != "building":
        size = (size[0], size[0], size[2])  # round things
    pick = np.array([spec.site % len(candidates)])
    x, y = candidates.origins(pick)[0] + roi.cell_size / 2.0  # the cell's centre
    return BackgroundObject(
        spec.kind,  # type: ignore[arg-type]
        (float(x), float(y)),
        size,  # type: ignore[arg-type]
        yaw=math.radians(10 * yaw_steps),
    )


def layout_scene(
    roi: ROI,
    *,
    height_steps: int,
    obstacles: Sequence[ObstacleSpec],
    clutter: Sequence[ClutterSpec],
    min_obstacles: int = 0,
    shapes: Mapping[str, tuple[MeshShape, ...]] | None = None,
    max_distance: float = MAX_DISTANCE,
    name: str = "generated",
) -> Scene:
    """The scene that drawn specs describe.

    Raises
    ------
    TooFewSlots
        The ROI has fewer slots than ``max(len(obstacles), min_obstacles)`` (rare: the
        default roads have 10 or more).
    """
    shapes = shapes or {}
    height = DEFAULT_HEIGHT + HEIGHT_STEP * height_steps
    slots = obstacle_slots(roi, max_distance)
    if len(slots) < max(len(obstacles), min_obstacles):
        raise TooFewSlots(f"{roi.describe()} has {len(slots)} obstacle slots")
    radices = obstacle_radices(1 + max((len(v) for v in shapes.values()), default=0))
    placed = []
    taken: set[int] = set()
    for spec in obstacles:
        # A taken slot passes the obstacle on to the next free one. (Not unique slots: the
        # shrinker cannot delete the first of two unique elements, and dropping the
        # obstacle instead would let deletions resurrect others.)
        slot = spec.slot % len(slots)
        while slot in taken:
            slot = (slot + 1) % len(slots)
        taken.add(slot)
        placed.append(_obstacle(spec, slots[slot], height, radices, shapes))
    # Background objects may overlap each other (a tree against a building): dropping one
    # for colliding with another would make shrinking order-dependent.
    background = [item for item in (_clutter(spec, roi) for spec in clutter) if item]
    return Scene(
        sensor_height=round(height, 6),
        roi=roi,
        obstacles=tuple(placed),
        background=tuple(background),
        name=name,
    )


def random_scene(
    rng: np.random.Generator,
    *,
    kinds: Sequence[RoadKind] = ("corridor", "curved", "junction"),
    min_obstacles: int = 1,
    max_obstacles: int = 6,
    labels: Sequence[Label] = ("car", "pedestrian", "cyclist"),
    max_background: int = 6,
    max_distance: float = 50.0,
    name: str = "random",
) -> Scene:
    """An independent random street scene (campaign sources), uniform over the same
    layouts the :func:`~pytest_metamorphic.strategies.scenes` strategy draws.

    Parameters
    ----------
    rng : numpy.random.Generator
    kinds : sequence of {"corridor", "curved", "junction", "polygon"}
        Road shapes to choose from.
    min_obstacles, max_obstacles : int
        Obstacle count, uniform in this range (fewer if the ROI has fewer slots).
    labels : sequence of {"car", "pedestrian", "cyclist", "unknown"}
        Obstacle classes, uniform.
    max_background : int
        Poles, trees and buildings outside the ROI, uniform count in [0, max_background].
    max_distance : float
        Farthest obstacle centre, metres. 50 m by default, unlike the strategy's 100 m:
        the campaign rates in the documentation were measured on such streets (pass
        ``max_distance=100`` through ``synthetic_frames`` for far obstacles too).
    """
    integer = rng_chooser(rng)
    _check_kinds(kinds)
    labels = (labels,) if isinstance(labels, str) else tuple(labels)  # type: ignore[assignment]
    if not labels or any(label not in LABELS for label in labels):
        raise InvalidArgument(f"labels={labels!r} must be a non-empty subset of {LABELS}")
    for argument, value in (
        ("min_obstacles", min_obstacles),
        ("max_obstacles", max_obstacles),
        ("max_background", max_background),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise InvalidArgument(f"{argument}={value!r} must be a non-negative int")
    if max_obstacles < min_obstacles:
        raise InvalidArgument(
            f"max_obstacles={max_obstacles} must be >= min_obstacles={min_obstacles}"
        )
    roi = road_roi(integer, kinds=kinds)
    slots = len(obstacle_slots(roi, float(max_distance)))
    count = min(integer(min_obstacles, max_obstacles), slots)
    variations = math.prod(obstacle_radices(1))
    obstacles = [
        ObstacleSpec(
            labels[integer(0, len(labels) - 1)],
            integer(0, SLOT_CHOICES - 1),
            integer(0, variations - 1),
        )
        for _ in range(count)
    ]
    clutter = [
        ClutterSpec(
            BACKGROUND_ORDER[integer(0, len(BACKGROUND_ORDER) - 1)],
            integer(0, SITE_CHOICES),
            integer(0, math.prod(_CLUTTER_RADICES) - 1),
        )
        for _ in range(integer(0, max_background))
    ]
    return layout_scene(
        roi,
        height_steps=integer(*HEIGHT_STEPS),
        obstacles=obstacles,
        clutter=clutter,
        max_distance=float(max_distance),
        name=name,
    )
