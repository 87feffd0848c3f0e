"""Scene edits a real sensor could have seen: an object taken out of a sweep.

:class:`RemoveObject` deletes an object's returns and, as the sensor would have seen
without it, lets each of those beams run on to the ground behind it (semLidarFuzz's
*remove*, with the ground filled by re-casting the beams instead of copying patches):
the ground height is the median of the ground returns around the object, each beam's
return lands where its ray meets that height (within the sensor's range), and takes the
surrounding ground's median intensity; the height is then read again around the
landing spot. Only the object's shadow is filled (up to 10 m behind it: farther on the
ground's height is not known well enough, and the beam returned nothing there before).
Beams that pointed above the horizon return nothing, and beams that meet another object
first (a return above the ground along the
same beam, nearer than the ground) return from it, which is already in the sweep.
Per-point fields (``ring``, ...) stay with their beams.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import matched_pairs
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import (
    Box,
    IoUMatcher,
    as_boxes,
    box_gap,
    footprint_distances,
)
from pytest_metamorphic.lidar.systems.perception import ReferencePerception

__all__ = [
    "OthersKept",
    "RemoveObject",
    "beams_meeting",
    "box_gap",
    "removal_candidates",
    "shadow_overlaps",
]

_GROUND_RING = (0.5, 4.0)  # metres around the footprint where the ground is sampled
_GROUND_BAND = 0.3  # metres above the box bottom still counted as ground
_MAX_RANGE = 120.0  # HDL-64E
# Half the angle between neighbouring beams (radians): the HDL-64E's lower lasers are 0.5
# degrees apart, its firings 0.17 degrees.
_BEAM_WIDTH = math.radians(0.3)
_MAX_SHADOW = 10.0  # metres behind the object that beams are re-cast to
_GROUND_LOOKUP = 1.5  # metres around a landing spot where the local ground is read
_CLASSES = ("car", "pedestrian", "cyclist")
_PROPOSER = ReferencePerception()  # proposes the objects of an unlabelled frame


def removal_candidates(
    frame: Frame, *, scope: ScopeLike = "roi", labelled_only: bool = False
) -> list[Box]:
    """Objects a follow-up may remove, nearest first: the frame's labelled boxes (ground
    truth) when it has any, else (unless ``labelled_only``) what the reference pipeline
    finds; cars, pedestrians and cyclists that ``scope`` judges."""
    chosen = as_scope(scope)
    boxes = list(frame.boxes) or ([] if labelled_only else _PROPOSER(frame))
    boxes = [box for box in boxes if box.label in _CLASSES]
    judged = chosen.judged(boxes, frame)
    inside = [box for box, keep in zip(boxes, judged, strict=True) if keep]
    return sorted(inside, key=lambda box: (box.center[0] ** 2 + box.center[1] ** 2, box.center))


def _polar(corners: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Bearings (unwrapped about the first corner's) and ranges of footprint corners."""
    bearing = np.arctan2(corners[:, 1], corners[:, 0])
    bearing = bearing[0] + np.remainder(bearing - bearing[0] + math.pi, 2 * math.pi) - math.pi
    return bearing, np.hypot(corners[:, 0], corners[:, 1])


def beams_meeting(
    xyz: NDArray[np.floating],
    direction: NDArray[np.float64],
    near: NDArray[np.float64],
    far: NDArray[np.float64],
    *,
    radius: float,
) -> NDArray[np.bool_]:
    """(b,) bool: which beams meet one of the returns ``xyz`` (n, 3) strictly between
    ``near`` and ``far`` metres along them, a return counting for a beam when its direction
    is within ``radius`` radians of the beam's ``direction`` (b, 3, unit vectors)."""
    met = np.zeros(len(direction), dtype=bool)
    if len(direction) == 0 or len(xyz) == 0:
        return met
    ranges = np.linalg.norm(np.asarray(xyz, dtype=np.float64), axis=1)
    tree = cKDTree(xyz / np.maximum(ranges, 1e-9)[:, None])
    for beam, neighbours in enumerate(tree.query_ball_point(direction, radius)):
        along = ranges[neighbours]
        met[beam] = bool(((along > near[beam]) & (along < far[beam])).any())
    return met


def shadow_overlaps(near: Box, box: Box, *, reach: float = math.inf) -> bool:
    """Whether ``box`` lies (partly) in ``near``'s shadow as seen from the sensor: within
    the bearings ``near`` covers (plus one degree) and between its nearest corner and
    ``reach`` metres."""
    front, far = _polar(near.corners_bev()), _polar(box.corners_bev())
    pad = math.radians(1.0)
    overlap = far[0].min() <= front[0].max() + pad and far[0].max() >= front[0].min() - pad
    return bool(overlap and far[1].min() <= reach and far[1].max() >= front[1].min())


