"""Strategies for object edits: an object taken out of the frame, or a real one put in.

Each takes the source frame and returns a strategy of
:class:`~pytest_metamorphic.core.engine.Followup`. When the frame offers nothing to edit
(no object to remove, no free place for any object, an unknown sensor) the strategy gives
:meth:`Followup.not_applicable <pytest_metamorphic.core.cases.Followup.not_applicable>`
with the reason: the system is not run, and a relation that never applied in a test is
reported as having tested nothing.
"""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.edit import RemoveObject, removal_candidates
from pytest_metamorphic.lidar.followups.insert import (
    InsertObject,
    ObjectTemplate,
    Placement,
    object_templates,
)
from pytest_metamorphic.lidar.followups.insert.catalogue import (
    SCALES,
    fits_class,
    road_user_templates,
    solid_road_users,
)
from pytest_metamorphic.lidar.followups.insert.placement import free_ground
from pytest_metamorphic.lidar.followups.insert.reach import REACHES, Reach, domain_placements
from pytest_metamorphic.lidar.followups.insert.relocation import (
    MOVE_KINDS,
    Movable,
    Move,
    MoveKind,
)
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN, OperatingDomain
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import BeamLayout
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors import frame_sensor
from pytest_metamorphic.strategies._noise import _check_frame

__all__ = ["inserted_objects", "relocated_objects", "removed_objects"]

_Options = list[tuple[Reach, list[tuple[ObjectTemplate, list[Placement]]]]]
# Free places per frame and options: the search reads the whole cloud once per frame.
_PLACES: weakref.WeakKeyDictionary[Frame, dict[tuple[Any, ...], _Options]] = (
    weakref.WeakKeyDictionary()
)


def removed_objects(
    frame: Any, *, margin: float = 0.15, scope: ScopeLike = "roi"
) -> st.SearchStrategy[Followup]:
    """The frame without one of its cars, pedestrians or cyclists
    (:func:`~pytest_metamorphic.lidar.followups.edit.removal_candidates`, shrinking toward the
    nearest) removed by :class:`~pytest_metamorphic.lidar.followups.edit.RemoveObject`."""
    frame = _check_frame(frame)
    RemoveObject(Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)), margin)  # validates margin
    chosen = as_scope(scope)

    proposer = "labels" if frame.boxes else "the reference pipeline's proposals (HDL-64E tuned)"

    def removals() -> st.SearchStrategy[Followup]:
        objects = removal_candidates(frame, scope=chosen)
        if not objects:
            reason = (
                f"no car, pedestrian or cyclist to remove among {proposer} ({chosen.describe()})"
            )
            return st.just(Followup.not_applicable(frame, reason))

        def remove(index: int) -> Followup:
            removal = RemoveObject(objects[index], margin)
            return Followup(removal.apply(frame), params={**removal.params(), "proposer": proposer})

        return st.integers(0, len(objects) - 1).map(remove)

    # Candidates are found when the first example is drawn, not when the strategy is made.
    return st.deferred(removals)


