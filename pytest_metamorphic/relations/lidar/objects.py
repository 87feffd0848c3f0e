"""Relations under object edits: an object taken out of the sweep."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.edit import OthersKept, RemoveObject
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.obstacles import Box
from pytest_metamorphic.lidar.perception import ReferencePerception
from pytest_metamorphic.lidar.scope import ScopeLike, as_scope
from pytest_metamorphic.relations.lidar._common import _frame

__all__ = ["object_removal", "removal_candidates"]

_PROPOSER = ReferencePerception()
_CLASSES = ("car", "pedestrian", "cyclist")


def removal_candidates(frame: Frame, *, scope: ScopeLike = "roi") -> list[Box]:
    """Objects a follow-up may remove, nearest first: the frame's labelled boxes (ground
    truth) when it has any, else what the reference pipeline finds; cars, pedestrians and
    cyclists that ``scope`` judges."""
    chosen = as_scope(scope)
    boxes = list(frame.boxes) or _PROPOSER(frame)
    boxes = [box for box in boxes if box.label in _CLASSES]
    judged = chosen.judged(boxes, frame)
    inside = [box for box, keep in zip(boxes, judged, strict=True) if keep]
    return sorted(inside, key=lambda box: (box.center[0] ** 2 + box.center[1] ** 2, box.center))


def object_removal(
    *,
    clearance: float = 5.0,
    margin: float = 0.15,
    matcher: Matcher | None = None,
    scope: ScopeLike = "roi",
    name: str = "an object removed => the others kept",
) -> MetamorphicRelation:
    """Taking one object out of the sweep loses no other obstacle (semLidarFuzz's remove).

    The follow-up removes one car, pedestrian or cyclist (:func:`removal_candidates`;
    shrinking toward the nearest) with :class:`~pytest_metamorphic.lidar.edit.RemoveObject`:
    its returns go, and its beams run on to the ground behind it. Every judged source
    obstacle at least ``clearance`` metres from it keeps its own match (``matcher``,
    default same label and bird's-eye IoU >= 0.5), as :class:`OthersKept` checks.

    Precondition: a detector whose decisions about one object do not depend on other
    objects farther away than ``clearance`` (default 5 m, beyond the reference pipeline's
    3.5 m ground window), judged outside the removed object's shadow (see
    :class:`~pytest_metamorphic.lidar.edit.OthersKept`). Holds for the reference and the
    whole-scene detector on all six KITTI sweeps and a rendered street (tests).
    """
    relation = OthersKept(clearance=clearance, matcher=matcher, scope=scope)
    RemoveObject(Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.0), margin)  # validate now

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        objects = removal_candidates(frame, scope=scope)
        if not objects:
            return st.just(Followup(frame, params={"remove_object": None}))

        def remove(index: int) -> Followup:
            removal = RemoveObject(objects[index], margin)
            return Followup(removal.apply(frame), params=removal.params())

        return st.integers(0, len(objects) - 1).map(remove)

    return MetamorphicRelation(name, followup, relation)
