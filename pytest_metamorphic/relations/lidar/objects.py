"""Relations under object edits: an object taken out of the sweep, or put into it."""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.edit import OthersKept, RemoveObject, removal_candidates
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.insert import (
    InsertedDetected,
    InsertObject,
    ObjectTemplate,
    Placement,
    free_placements,
    object_templates,
)
from pytest_metamorphic.lidar.obstacles import Box
from pytest_metamorphic.lidar.scope import ScopeLike
from pytest_metamorphic.relations.lidar._common import _frame

__all__ = ["object_insertion", "object_removal", "object_templates", "removal_candidates"]


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


def object_insertion(
    *,
    objects: Sequence[ObjectTemplate] | None = None,
    clearance: float = 5.0,
    min_points: int = 30,
    min_detected: float = 0.5,
    matcher: Matcher | None = None,
    layout: BeamLayout = HDL64E,
    scope: ScopeLike = "roi",
    name: str = "an object inserted => it is detected and the others kept",
) -> MetamorphicRelation:
    """A real object put on free ground in the ROI is detected, and nothing else is lost
    (semLidarFuzz's add, MultiTest's insertion).

    The follow-up takes one of ``objects`` (:func:`object_templates`, e.g. from labelled
    KITTI sweeps or a rendered scene; default: the source frame's own cars, pedestrians
    and cyclists) and places it with
    :class:`~pytest_metamorphic.lidar.insert.InsertObject`: on free ground judged by
    ``scope`` and in clear view (:func:`~pytest_metamorphic.lidar.insert.free_placements`),
    re-projected onto ``layout``'s beams, hiding what it stands in front of. Shrinking goes
    toward the first object and the smallest move from where it was seen; a violation
    reduces to the fewest inserted returns that still fail.

    The check is :class:`~pytest_metamorphic.lidar.insert.InsertedDetected` (an inserted
    object with >= ``min_points`` returns has >= ``min_detected`` of them in follow-up
    obstacles, any label) and :class:`~pytest_metamorphic.lidar.edit.OthersKept` (judged
    source obstacles >= ``clearance`` metres from it and not behind it keep their match).

    Precondition: a detector that finds an unoccluded object of >= 30 returns on free
    ground, and whose decisions about one object do not depend on objects farther away
    than ``clearance``. Holds for the reference and the whole-scene detector on all six
    KITTI sweeps and a rendered street (tests).
    """
    check = InsertedDetected(min_points=min_points, min_detected=min_detected, scope=scope)
    relation = check & OthersKept(clearance=clearance, matcher=matcher, scope=scope)
    if not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout")
    if objects is not None:
        objects = list(objects)
        for index, template in enumerate(objects):
            if not isinstance(template, ObjectTemplate):
                raise InvalidArgument(f"objects[{index}] is {template!r}, not an ObjectTemplate")
        if not objects:
            raise InvalidArgument("objects is empty: pass None to take the source's own")
    # Placements per source frame (the search reads the whole cloud once).
    options: weakref.WeakKeyDictionary[Frame, list[tuple[ObjectTemplate, list[Placement]]]]
    options = weakref.WeakKeyDictionary()

    def where(frame: Frame) -> list[tuple[ObjectTemplate, list[Placement]]]:
        if frame not in options:
            templates = objects
            if templates is None:
                templates = object_templates(frame, min_returns=min_points, scope=scope)
            found = [(t, free_placements(frame, t, scope=scope, layout=layout)) for t in templates]
            options[frame] = [(t, places) for t, places in found if places]
        return options[frame]

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        choices = where(frame)
        if not choices:
            return st.just(Followup(frame, params={"insert_object": None}))

        def insert(template: ObjectTemplate, placement: Placement) -> Followup:
            insertion = InsertObject.onto(frame, template, placement, layout=layout)
            return Followup(insertion.apply(frame), params=insertion.params())

        def place(index: int) -> st.SearchStrategy[Followup]:
            template, places = choices[index]
            return st.sampled_from(places).map(lambda placement: insert(template, placement))

        return st.integers(0, len(choices) - 1).flatmap(place)

    return MetamorphicRelation(name, followup, relation)