def inserted_objects(
    frame: Any,
    *,
    objects: Sequence[ObjectTemplate] | None = None,
    road_users: bool = True,
    scales: Sequence[float] = SCALES,
    min_returns: int = 30,
    layout: BeamLayout | None = None,
    scope: ScopeLike = "roi",
    reach: Sequence[Reach] = REACHES,
    domain: OperatingDomain = DEFAULT_DOMAIN,
) -> st.SearchStrategy[Followup]:
    """The frame with one of ``objects`` (default: its own cars, pedestrians and cyclists
    of >= ``min_returns`` returns,
    :func:`~pytest_metamorphic.lidar.followups.insert.object_templates`, and with
    ``road_users`` the built-in rendered ones of every size, a child to an articulated
    lorry, :func:`~pytest_metamorphic.lidar.followups.insert.catalogue.road_user_templates`)
    put on free ground judged by ``scope``, in clear view, re-cast with ``layout``'s beams
    (default: the frame's sensor, :func:`~pytest_metamorphic.lidar.model.sensors.frame_sensor`)
    (:class:`~pytest_metamorphic.lidar.followups.insert.InsertObject`), in one of the
    ``reach`` bands of ``domain``
    (:func:`~pytest_metamorphic.lidar.followups.insert.reach.domain_placements`):

    * ``"as seen"``: 80-150 % of the range it was seen from, scaled by one of ``scales``
      where the result is a real size of its class
      (:data:`~pytest_metamorphic.lidar.followups.insert.catalogue.CLASS_SIZES`) and still
      fits the place;
    * ``"near field"``: the built-in road users as whole meshes
      (:func:`~pytest_metamorphic.lidar.followups.insert.catalogue.solid_road_users`,
      with ``road_users``; solid templates among ``objects``) within the first metres on
      every side of the car, lorries and buses with their near end there (dense);
    * ``"far field"``: any of them 35-90 % of the way to the far limit, where the
      sensor's beams still leave ``min_returns`` on it.

    Shrinks toward the first band, the first object, the smallest move from where it was
    seen and the first scale (1). Not applicable (and reported so) when there is no object
    to insert or the frame's sensor is unknown."""
    frame = _check_frame(frame)
    if layout is not None and not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout or None (the frame's)")
    chosen = as_scope(scope)
    templates = None if objects is None else tuple(objects)
    if templates is not None:
        for index, template in enumerate(templates):
            if not isinstance(template, ObjectTemplate):
                raise InvalidArgument(f"objects[{index}] is {template!r}, not an ObjectTemplate")
        if not templates:
            raise InvalidArgument("objects is empty: pass None to take the frame's own")
    if isinstance(min_returns, bool) or not isinstance(min_returns, int) or min_returns < 10:
        raise InvalidArgument(f"min_returns={min_returns!r} must be an int >= 10")
    if not isinstance(road_users, bool):
        raise InvalidArgument(f"road_users={road_users!r} must be True or False")
    factors = _scales(scales)
    reaches = _reaches(reach)
    if not isinstance(domain, OperatingDomain):
        raise InvalidArgument(f"domain={domain!r} must be an OperatingDomain")

    def insertions() -> st.SearchStrategy[Followup]:
        beams = layout if layout is not None else frame_sensor(frame).sensor
        if not isinstance(beams, BeamLayout):
            return st.just(Followup.not_applicable(frame, _no_beams(frame)))
        key = (templates, road_users, min_returns, chosen, id(beams), reaches, domain)

        def insert(
            band: Reach, template: ObjectTemplate, placement: Placement, factor: float
        ) -> Followup:
            if band == "as seen":
                template, placement = _scaled(frame, template, placement, factor, chosen)
            insertion = InsertObject.onto(frame, template, placement, layout=beams)
            return Followup(insertion.apply(frame), params={**insertion.params(), "reach": band})

        cache = _PLACES.setdefault(frame, {})
        if key not in cache:
            cache[key] = _insertion_options(
                frame, templates, road_users, min_returns, chosen, beams, reaches, domain
            )
        options = cache[key]
        if not options:
            reason = (
                "no free place in scope for any of the given objects"
                if templates
                else "no object to insert: the frame has no labelled car, pedestrian or "
                f"cyclist of >= {min_returns} returns; pass objects= (object_templates of "
                "labelled recordings or rendered scenes, or load_templates(library))"
            )
            return st.just(Followup.not_applicable(frame, reason))

        def place(band: Reach, index: int, chosen: list[Any]) -> st.SearchStrategy[Followup]:
            template, places = chosen[index]
            drawn = st.tuples(st.sampled_from(places), st.sampled_from(factors)).map(
                lambda drawn: insert(band, template, *drawn)
            )
            # Places are kept where the object in the open holds 1.2 x min_returns; the
            # frame may still block a few of its beams at one bearing, or a scale shrink it.
            return drawn.filter(lambda f: f.params["inserted_returns"] >= min_returns)

        def pick(option: tuple[Reach, list[Any]]) -> st.SearchStrategy[Followup]:
            band, chosen = option
            return st.integers(0, len(chosen) - 1).flatmap(lambda i: place(band, i, chosen))

        return st.sampled_from(options).flatmap(pick)

    # Places are searched when the first example is drawn, not when the strategy is made.
    return st.deferred(insertions)


def _reaches(reach: Sequence[Reach]) -> tuple[Reach, ...]:
    chosen = tuple(reach) if not isinstance(reach, str) else ()
    if not chosen or any(band not in REACHES for band in chosen) or len(set(chosen)) < len(chosen):
        raise InvalidArgument(f"reach={reach!r} must be distinct bands of {REACHES}")
    return chosen


def _insertion_options(
    frame: Frame,
    templates: tuple[ObjectTemplate, ...] | None,
    road_users: bool,
    min_returns: int,
    scope: ObstacleScope,
    beams: BeamLayout,
    reaches: tuple[Reach, ...],
    domain: OperatingDomain,
) -> _Options:
    """Per band, the templates with free places in it (bands with none left out)."""
    found = list(templates or object_templates(frame, min_returns=min_returns, scope=scope))
    if road_users and templates is None:
        found += road_user_templates()
    solid = [t for t in found if t.solid]
    if road_users and templates is None:
        solid += solid_road_users()
    options: _Options = []
    for band in reaches:
        pool = solid if band == "near field" else found
        places = [
            (
                t,
                domain_placements(
                    frame,
                    t,
                    reach=band,
                    domain=domain,
                    scope=scope,
                    layout=beams,
                    min_returns=min_returns,
                ),
            )
            for t in pool
        ]
        kept = [(t, p) for t, p in places if p]
        if kept:
            options.append((band, kept))
    return options


def _scales(scales: Sequence[float]) -> tuple[float, ...]:
    chosen = tuple(scales)
    if not chosen or not all(
        isinstance(f, (int, float)) and not isinstance(f, bool) and 0.5 <= f <= 2 for f in chosen
    ):
        raise InvalidArgument(f"scales={scales!r} must be factors between 0.5 and 2")
    return chosen


def _scaled(
    frame: Frame, template: ObjectTemplate, placement: Placement, factor: float, scope: Any
) -> tuple[ObjectTemplate, Placement]:
    """``template`` scaled by ``factor`` at ``placement`` when that is a real size of its
    class and the place still takes it; else the template as it is."""
    if factor == 1:
        return template, placement
    scaled = template.scaled(factor)
    if not fits_class(scaled.size, scaled.label):
        return template, placement
    ground = free_ground(frame, scaled.box_at(placement), scope=scope)
    if ground is None:
        return template, placement
    return scaled, dataclasses.replace(placement, ground_z=ground)


def relocated_objects(
    frame: Any,
    *,
    kinds: Sequence[MoveKind] = MOVE_KINDS,
    margin: float = 0.15,
    min_returns: int = 30,
    layout: BeamLayout | None = None,
    scope: ScopeLike = "roi",
    domain: OperatingDomain = DEFAULT_DOMAIN,
) -> st.SearchStrategy[Followup]:
    """The frame with one of its cars, pedestrians or cyclists moved
    (:class:`~pytest_metamorphic.lidar.followups.insert.relocation.RelocateObject`): nearer or
    farther along its bearing, around the sensor at the same range, or turned in place
    (``kinds``), onto free ground judged by ``scope``, in clear view, re-cast with
    ``layout``'s beams (default: the frame's sensor). The objects are
    :func:`~pytest_metamorphic.lidar.followups.edit.removal_candidates` (labels, else the
    reference pipeline's proposals) whose returns make a template of >= ``min_returns``,
    never beyond 90 % of ``domain``'s far limit (``max_range_m``, by default the
    sensor's range). Shrinks toward the nearest object, the first kind and the smallest
    move. Not
    applicable (and reported so) when no object can move or the sensor is unknown."""
    frame = _check_frame(frame)
    if layout is not None and not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout or None (the frame's)")
    chosen_kinds = tuple(kinds)
    if not chosen_kinds or any(kind not in MOVE_KINDS for kind in chosen_kinds):
        raise InvalidArgument(f"kinds={kinds!r} must be a non-empty subset of {MOVE_KINDS}")
    if isinstance(min_returns, bool) or not isinstance(min_returns, int) or min_returns < 10:
        raise InvalidArgument(f"min_returns={min_returns!r} must be an int >= 10")
    RemoveObject(Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)), margin)  # validates margin
    chosen = as_scope(scope)
    if not isinstance(domain, OperatingDomain):
        raise InvalidArgument(f"domain={domain!r} must be an OperatingDomain")

    def moves() -> st.SearchStrategy[Followup]:
        beams = layout if layout is not None else frame_sensor(frame).sensor
        if not isinstance(beams, BeamLayout):
            return st.just(Followup.not_applicable(frame, _no_beams(frame)))
        key = ("relocate", chosen_kinds, margin, min_returns, chosen, id(beams), domain)
        cache = _MOVABLE.setdefault(frame, {})
        if key not in cache:
            cache[key] = _movables(frame, chosen_kinds, margin, min_returns, beams, chosen, domain)
        movables = cache[key]
        if not movables:
            return st.just(Followup.not_applicable(frame, _nothing_moves(frame, chosen)))

        def move(item: Movable, step: Move) -> Followup:
            relocation = item.relocate(step, layout=beams)
            if relocation is None:  # listed as free: the same checks, so never
                return Followup.not_applicable(frame, f"no free place {step.describe()}")
            return Followup(relocation.apply(frame), params=relocation.params())

        def pick(index: int) -> st.SearchStrategy[Followup]:
            item, free = movables[index]
            return st.sampled_from([k for k in chosen_kinds if k in free]).flatmap(
                lambda kind: st.sampled_from(free[kind]).map(lambda m: move(item, m))
            )

        return st.integers(0, len(movables) - 1).flatmap(pick)

    # Objects and their free moves are found when the first example is drawn.
    return st.deferred(moves)


