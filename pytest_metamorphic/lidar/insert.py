"""Scene edits: a real object placed into another sweep, as that sweep's sensor would see it.

semLidarFuzz's *add* and MultiTest's insertion, without a renderer of our own models:

1. :meth:`ObjectTemplate.from_frame` takes a labelled (or detected) object's returns from
   a real or rendered sweep and meshes them the way the sensor saw them: a Delaunay
   triangulation in (azimuth, elevation), neighbouring returns joined, holes (more than
   three beam spacings, or 1 m in depth) left open. The mesh is kept in the object's own
   coordinates, standing on its local ground, with the *view*: its heading relative to the
   line of sight.
2. :func:`free_placements` lists where it may go in another frame: on free ground (no
   return above the local ground in its footprint grown by 0.5 m), judged by the scope
   (inside the ROI), at the range it was seen from or up to 20 % nearer / 50 % farther,
   turned about the sensor so that the sensor sees the same face (the view is kept).
3. :meth:`InsertObject.onto` casts the target sensor's beams (its
   :class:`~pytest_metamorphic.lidar.hdl64.BeamLayout`) at the placed mesh: one return
   per beam that hits it, at the hit's range and the surrounding returns' intensity, with
   the beam's ring; returns of the target that the object hides (their ray crosses the
   mesh first) go; beams whose ray meets a target return in front of the object first are
   not added. Density therefore follows the new range and the target's beams, not the
   source's.

:class:`InsertObject` is :class:`~pytest_metamorphic.core.perturbation.Reducible` over its
returns (each with the target returns it hides): a violation reduces to the fewest
inserted returns that still fail. :class:`InsertedDetected` checks that the inserted
object is found, :class:`~pytest_metamorphic.lidar.edit.OthersKept` that nothing else is
lost.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import Delaunay, QhullError, cKDTree

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.edit import RemoveObject, box_gap, shadow_overlaps
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.minimize import footprint_distances
from pytest_metamorphic.lidar.obstacles import Box, Label
from pytest_metamorphic.lidar.perturb import append_points
from pytest_metamorphic.lidar.scene.meshes import SceneMesh
from pytest_metamorphic.lidar.scene.raycast import cast_rays
from pytest_metamorphic.lidar.scope import ObstacleScope, ScopeLike, as_scope

__all__ = [
    "INSERTED_INSTANCE",
    "RANGE_FACTORS",
    "InsertObject",
    "InsertedDetected",
    "ObjectTemplate",
    "Placement",
    "free_placements",
]

INSERTED_INSTANCE = -4
"""``instance`` field value of inserted returns (rendered frames carry the field)."""
RANGE_FACTORS = (1.0, 0.9, 1.1, 0.8, 1.25, 1.5)
"""Ranges a template may be placed at, as multiples of the range it was seen from."""

# Normalising spacings for the mesh (HDL-64E: firings 0.17 degrees apart, lasers 0.3-0.6).
_AZIMUTH_SPACING = math.radians(0.17)
_ELEVATION_SPACING = math.radians(0.45)
_MAX_GAP = 3.0  # triangles wider than this many spacings span a hole
_MAX_DEPTH_STEP = 1.0  # metres: a longer triangle edge joins two surfaces
_MIN_RETURNS = 10
_FREE_MARGIN = 0.5  # metres around a placed footprint that must hold no solid return
_SOLID = 0.3  # metres above the local ground that a return counts as solid
_GROUND_CELL = 1.0  # metres: cells of the local ground estimate of a target frame
_CELL_KEY = 1_000_003  # cell (i, j) -> i * _CELL_KEY + j
_BEAM_RADIUS = math.radians(0.15)  # angular half-width of one beam
_BEARING_STEP = 2.0  # degrees between candidate bearings


@dataclass(frozen=True, eq=False)
class ObjectTemplate:
    """An object's surface as a LiDAR saw it, ready to be placed into other sweeps.

    Attributes
    ----------
    label : str
    size : (3,) float
        Length, width, height of its box in metres.
    vertices : (k, 3) float64
        Its returns in object coordinates: x along the heading, y to the left, z up from
        the local ground under it.
    faces : (m, 3) int64
        Triangles joining neighbouring returns.
    intensity : (k,) float32
        Each return's intensity.
    view : float
        Heading minus bearing (radians): which face the sensor saw.
    range, bearing : float
        Metres and radians from the sensor to the box centre when it was seen.
    source : str
        Where it was taken from, for messages.
    """

    label: Label
    size: tuple[float, float, float]
    vertices: NDArray[np.float64] = field(repr=False)
    faces: NDArray[np.int64] = field(repr=False)
    intensity: NDArray[np.float32] = field(repr=False)
    view: float
    range: float
    bearing: float
    source: str = ""

    @classmethod
    def from_frame(cls, frame: Frame, box: Box, *, margin: float = 0.15) -> ObjectTemplate:
        """The returns of the object in ``box`` (grown by ``margin``, above the local ground)
        of ``frame``, meshed. Raises :class:`InvalidArgument` when fewer than 10 returns
        lie on it or they do not form a surface."""
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        removal = RemoveObject(box, margin)
        points = frame.cloud.points[removal.removed(frame)].astype(np.float64)
        where = f"{box.describe()} in {frame!r}"
        if len(points) < _MIN_RETURNS:
            raise InvalidArgument(
                f"{where} has {len(points)} returns; a template needs >= {_MIN_RETURNS}"
            )
        faces = _surface(points[:, :3])
        if len(faces) == 0:
            raise InvalidArgument(f"the returns of {where} do not form a surface")
        ground_z, _ = removal.ground_height(frame)
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        offset = points[:, :3] - np.array([box.center[0], box.center[1], ground_z])
        local = np.column_stack(
            [
                c * offset[:, 0] + s * offset[:, 1],
                -s * offset[:, 0] + c * offset[:, 1],
                offset[:, 2],
            ]
        )
        bearing = math.atan2(box.center[1], box.center[0])
        return cls(
            label=box.label,
            size=box.size,
            vertices=local,
            faces=faces,
            intensity=points[:, 3].astype(np.float32),
            view=math.remainder(box.yaw - bearing, 2 * math.pi),
            range=math.hypot(box.center[0], box.center[1]),
            bearing=bearing,
            source=f"{frame.source or '<memory>'}#{frame.index}",
        )

    def box_at(self, placement: Placement) -> Box:
        """The template's box standing at ``placement``, turned so the same face is seen."""
        x, y = (
            placement.range * math.cos(placement.bearing),
            placement.range * math.sin(placement.bearing),
        )
        yaw = math.remainder(placement.bearing + self.view, 2 * math.pi)
        centre = (x, y, placement.ground_z + self.size[2] / 2)
        return Box(centre, self.size, yaw, self.label)

    def mesh_at(self, placement: Placement) -> SceneMesh:
        """The template's triangles at ``placement`` (sensor frame)."""
        box = self.box_at(placement)
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        v = self.vertices
        world = np.column_stack(
            [
                box.center[0] + c * v[:, 0] - s * v[:, 1],
                box.center[1] + s * v[:, 0] + c * v[:, 1],
                placement.ground_z + v[:, 2],
            ]
        )
        m = len(self.faces)
        return SceneMesh(world, self.faces, np.zeros(m, np.int32), np.zeros(m), ((0, m),))

    def describe(self) -> str:
        return (
            f"{self.label} seen at {self.range:.1f} m ({len(self.vertices)} returns, {self.source})"
        )


