"""Whether a moved object is found where it went, as what it was."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Verdict
from pytest_metamorphic.lidar.followups.insert.check import PlacedObjectCheck
from pytest_metamorphic.lidar.followups.insert.relocation import RelocateObject
from pytest_metamorphic.lidar.judging.found import (
    ClassRule,
    accepted_labels,
    found_as,
)
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.lidar.model.obstacles import Box, as_boxes, footprint_distances
from pytest_metamorphic.lidar.roi.arguments import _positive_float

__all__ = ["RelocatedFound"]

# Boxes at least this long, and this many times as long as wide, have a heading to compare
# (a car cut to its front half is nearly square, and its box's heading is arbitrary).
_ELONGATED = 2.2
_ASPECT = 1.5


class RelocatedFound(PlacedObjectCheck):
    """The moved object is found where it went, as what the system called it where it
    stood.

    The source obstacle that was the object is the one holding most of its returns (at least
    half); a system that did not find it there, or an obstacle ``scope`` does not judge,
    makes no claim to keep. When the moved object has at least ``min_points`` returns
    spanning at least ``min_height_share`` of the height its cast returns spanned, at least
    ``min_detected`` of them must lie in follow-up obstacles of the source obstacle's class
    (``classes``, by default also ``"unknown"``; a source ``"unknown"`` accepts any class),
    and the obstacle holding most of them must stand with its centre within
    ``center_tolerance`` metres of the footprint of the source obstacle moved by the same
    motion, headed within ``yaw_tolerance`` degrees of it (modulo 180) when both footprints
    are elongated (the longer side at least 2.2 m and 1.5 times the shorter; other boxes
    have no heading to speak of). A turned object's class is not judged: turned, it shows
    the sensor another outline (a cyclist turned toward it is as short as a pedestrian);
    nor is the class of a moved object of fewer than ``class_points`` returns (100), only
    its place: a sparse object's class rests on a few returns, and where the grids of a
    detector cut it anew it flips (a KITTI car of 49 returns 33 m away, moved 22 degrees
    around the sensor, was a "pedestrian" to the reference's size rules; under a pitch of
    a few degrees the reference's cars of 36-68 returns changed class too).

    Sizes are not compared: the object is re-sampled at another range or angle, and a
    box fitted to the returns of one face changes length with how many rows reach its far
    end (see :func:`~pytest_metamorphic.relations.lidar.object_relocation`).
    """

    def __init__(
        self,
        *,
        min_points: int = 30,
        min_detected: float = 0.5,
        min_height_share: float = 0.8,
        classes: ClassRule = "own_or_unknown",
        center_tolerance: float = 0.5,
        yaw_tolerance: float = 30.0,
        class_points: int = 100,
        scope: ScopeLike = "roi",
    ) -> None:
        if isinstance(class_points, bool) or not isinstance(class_points, int) or class_points < 0:
            raise InvalidArgument(f"class_points={class_points!r} must be an int >= 0")
        self.class_points = class_points
        super().__init__(
            min_points=min_points, min_detected=min_detected, min_height_share=min_height_share,
            classes=classes, scope=scope,
        )  # fmt: skip
        self.center_tolerance = _positive_float(center_tolerance, "center_tolerance")
        self.yaw_tolerance = _positive_float(yaw_tolerance, "yaw_tolerance")
        self.name = (
            f"moved object found where it went (>= {min_points} returns: >= "
            f"{min_detected:.0%} in obstacles of its class, centre within "
            f"{center_tolerance:g} m of its moved footprint; {self.scope.describe()})"
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        relocation = context.params.get("relocate_object", ())
        if relocation is None:
            return Verdict(True, self.name, "no object to move", {"judged": 0})
        if not isinstance(relocation, RelocateObject):
            raise InvalidArgument(
                f"{self.name} needs the follow-up's RelocateObject in "
                "params['relocate_object'] (use object_relocation() or RelocateObject.params())"
            )
        source = as_boxes(source_output, "source")
        details: dict[str, Any] = {"moved": relocation.describe_edit(), "judged": 0}
        index = _holder(source, relocation.original)
        if index is None:
            return Verdict(
                True, self.name, "the system did not find the object where it stood", details
            )
        before = source[index]
        if not self.scope.judged([before], context.source_input)[0]:
            return Verdict(True, self.name, "the object is not judged where it stood", details)
        moved = relocation.insertion.points[:, :3]
        if len(moved) < self.min_points or not self.spans(relocation.insertion)[1]:
            return Verdict(True, self.name, "too few returns where it went", details)
        expected = relocation.expected(before)
        boxes = as_boxes(followup_output, "follow-up")
        # A turned object shows the sensor another outline (a cyclist turned toward it is
        # as short as a pedestrian), a sparse one's class flips where grids cut it anew:
        # their class is not judged, their place and heading are.
        judged_class = (
            before.label != "unknown"
            and relocation.move.kind != "turn"
            and len(moved) >= self.class_points
        )
        accepted = accepted_labels(before.label, self.classes if judged_class else "any")
        found = found_as(moved, boxes, accepted)
        details.update(
            judged=1,
            source_obstacle=before.describe(),
            expected=expected.describe(),
            found_share=round(found.share, 3),
            found_as_share=round(found.share_as, 3),
            found_as=found.main_label(),
        )
        what = f"{before.describe()}, moved {relocation.move.describe()} ({len(moved)} returns)"
        if found.share_as < self.min_detected:
            if found.share >= self.min_detected:
                wrong = [label for label in found.labels if accepted and label not in accepted]
                return Verdict(
                    False, self.name, f"{what} is found as a {wrong[0]}, not a {before.label}",
                    {**details, "blamed": [index]},
                )  # fmt: skip
            return Verdict(
                False,
                self.name,
                f"{what} is not found: {found.share:.0%} of its returns lie in follow-up obstacles",
                {**details, "blamed": [index]},
            )
        holder = _holder(boxes, moved, accepted=accepted, share=0.0)
        assert holder is not None  # share_as > 0: an accepted box holds some of them
        after = boxes[holder]
        # A box fitted to the faces seen changes length with how many rows reach its far
        # end, and its centre slides along it: the place is the expected footprint.
        gap = _footprint_gap(after, expected)
        details.update(
            found=after.describe(),
            center_gap=round(math.dist(after.center[:2], expected.center[:2]), 3),
            outside_footprint=round(gap, 3),
        )
        if gap > self.center_tolerance:
            return Verdict(
                False,
                self.name,
                f"{what} is found {gap:.2f} m outside where it went: {after.describe()}, "
                f"expected {expected.describe()} ({expected.size[0]:.1f} x "
                f"{expected.size[1]:.1f} m)",
                {**details, "blamed": [index]},  # a picture marks where it stood
            )
        turn = _heading_gap(after, expected)
        if turn is not None:
            details["heading_gap"] = round(turn, 1)
            if turn > self.yaw_tolerance:
                return Verdict(
                    False,
                    self.name,
                    f"{what} is found headed {turn:.0f} degrees off: {after.describe()}, "
                    f"expected heading {math.degrees(expected.yaw):.0f} degrees",
                    {**details, "blamed": [index]},
                )
        return Verdict(True, self.name, details=details)


def _holder(
    boxes: list[Box],
    points: np.ndarray,
    *,
    accepted: frozenset[str] | None = None,
    share: float = 0.5,
) -> int | None:
    """Index of the box (of an ``accepted`` label) holding most of ``points``, when it
    holds at least ``share`` of them (and one)."""
    best, count = None, 0
    for i, box in enumerate(boxes):
        if accepted is not None and box.label not in accepted:
            continue
        held = int(box.grown(0.1).contains(points).sum())
        if held > count:
            best, count = i, held
    if best is None or count < share * len(points):
        return None
    return best


def _footprint_gap(found: Box, expected: Box) -> float:
    """Metres from ``found``'s centre to ``expected``'s footprint (0 inside it)."""
    return float(footprint_distances(np.array([found.center[:2]]), [expected])[0])


def _heading_gap(a: Box, b: Box) -> float | None:
    """Degrees between the headings (``yaw``) of two elongated boxes, modulo 180 (None:
    either footprint's longer side is under 2.2 m or under 1.5 times the shorter)."""
    for box in (a, b):
        # Either side may be the long one: a box reported as 1.8 m long and 4.3 m wide
        # claims the car drives sideways, and that heading is compared as given.
        long, short = max(box.size[:2]), min(box.size[:2])
        if long < _ELONGATED or long < _ASPECT * short:
            return None
    gap = abs(math.remainder(a.yaw - b.yaw, math.pi))
    return math.degrees(gap)
