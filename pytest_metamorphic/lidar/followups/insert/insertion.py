"""The insertion itself: the target's beams cast at the placed mesh."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.edit import beams_meeting, box_gap, shadow_overlaps
from pytest_metamorphic.lidar.followups.insert.template import (
    ObjectTemplate,
    Placement,
    _bearing_window,
    _relative_bearing,
    _wrapped,
)
from pytest_metamorphic.lidar.followups.perturb import append_points
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.model.obstacles import Box, footprint_distances
from pytest_metamorphic.lidar.synthetic.meshes import SceneMesh
from pytest_metamorphic.lidar.synthetic.raycast import cast_rays

__all__ = ["INSERTED_INSTANCE", "InsertObject", "returns_in_the_open"]

INSERTED_INSTANCE = -4
"""``instance`` field value of inserted returns (rendered frames carry the field)."""

_BEAM_RADIUS = math.radians(0.15)  # angular half-width of one beam


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
    template : ObjectTemplate or None
    span : float or None
        The vertical extent (m) of all the returns cast onto the object, kept by
        :meth:`restrict`: how much of the object a reduced set of returns still shows.
    """

    box: Box
    points: NDArray[np.float32] = field(repr=False)
    ring: NDArray[np.uint8] = field(repr=False)
    hidden: NDArray[np.intp] = field(repr=False)
    hidden_by: NDArray[np.intp] = field(repr=False)
    hidden_xy: NDArray[np.float64] = field(repr=False)
    target_points: int
    template: ObjectTemplate | None = field(default=None, repr=False)
    span: float | None = field(default=None, repr=False)

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
        # A beam that meets a target return in front of the object returns from it instead.
        blocked = beams_meeting(
            xyz[near[~behind]],
            direction,
            np.zeros(len(distance)),
            distance - 0.05,
            radius=_BEAM_RADIUS,
        )
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
            _span(points),
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
            "type": "InsertObject",
            "box": self.box.to_json(),
            "points": self.points.tolist(),
            "ring": self.ring.tolist(),
            "hidden": self.hidden.tolist(),
            "hidden_by": self.hidden_by.tolist(),
            "hidden_xy": self.hidden_xy.tolist(),
            "target_points": self.target_points,
            "template": None if self.template is None else self.template.describe(),
            "span": self.span,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> InsertObject:
        """The insertion :meth:`to_json` describes, without its template (artifacts replay
        with it)."""
        points = np.asarray(data["points"], dtype=np.float32).reshape(-1, 4)
        span = data.get("span")  # records of earlier versions have none: the returns' own
        return cls(
            Box.from_json(data["box"]),
            points,
            np.asarray(data["ring"], dtype=np.uint8),
            np.asarray(data["hidden"], dtype=np.intp),
            np.asarray(data["hidden_by"], dtype=np.intp),
            np.asarray(data["hidden_xy"], dtype=np.float64).reshape(-1, 2),
            int(data["target_points"]),
            span=_span(points) if span is None else float(span),
        )

    def __repr__(self) -> str:
        return f"InsertObject({self.box.describe()}, {len(self.points)} returns)"


def returns_in_the_open(
    template: ObjectTemplate, placement: Placement, *, layout: BeamLayout = HDL64E
) -> NDArray[np.float64]:
    """(k, 3) float64: where ``layout``'s beams meet ``template`` standing at ``placement``
    with nothing in front of it, the most an insertion there can hold (one cast of the
    object alone, milliseconds; :meth:`InsertObject.onto` also casts the frame)."""
    mesh = template.mesh_at(placement)
    low, high = _bearing_window(mesh.vertices, placement.bearing)
    direction, _, distance = _returns(mesh, layout, placement.bearing, low, high)
    return direction * distance[:, None]


def _span(points: NDArray[np.float32]) -> float:
    """Vertical extent (m) of ``points``; 0 for none."""
    return float(points[:, 2].max() - points[:, 2].min()) if len(points) else 0.0


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


def _intensity(
    template: ObjectTemplate,
    mesh: SceneMesh,
    direction: NDArray[np.float64],
    distance: NDArray[np.float64],
) -> NDArray[np.float32]:
    """Intensity of each new return: that of the template's nearest return."""
    if len(direction) == 0:
        return np.empty(0, dtype=np.float32)
    # The template's returns come first among the mesh's vertices (then their patches).
    returns = mesh.vertices[: len(template.vertices)]
    _, nearest = cKDTree(returns).query(direction * distance[:, None])
    return template.intensity[nearest]