# Movable objects per frame and options: finding their free moves reads the cloud per object.
_MOVABLE: weakref.WeakKeyDictionary[
    Frame, dict[tuple[Any, ...], list[tuple[Movable, dict[MoveKind, list[Move]]]]]
] = weakref.WeakKeyDictionary()


def _movables(
    frame: Frame,
    kinds: tuple[MoveKind, ...],
    margin: float,
    min_returns: int,
    beams: BeamLayout,
    scope: ObstacleScope,
    domain: OperatingDomain,
) -> list[tuple[Movable, dict[MoveKind, list[Move]]]]:
    found = []
    for box in removal_candidates(frame, scope=scope):
        item = Movable.of(frame, box, margin=margin, min_returns=min_returns)
        moves = (
            {}
            if item is None
            else item.moves(layout=beams, scope=scope, kinds=kinds, domain=domain)
        )
        if item is not None and moves:
            found.append((item, moves))
    return found


def _nothing_moves(frame: Frame, scope: ObstacleScope) -> str:
    proposer = "labels" if frame.boxes else "the reference pipeline's proposals"
    return (
        f"no car, pedestrian or cyclist among {proposer} ({scope.describe()}) can move: none "
        "has enough returns for a template, or no move leaves one on free ground in view"
    )


def _no_beams(frame: Frame) -> str:
    estimate = frame_sensor(frame)
    if estimate.sensor is None:
        return (
            f"re-casting needs the frame's sensor, and it is not known ({estimate.describe()}); "
            "pass sensor= to the Frame or FrameCatalog"
        )
    return f"re-casting needs a spinning multi-beam sensor, not a {estimate.sensor.short_name}"