def _surface(xyz: NDArray[np.float64]) -> NDArray[np.int64]:
    """Triangles joining returns that neighbour each other in the sensor's view."""
    azimuth = np.unwrap(np.arctan2(xyz[:, 1], xyz[:, 0]))
    planar = np.hypot(xyz[:, 0], xyz[:, 1])
    view = np.column_stack(
        [azimuth / _AZIMUTH_SPACING, np.arctan2(xyz[:, 2], planar) / _ELEVATION_SPACING]
    )
    try:
        faces = Delaunay(view).simplices.astype(np.int64)
    except (QhullError, ValueError):
        return np.empty((0, 3), dtype=np.int64)
    edges = [(0, 1), (1, 2), (2, 0)]
    wide = np.zeros(len(faces), dtype=bool)
    for a, b in edges:
        wide |= np.linalg.norm(view[faces[:, a]] - view[faces[:, b]], axis=1) > _MAX_GAP
        wide |= np.linalg.norm(xyz[faces[:, a]] - xyz[faces[:, b]], axis=1) > _MAX_DEPTH_STEP
    return faces[~wide]


@dataclass(frozen=True)
class Placement:
    """Where a template goes: ``range`` metres from the sensor at ``bearing`` radians, its
    underside at ``ground_z``."""

    bearing: float
    range: float
    ground_z: float