@dataclass(frozen=True)
class RemoveObject:
    """Delete the returns of the object in ``box`` (grown by ``margin``) and re-cast their
    beams to the ground behind it.

    Parameters
    ----------
    box : Box
        The object (e.g. a detected or labelled obstacle).
    margin : float
        Metres added to the box's length and width on every side, and below its top, so
        that returns on its skin are removed too.
    """

    box: Box
    margin: float = 0.15

    def __post_init__(self) -> None:
        if not isinstance(self.box, Box):
            raise InvalidArgument(f"box={self.box!r} must be a Box")
        margin = self.margin
        if isinstance(margin, bool) or not isinstance(margin, (int, float)):
            raise InvalidArgument(f"margin={margin!r} must be a number of metres >= 0")
        if not (math.isfinite(margin) and margin >= 0):
            raise InvalidArgument(f"margin={margin!r} must be a number of metres >= 0")

    def region(self) -> Box:
        """The grown box whose returns are removed."""
        return self.box.grown(self.margin)

    def ground_height(self, frame: Frame) -> tuple[float, float]:
        """``(z, intensity)``: median height and intensity of the ground around the object."""
        points = frame.cloud.points
        gap = footprint_distances(points[:, :2], [self.box])
        near = (gap >= _GROUND_RING[0]) & (gap <= _GROUND_RING[1])
        ground = near & (points[:, 2] <= self.box.bottom_z + _GROUND_BAND)
        if not ground.any():
            return self.box.bottom_z, 0.0
        return float(np.median(points[ground, 2])), float(np.median(points[ground, 3]))

    def removed(self, frame: Frame, ground_z: float | None = None) -> NDArray[np.bool_]:
        """Which points are the object's (inside the grown box, above the ground band);
        ``ground_z``: :meth:`ground_height`'s, when already known."""
        points = frame.cloud.points
        if ground_z is None:
            ground_z, _ = self.ground_height(frame)
        return self.region().contains(points[:, :3]) & (points[:, 2] > ground_z + 0.1)

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        cloud = frame.cloud
        ground_z, intensity = self.ground_height(frame)
        removed = self.removed(frame, ground_z)
        rows = np.flatnonzero(removed)
        xyz = cloud.points[rows, :3].astype(np.float64)
        ranges = np.linalg.norm(xyz, axis=1)
        direction = xyz / np.maximum(ranges, 1e-9)[:, None]
        others = cloud.points[~removed]
        reach = self._reach(others, direction, ground_z)
        # Only the object's shadow: farther on, the beam's ground is not known well enough
        # (and before the removal it returned nothing there either).
        hits = (reach > ranges) & (reach - ranges <= _MAX_SHADOW) & (reach <= _MAX_RANGE)
        hits &= ~self._blocked(others, direction, ranges, reach, ground_z)
        landed = np.column_stack(
            [direction[hits] * reach[hits, None], np.full(int(hits.sum()), intensity)]
        ).astype(np.float32)
        behind = cloud[rows[hits]].with_points(landed) if hits.any() else None
        kept = cloud[~removed]
        new_cloud = kept if behind is None else PointCloud.concatenate([kept, behind])
        region = self.region()
        boxes = tuple(b for b in frame.boxes if not region.contains([b.center])[0])
        return dataclasses.replace(frame, cloud=new_cloud, boxes=boxes)

    @staticmethod
    def _reach(
        others: NDArray[np.float32], direction: NDArray[np.float64], ground_z: float
    ) -> NDArray[np.float64]:
        """Range at which each beam meets the ground: first at the height around the
        object, then at the median height of the ground returns near that spot (a road is
        rarely flat over the shadow). ``inf`` for beams that do not point down."""
        down = direction[:, 2] < -1e-3
        reach = np.full(len(direction), np.inf)
        reach[down] = ground_z / direction[down, 2]
        ground = others[others[:, 2] <= ground_z + _GROUND_BAND]
        if not down.any() or len(ground) == 0:
            return reach
        tree = cKDTree(ground[:, :2])
        landing = direction[down, :2] * reach[down, None]
        heights = [
            float(np.median(ground[near, 2])) if near else ground_z
            for near in tree.query_ball_point(landing, _GROUND_LOOKUP)
        ]
        reach[down] = np.asarray(heights) / direction[down, 2]
        return reach

    @staticmethod
    def _blocked(
        others: NDArray[np.float32],
        direction: NDArray[np.float64],
        ranges: NDArray[np.float64],
        reach: NDArray[np.float64],
        ground_z: float,
    ) -> NDArray[np.bool_]:
        """Beams that meet another object (a return above the ground, along the same beam
        within the sensor's angular resolution) before they reach the ground: they return
        from that object, whose own returns are already in the sweep, so they add none."""
        solid = others[others[:, 2] > ground_z + _GROUND_BAND]
        return beams_meeting(solid[:, :3], direction, ranges, reach, radius=_BEAM_WIDTH)

    def in_shadow(self, box: Box) -> bool:
        """Whether ``box`` lies (partly) in the removed object's shadow: the bearings the
        object covers, from it to where its beams are re-cast (10 m behind it). The ground
        there is new in the follow-up but the lower parts of objects behind it, which a
        sensor would now see too, are not: they are exempt from the relation."""
        region = self.region()
        reach = float(np.hypot(*region.corners_bev().T).max()) + _MAX_SHADOW + 2.0
        return shadow_overlaps(region, box, reach=reach)

    def affects(self, box: Box, clearance: float) -> bool:
        """Whether ``box`` is within ``clearance`` metres of the removed object or in its
        shadow: the removal may fairly change what is detected there."""
        return box_gap(box, self.region()) < clearance or self.in_shadow(box)

    def params(self) -> dict[str, Any]:
        return {"removed_object": self.box.describe(), "remove_object": self}

    def describe_edit(self) -> str:
        return f"removed {self.box.describe()}"

    def to_json(self) -> dict[str, Any]:
        return {"type": "RemoveObject", "box": self.box.to_json(), "margin": self.margin}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RemoveObject:
        """The removal :meth:`to_json` describes (artifacts replay with it)."""
        return cls(Box.from_json(data["box"]), float(data["margin"]))

    def __repr__(self) -> str:
        return f"RemoveObject({self.box.describe()})"


