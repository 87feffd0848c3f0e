"""Object insertion and removal as campaigns."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from pytest_metamorphic.core.campaign import Campaign
from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.core.relations import Relation
from pytest_metamorphic.lidar.campaign.sources import (
    SourceFn,
    _severities,
    scoped_campaign,
)
from pytest_metamorphic.lidar.followups.edit import OthersKept, RemoveObject, removal_candidates
from pytest_metamorphic.lidar.followups.insert import (
    InsertedDetected,
    InsertObject,
    ObjectTemplate,
    free_placements,
    object_templates,
)
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.found import ClassRule, check_class_rule
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box

__all__ = ["EDIT_SEVERITIES", "edit_campaign", "insertion_followup", "removal_followup"]


#: Default severities: insertion at this percentage of the range the object was seen at
#: (nearer, the same, farther); removal of the k-th nearest object.
EDIT_SEVERITIES: dict[str, tuple[int, ...]] = {
    "insertion": (80, 100, 125, 150),
    "removal": (1, 2, 3, 4),
}


@functools.lru_cache(maxsize=4)
def _templates(frame: Frame) -> tuple[ObjectTemplate, ...]:
    return tuple(object_templates(frame))


def insertion_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """One of the frame's own cars, pedestrians or cyclists inserted again, at
    ``severity`` percent of the range it was seen at, at a random free place (not
    applicable, and not counted as a pair, when there is no such place)."""
    factor = severity / 100.0
    places = [
        (template, placement)
        for template in _templates(frame)
        for placement in free_placements(frame, template, limit=8, factors=(factor,))
    ]
    if not places:
        reason = "no object of the frame's own has a free place at that range"
        return Followup.not_applicable(frame, reason)
    template, placement = places[int(rng.integers(len(places)))]
    insertion = InsertObject.onto(frame, template, placement)
    return Followup(insertion.apply(frame), params=insertion.params())


def removal_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """The ``severity``-th nearest car, pedestrian or cyclist removed (not applicable, and
    not counted as a pair, when the frame has fewer)."""
    candidates = removal_candidates(frame)
    if len(candidates) < severity:
        reason = f"the frame has {len(candidates)} car(s), pedestrian(s) and cyclist(s)"
        return Followup.not_applicable(frame, reason)
    removal = RemoveObject(candidates[severity - 1])
    return Followup(removal.apply(frame), params=removal.params())


_EDIT_FOLLOWUPS = {"insertion": insertion_followup, "removal": removal_followup}
_SEVERITY_LABELS = {"insertion": "range %", "removal": "k-th nearest"}


def edit_campaign(
    system: Callable[[Frame], Sequence[Box]],
    *,
    edit: Literal["insertion", "removal"],
    name: str,
    frames: SourceFn | FrameCatalog | str | os.PathLike[str] | None = None,
    sources: int | None = None,
    severities: Sequence[int] | None = None,
    followups: int = 1,
    seed: int = 0,
    clearance: float = 5.0,
    min_points: int = 30,
    min_detected: float = 0.5,
    classes: ClassRule = "own_or_unknown",
    matcher: Matcher | None = None,
    scope: ScopeLike = "roi",
) -> Campaign:
    """Object insertion or removal as a campaign: violation rates per severity, with
    Wilson intervals.

    Parameters
    ----------
    system : callable(Frame) -> sequence of Box
    edit : {"insertion", "removal"}
        Insertion (severity: the range, in percent of the range the object was seen at;
        checked with :class:`~pytest_metamorphic.lidar.followups.insert.InsertedDetected` and
        :class:`~pytest_metamorphic.lidar.followups.edit.OthersKept`) or removal (severity: which
        object, nearest first; checked with ``OthersKept``). A follow-up that finds no
        place or no object edits nothing and holds.
    name, frames, sources, followups, seed, scope
        As for :func:`mr1_campaign`.
    clearance, min_points, min_detected, classes, matcher
        As for :func:`~pytest_metamorphic.relations.lidar.object_insertion`.
    """
    if edit not in _EDIT_FOLLOWUPS:
        raise InvalidArgument(f"edit={edit!r} must be one of {sorted(_EDIT_FOLLOWUPS)}")
    levels = _severities(severities, EDIT_SEVERITIES[edit], 1000)
    check_class_rule(classes)

    def relation(chosen: ObstacleScope) -> Relation:
        kept = OthersKept(clearance=clearance, matcher=matcher, scope=chosen)
        if edit == "removal":
            return kept
        found = InsertedDetected(
            min_points=min_points, min_detected=min_detected, classes=classes, scope=chosen
        )
        return found & kept

    return scoped_campaign(
        system,
        name=name,
        frames=frames,
        sources=sources,
        followup=_EDIT_FOLLOWUPS[edit],
        relation=relation,
        sizes=levels,
        followups=followups,
        seed=seed,
        scope=scope,
        size_label=_SEVERITY_LABELS[edit],
    )