class _TargetGround:
    """A target frame's local ground and its solid returns.

    The ground under a return is the lowest 5th-percentile height of the 1 m cells around
    it (3 x 3): a cell on a car's flank holds no ground return of its own.
    """

    def __init__(self, frame: Frame) -> None:
        xyz = frame.cloud.xyz.astype(np.float64)
        cells = np.floor(xyz[:, :2] / _GROUND_CELL).astype(np.int64)
        keys = cells[:, 0] * _CELL_KEY + cells[:, 1]
        order = np.lexsort((xyz[:, 2], keys))
        sorted_keys = keys[order]
        starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
        counts = np.diff(np.r_[starts, len(keys)])
        low = dict(
            zip(
                sorted_keys[starts].tolist(),
                xyz[order[starts + (counts * 0.05).astype(np.int64)], 2].tolist(),
                strict=True,
            )
        )
        around = [dx * _CELL_KEY + dy for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
        lowest = np.array(
            [min(low.get(key + step, math.inf) for step in around) for key in sorted_keys[starts]]
        )
        self.height = np.empty(len(xyz))
        self.height[order] = np.repeat(lowest, counts)
        self.solid = xyz[:, 2] > self.height + _SOLID
        self.xyz = xyz
        self.tree = cKDTree(xyz[:, :2])
        solid = xyz[self.solid]
        azimuth = np.arctan2(solid[:, 1], solid[:, 0])
        by_azimuth = np.argsort(azimuth)
        self.solid_azimuth = azimuth[by_azimuth]
        self.solid_range = np.hypot(solid[by_azimuth, 0], solid[by_azimuth, 1])

    def ground_under(self, box: Box) -> float | None:
        """Median height of the non-solid returns in the grown footprint, or None when
        there are fewer than 5 (no ground seen there) or a solid return lies in it."""
        reach = math.hypot(box.size[0], box.size[1]) / 2 + _FREE_MARGIN
        near = np.asarray(self.tree.query_ball_point(box.center[:2], reach), dtype=np.intp)
        if len(near) == 0:
            return None
        footprint = box.grown(_FREE_MARGIN)
        inside = near[_in_footprint(footprint, self.xyz[near, :2])]
        if self.solid[inside].any() or len(inside) < 5:
            return None
        return float(np.median(self.xyz[inside, 2]))

    def in_clear_view(self, box: Box) -> bool:
        """Whether at most 2 solid returns lie between the sensor and ``box`` (within the
        bearings its footprint covers): it is not placed behind something."""
        corners = box.corners_bev()
        bearing = math.atan2(box.center[1], box.center[0])
        low, high = _bearing_window(np.column_stack([corners, np.zeros(4)]), bearing)
        nearest = float(np.hypot(corners[:, 0], corners[:, 1]).min())
        count = 0
        for start, stop in _azimuth_spans(bearing + low, bearing + high):
            a, b = np.searchsorted(self.solid_azimuth, [start, stop])
            count += int((self.solid_range[a:b] < nearest).sum())
        return count <= 2


def _azimuth_spans(start: float, stop: float) -> list[tuple[float, float]]:
    """``[start, stop]`` (radians, stop - start < 2π) as spans within [-π, π]."""
    width = stop - start
    start = math.remainder(start, 2 * math.pi)
    stop = start + width
    if stop <= math.pi:
        return [(start, stop)]
    return [(start, math.pi), (-math.pi, stop - 2 * math.pi)]


def _in_footprint(box: Box, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
    offset = xy - np.asarray(box.center[:2])
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    along = np.abs(offset[:, 0] * c + offset[:, 1] * s) <= box.size[0] / 2
    across = np.abs(-offset[:, 0] * s + offset[:, 1] * c) <= box.size[1] / 2
    return along & across


def free_placements(
    frame: Frame,
    template: ObjectTemplate,
    *,
    scope: ScopeLike = "roi",
    layout: BeamLayout = HDL64E,
    limit: int = 32,
) -> list[Placement]:
    """Up to ``limit`` places where ``template`` can stand in ``frame``, smallest move first.

    A place is free when no return of ``frame`` rises more than 0.3 m above the local
    ground in the template's footprint grown by 0.5 m, and that footprint holds at least
    5 ground returns (the ground is seen there). The box must be judged by ``scope`` (by
    default: wholly inside the ROI) and within the sensor's range. Candidates keep the
    template's view and lie at :data:`RANGE_FACTORS` times its range, at bearings 2
    degrees apart; they are ordered by how far they move it (bearing change in degrees
    plus 20 times the log of the range factor), so Hypothesis shrinks toward the place
    the object was seen from.
    """
    if not isinstance(frame, Frame):
        raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
    if not isinstance(template, ObjectTemplate):
        raise InvalidArgument(f"template={template!r} must be an ObjectTemplate")
    chosen = as_scope(scope)
    ground = _ground_of(frame)
    candidates = []
    for factor in RANGE_FACTORS:
        distance = template.range * factor
        if not layout.min_range + 2.0 < distance < 0.9 * layout.max_range:
            continue
        for step in range(-int(180 / _BEARING_STEP), int(180 / _BEARING_STEP)):
            turn = step * _BEARING_STEP
            candidates.append((abs(turn) + 20 * abs(math.log(factor)), turn, distance))
    candidates.sort()
    found: list[Placement] = []
    for _, turn, distance in candidates:
        bearing = math.remainder(template.bearing + math.radians(turn), 2 * math.pi)
        box = template.box_at(Placement(bearing, distance, 0.0))
        z = ground.ground_under(box)
        if z is None or not ground.in_clear_view(box):
            continue
        placement = Placement(bearing, distance, z)
        if not chosen.judged([template.box_at(placement)], frame)[0]:
            continue
        found.append(placement)
        if len(found) == limit:
            break
    return found


@functools.lru_cache(maxsize=8)
def _ground_of(frame: Frame) -> _TargetGround:
    return _TargetGround(frame)


@dataclass(frozen=True, eq=False)
class InsertObject:
    """A placed template's returns added to one target frame, and the returns they hide.

    Build it with :meth:`onto`; :meth:`apply` takes the frame it was built for.

    Attributes
    ----------
    box : Box
        The inserted object's box in the target frame (its label is the template's).
    points : (k, 4) float32
        The inserted returns: x, y, z, intensity.
    ring : (k,) uint8
        The laser of each inserted return.
    hidden : (h,) intp
        Rows of the target cloud whose returns the object hides.
    hidden_by : (h,) intp
        For each hidden row, the inserted return (index into ``points``) on the nearest
        beam: reducing the returns brings back what only they hid.
    hidden_xy : (h, 2) float64
        Where the hidden returns were (bird's eye).
    target_points : int
        How many points the target cloud has (checked by :meth:`apply`).
    """

    box: Box
    points: NDArray[np.float32] = field(repr=False)
    ring: NDArray[np.uint8] = field(repr=False)
    hidden: NDArray[np.intp] = field(repr=False)
    hidden_by: NDArray[np.intp] = field(repr=False)
    hidden_xy: NDArray[np.float64] = field(repr=False)
    target_points: int
    template: ObjectTemplate | None = field(default=None, repr=False)

    @classmethod
    def onto(
        cls,
        frame: Frame,
        template: ObjectTemplate,
        placement: Placement,
        *,
        layout: BeamLayout = HDL64E,
    ) -> InsertObject:
        """Cast ``layout``'s beams at ``template`` standing at ``placement`` in ``frame``."""
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        if not isinstance(template, ObjectTemplate):
            raise InvalidArgument(f"template={template!r} must be an ObjectTemplate")
        if not isinstance(placement, Placement):
            raise InvalidArgument(f"placement={placement!r} must be a Placement")
        if not isinstance(layout, BeamLayout):
            raise InvalidArgument(f"layout={layout!r} must be a BeamLayout")
        mesh = template.mesh_at(placement)
        low, high = _bearing_window(mesh.vertices, placement.bearing)
        direction, ring, distance = _returns(mesh, layout, placement.bearing, low, high)
        xyz = frame.cloud.xyz.astype(np.float64)
        ranges = np.linalg.norm(xyz, axis=1)
        offset = _relative_bearing(xyz, placement.bearing)
        near = np.flatnonzero((offset >= low - _BEAM_RADIUS) & (offset <= high + _BEAM_RADIUS))
        unit = xyz[near] / np.maximum(ranges[near], 1e-9)[:, None]
        ray, _, hit = cast_rays(mesh, unit)
        behind = np.zeros(len(near), dtype=bool)
        behind[ray] = hit < ranges[near[ray]] - 0.05
        hidden = near[behind]
        blocked = _blocked(unit[~behind], ranges[near[~behind]], direction, distance)
        direction, ring, distance = direction[~blocked], ring[~blocked], distance[~blocked]
        intensity = _intensity(template, mesh, direction, distance)
        points = np.column_stack([direction * distance[:, None], intensity]).astype(np.float32)
        if len(points):
            _, hidden_by = cKDTree(direction).query(unit[behind])
        else:  # nothing of the object is seen: it hides nothing either
            hidden, hidden_by = hidden[:0], np.empty(0, dtype=np.intp)
        return cls(
            template.box_at(placement),
            points,
            ring.astype(np.uint8),
            hidden.astype(np.intp),
            np.asarray(hidden_by, dtype=np.intp),
            xyz[hidden, :2],
            len(frame.cloud),
            template,
        )

    def __len__(self) -> int:
        return len(self.points)

    def restrict(self, indices: Sequence[int]) -> InsertObject:
        """Only the returns at ``indices`` (and what they hide)."""
        chosen = np.asarray(list(indices), dtype=np.intp)
        renumber = np.full(len(self.points), -1, dtype=np.intp)
        renumber[chosen] = np.arange(len(chosen))
        kept = renumber[self.hidden_by] >= 0
        return dataclasses.replace(
            self,
            points=self.points[chosen],
            ring=self.ring[chosen],
            hidden=self.hidden[kept],
            hidden_by=renumber[self.hidden_by[kept]],
            hidden_xy=self.hidden_xy[kept],
        )

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        if len(frame.cloud) != self.target_points:
            raise InvalidArgument(
                f"{self!r} was built for a frame of {self.target_points} points, not "
                f"{frame!r} (use InsertObject.onto(frame, ...))"
            )
        keep = np.ones(len(frame.cloud), dtype=bool)
        keep[self.hidden] = False
        cloud = append_points(
            frame.cloud[keep], self.points, instance=INSERTED_INSTANCE, given={"ring": self.ring}
        )
        return dataclasses.replace(frame, cloud=cloud, boxes=(*frame.boxes, self.box))

    def region(self) -> Box:
        """The inserted object's box (what :class:`OthersKept` keeps its distance from)."""
        return self.box

    def affects(self, box: Box, clearance: float) -> bool:
        """Whether ``box`` is within ``clearance`` metres of the inserted object or of a
        return it hides, or (partly) behind it: the insertion may fairly change what is
        detected there (seen on KITTI: hidden returns 4 m from an obstacle changed the
        ground a detector estimated under it, and with it the obstacle's class)."""
        if box_gap(box, self.box) < clearance or shadow_overlaps(self.box, box):
            return True
        if len(self.hidden_xy) == 0:
            return False
        return bool(footprint_distances(self.hidden_xy, [box]).min() < clearance)

    def params(self) -> dict[str, Any]:
        return {
            "inserted_object": self.box.describe(),
            "inserted_returns": len(self.points),
            "hidden_returns": len(self.hidden),
            "insert_object": self,
        }

    def describe_edit(self) -> str:
        return f"inserted {self.box.describe()}"

    def describe_elements(self, limit: int) -> list[str]:
        return [
            f"return at ({x:.2f}, {y:.2f}, {z:.2f}), ring {ring}"
            for (x, y, z, _), ring in zip(self.points[:limit], self.ring[:limit], strict=True)
        ]

    def to_json(self) -> dict[str, Any]:
        return {
            "box": self.box.describe(),
            "points": self.points.tolist(),
            "ring": self.ring.tolist(),
            "hidden": self.hidden.tolist(),
            "template": None if self.template is None else self.template.describe(),
        }

    def __repr__(self) -> str:
        return f"InsertObject({self.box.describe()}, {len(self.points)} returns)"


def _bearing_window(vertices: NDArray[np.float64], bearing: float) -> tuple[float, float]:
    """Bearings the mesh covers, relative to ``bearing`` (radians)."""
    offset = _relative_bearing(vertices, bearing)
    return float(offset.min()), float(offset.max())


def _relative_bearing(xyz: NDArray[np.float64], bearing: float) -> NDArray[np.float64]:
    """Bearing of each point minus ``bearing``, in [-π, π)."""
    return _wrapped(np.arctan2(xyz[:, 1], xyz[:, 0]) - bearing)


def _wrapped(angle: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.remainder(angle + math.pi, 2 * math.pi) - math.pi


def _returns(
    mesh: SceneMesh, layout: BeamLayout, bearing: float, low: float, high: float
) -> tuple[NDArray[np.float64], NDArray[np.uint8], NDArray[np.float64]]:
    """Directions, rings and ranges of the layout's beams that hit the mesh."""
    pad = float(np.abs(layout.azimuth_offsets).max()) + layout.azimuth_step
    rays = layout.rays(azimuth_range=(bearing + low - pad, bearing + high + pad))
    offset = _wrapped(rays.azimuth - bearing)
    inside = np.flatnonzero((offset >= low) & (offset <= high))
    ray, _, distance = cast_rays(mesh, rays.directions[inside], max_distance=layout.max_range)
    seen = distance >= layout.min_range
    rows = inside[ray[seen]]
    return rays.directions[rows], rays.ring[rows], distance[seen]


def _blocked(
    unit: NDArray[np.float64],
    ranges: NDArray[np.float64],
    direction: NDArray[np.float64],
    distance: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """Inserted beams that meet a target return in front of the object first (within the
    beam's angular half-width)."""
    blocked = np.zeros(len(direction), dtype=bool)
    if len(unit) == 0 or len(direction) == 0:
        return blocked
    tree = cKDTree(unit)
    for beam, neighbours in enumerate(tree.query_ball_point(direction, _BEAM_RADIUS)):
        blocked[beam] = bool((ranges[neighbours] < distance[beam] - 0.05).any())
    return blocked


def _intensity(
    template: ObjectTemplate,
    mesh: SceneMesh,
    direction: NDArray[np.float64],
    distance: NDArray[np.float64],
) -> NDArray[np.float32]:
    """Intensity of each new return: that of the template's nearest return."""
    if len(direction) == 0:
        return np.empty(0, dtype=np.float32)
    _, nearest = cKDTree(mesh.vertices).query(direction * distance[:, None])
    return template.intensity[nearest]


class InsertedDetected(Relation):
    """The inserted object is detected: when it has at least ``min_points`` returns and
    ``scope`` judges it, at least ``min_detected`` of its returns lie in follow-up
    obstacles (boxes grown by 10 cm, any label: a car seen from afar may come out as an
    unknown object, and the check is about not missing it)."""

    def __init__(
        self, *, min_points: int = 30, min_detected: float = 0.5, scope: ScopeLike = "roi"
    ) -> None:
        if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 1:
            raise InvalidArgument(f"min_points={min_points!r} must be a positive int")
        if isinstance(min_detected, bool) or not isinstance(min_detected, (int, float)):
            raise InvalidArgument(f"min_detected={min_detected!r} must be a number in [0, 1]")
        if not 0.0 <= min_detected <= 1.0:
            raise InvalidArgument(f"min_detected={min_detected!r} must be a number in [0, 1]")
        self.min_points = min_points
        self.min_detected = float(min_detected)
        self.scope: ObstacleScope = as_scope(scope)
        self.name = (
            f"inserted object detected (>= {min_points} returns: >= {min_detected:.0%} of "
            f"them in obstacles; {self.scope.describe()})"
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        insertion = context.params.get("insert_object", ())
        if insertion is None:
            return Verdict(True, self.name, "no free place to insert an object", {})
        if not isinstance(insertion, InsertObject):
            raise InvalidArgument(
                f"{self.name} needs the follow-up's InsertObject in params['insert_object'] "
                "(use object_insertion() or InsertObject.params())"
            )
        returns = len(insertion)
        details: dict[str, Any] = {"inserted": insertion.box.describe(), "returns": returns}
        judged = bool(self.scope.judged([insertion.box], context.followup_input)[0])
        if returns < self.min_points or not judged:
            details["judged"] = False
            return Verdict(True, self.name, "too few returns or not judged", details)
        detected = np.zeros(returns, dtype=bool)
        for value in followup_output:
            if not isinstance(value, Box):
                raise InvalidArgument(
                    f"object insertion needs Box outputs; a follow-up item is {value!r}"
                )
            detected |= value.grown(0.1).contains(insertion.points[:, :3])
        share = float(detected.mean())
        details.update(judged=True, detected_share=round(share, 3))
        if share >= self.min_detected:
            return Verdict(True, self.name, details=details)
        return Verdict(
            False,
            self.name,
            f"the inserted {insertion.box.describe()} ({returns} returns) is not detected: "
            f"{share:.0%} of its returns lie in follow-up obstacles",
            details,
        )