class OthersKept(Relation):
    """Every judged source obstacle at least ``clearance`` metres (footprint to footprint)
    from the removed (or inserted, :class:`~pytest_metamorphic.lidar.followups.insert.InsertObject`)
    object, and outside its shadow, keeps its own match in the follow-up.

    Closer obstacles are exempt: the removal changes the ground a detector estimates
    around them (the reference uses returns within 3.5 m) and may split or merge what
    touched the object. So are those in its shadow (:meth:`RemoveObject.in_shadow`): a
    real removal would also reveal their lower parts, which the edit cannot invent (seen
    on KITTI: a car 6 m behind a removed one, floating over new ground, lost its label),
    and those an inserted object hides (partly or their ground). The removed object itself
    may vanish or stay; whether an inserted one is found is
    :class:`~pytest_metamorphic.lidar.followups.insert.InsertedDetected`'s question.
    """

    def __init__(
        self, *, clearance: float = 5.0, matcher: Any = None, scope: ScopeLike = "roi"
    ) -> None:
        if isinstance(clearance, bool) or not isinstance(clearance, (int, float)):
            raise InvalidArgument(f"clearance={clearance!r} must be a number of metres >= 0")
        if not (math.isfinite(clearance) and clearance >= 0):
            raise InvalidArgument(f"clearance={clearance!r} must be a number of metres >= 0")
        self.clearance = float(clearance)
        self.matcher = matcher or IoUMatcher()
        self.scope: ObstacleScope = as_scope(scope)
        self.name = (
            f"others kept (>= {clearance:g} m from the edited object; {self.matcher.name}; "
            f"{self.scope.describe()})"
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        edit = _edit(context.params, self.name)
        if edit is None:  # the source had no object to edit: the follow-up is the source
            return Verdict(True, self.name, "no object edited", {"edited": None, "judged": 0})
        source = as_boxes(source_output, "source")
        found = as_boxes(followup_output, "follow-up")
        region = edit.region()
        judged = self.scope.judged(source, context.source_input)
        rows = [
            i for i, box in enumerate(source) if judged[i] and not edit.affects(box, self.clearance)
        ]
        matched = {
            rows[r] for r, _ in matched_pairs(self.matcher, [source[i] for i in rows], found)
        }
        lost = [i for i in rows if i not in matched]
        details = {
            "edited": region.describe(),
            "judged_far": len(rows),
            "judged": len(rows),
            "lost": [source[i].describe() for i in lost],
            # Source indices: what a picture marks as lost, and what it shows as not judged.
            "blamed": lost,
            "unjudged_source": [i for i, chosen in enumerate(judged) if not chosen],
        }
        if not lost:
            return Verdict(True, self.name, details=details)
        lines = [
            f"{source[i].describe()} ({box_gap(source[i], region):.1f} m from the "
            f"{edit.describe_edit()}) has no match"
            for i in lost[:10]
        ]
        return Verdict(False, self.name, "; ".join(lines), details)


_EDIT_KEYS = ("remove_object", "insert_object", "relocate_object")
_EDIT_API = ("region", "affects", "describe_edit")


def _edit(params: Mapping[str, Any], relation: str) -> Any:
    """The follow-up's object edit (None: the source had no object to edit)."""
    for key in _EDIT_KEYS:
        if key in params:
            edit = params[key]
            if edit is None or all(callable(getattr(edit, name, None)) for name in _EDIT_API):
                return edit
            raise InvalidArgument(f"params[{key!r}]={edit!r} is not an object edit")
    raise InvalidArgument(
        f"{relation} needs the follow-up's edit in params['remove_object'], "
        "params['insert_object'] or params['relocate_object'] (use object_removal(), "
        "object_insertion(), object_relocation() or the edit's params())"
    )
