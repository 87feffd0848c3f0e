"""Relations under object edits: an object taken out of the sweep, or put into it."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.followups.edit import OthersKept, removal_candidates
from pytest_metamorphic.lidar.followups.insert import (
    InsertedDetected,
    ObjectTemplate,
    object_templates,
)
from pytest_metamorphic.lidar.followups.insert.catalogue import SCALES
from pytest_metamorphic.lidar.followups.insert.reach import Reach
from pytest_metamorphic.lidar.followups.insert.relocated import RelocatedFound
from pytest_metamorphic.lidar.followups.insert.relocation import MOVE_KINDS, MoveKind
from pytest_metamorphic.lidar.judging.found import ClassRule
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.lidar.judging.well_seen import WELL_SEEN, WellSeen
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN, OperatingDomain
from pytest_metamorphic.lidar.model.hdl64 import BeamLayout
from pytest_metamorphic.relations.lidar._common import _PROBE, _frame, lidar_relation
from pytest_metamorphic.strategies._edits import (
    inserted_objects,
    relocated_objects,
    removed_objects,
)

__all__ = [
    "near_field_insertion",
    "object_insertion",
    "object_relocation",
    "object_removal",
    "object_templates",
    "removal_candidates",
]


def object_removal(
    *,
    clearance: float = 5.0,
    margin: float = 0.15,
    matcher: Matcher | None = None,
    scope: ScopeLike = "roi",
    name: str = "an object removed => the others kept",
) -> MetamorphicRelation:
    """Taking one object out of the sweep loses no other obstacle (semLidarFuzz's remove).

    The follow-up removes one car, pedestrian or cyclist
    (:func:`~pytest_metamorphic.strategies.removed_objects`: :func:`removal_candidates`,
    shrinking toward the nearest) with
    :class:`~pytest_metamorphic.lidar.followups.edit.RemoveObject`:
    its returns go, and its beams run on to the ground behind it. Every judged source
    obstacle at least ``clearance`` metres from it keeps its own match (``matcher``,
    default same label and bird's-eye IoU >= 0.5), as :class:`OthersKept` checks.

    Precondition: a detector whose decisions about one object do not depend on other
    objects farther away than ``clearance`` (default 5 m, beyond the reference pipeline's
    3.5 m ground window), judged outside the removed object's shadow (see
    :class:`~pytest_metamorphic.lidar.followups.edit.OthersKept`). Holds for the reference and the
    whole-scene detector on all six KITTI sweeps and a rendered street (tests).
    """
    relation = OthersKept(clearance=clearance, matcher=matcher, scope=scope)
    removed_objects(_PROBE, margin=margin, scope=scope)  # validate now

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return removed_objects(_frame(frame), margin=margin, scope=scope)

    return lidar_relation(name, followup, relation)


def object_insertion(
    *,
    objects: Sequence[ObjectTemplate] | None = None,
    road_users: bool = True,
    scales: Sequence[float] = SCALES,
    clearance: float = 5.0,
    min_points: int = 30,
    min_detected: float = 0.5,
    classes: ClassRule = "own_or_unknown",
    well_seen: WellSeen | None = WELL_SEEN,
    matcher: Matcher | None = None,
    layout: BeamLayout | None = None,
    scope: ScopeLike = "roi",
    reach: Sequence[Reach] = ("as seen", "far field"),
    domain: OperatingDomain = DEFAULT_DOMAIN,
    name: str = "an object inserted => it is detected and the others kept",
) -> MetamorphicRelation:
    """A real object put on free ground in the ROI is detected, and nothing else is lost
    (semLidarFuzz's add, MultiTest's insertion).

    The follow-up takes one of ``objects`` (:func:`object_templates`, e.g. from labelled
    KITTI sweeps or a rendered scene; default: the source frame's own cars, pedestrians
    and cyclists and, with ``road_users``, the built-in rendered road users of every size,
    a child to a 16.5 m articulated lorry), scaled by one of ``scales`` where it keeps a
    real size of its class, and places it (:func:`~pytest_metamorphic.strategies.inserted_objects`)
    with :class:`~pytest_metamorphic.lidar.followups.insert.InsertObject`: on free ground judged by
    ``scope`` and in clear view
    (:func:`~pytest_metamorphic.lidar.followups.insert.free_placements`),
    re-projected onto ``layout``'s beams (default: the frame's sensor), hiding what it
    stands in front of. Where it goes covers the operating domain (``reach`` bands of
    ``domain``, :mod:`~pytest_metamorphic.lidar.followups.insert.reach`): near the range
    it was seen from and far out (35-90 % of the sensor's range); the near field (the
    first metres around the car) is :func:`near_field_insertion`'s.
    Shrinking goes toward the first band, the first object and the smallest move from
    where it was seen; a violation reduces to the fewest inserted returns that still fail.
    An unlabelled recording has no objects of its own: the built-in road users are
    inserted, or pass ``objects`` (templates cut from any labelled recording or rendered
    scene, :func:`object_templates`, or a saved library,
    :func:`~pytest_metamorphic.lidar.followups.insert.load_templates`; they are re-cast for
    the frame's sensor); when the frame's sensor is unknown the relation is reported as
    having tested nothing.

    The check is :class:`~pytest_metamorphic.lidar.followups.insert.InsertedDetected` (an inserted
    object with >= ``min_points`` returns has >= ``min_detected`` of them in follow-up
    obstacles of its class, or ``"unknown"``: ``classes``, under either tolerance profile;
    an inserted pedestrian reported as a car is a violation; a well-seen pedestrian or
    cyclist reported as ``"unknown"`` is one too, ``well_seen``,
    :class:`~pytest_metamorphic.lidar.judging.well_seen.WellSeen`) and
    :class:`~pytest_metamorphic.lidar.followups.edit.OthersKept` (judged source obstacles
    >= ``clearance`` metres from it and not behind it keep their match).

    Precondition: a detector that finds an unoccluded object of >= 30 returns on free
    ground, and whose decisions about one object do not depend on objects farther away
    than ``clearance``. Holds for the reference and the whole-scene detector on all six
    KITTI sweeps and a rendered street (tests). Far away it tests the detector's ground
    model: inserting the KITTI and street templates at 1-2x their range on every sweep
    (84 insertions, 19 beyond 40 m), the reference missed one, a car 52 m away with 35
    returns, whose lowest returns its grid ground (cell minima) took for the ground it
    could not see around the car: a real limit of that ground model, which a search of
    far placements finds.
    """
    check = InsertedDetected(
        min_points=min_points, min_detected=min_detected, classes=classes,
        well_seen=well_seen, scope=scope,
    )  # fmt: skip
    relation = check & OthersKept(clearance=clearance, matcher=matcher, scope=scope)
    options: dict[str, Any] = {
        "objects": objects, "road_users": road_users, "scales": scales,
        "min_returns": min_points, "layout": layout, "reach": reach, "domain": domain,
    }  # fmt: skip
    inserted_objects(_PROBE, **options)  # validate now

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return inserted_objects(_frame(frame), scope=scope, **options)

    return lidar_relation(name, followup, relation)


def near_field_insertion(
    *,
    clearance: float = 5.0,
    min_points: int = 30,
    min_detected: float = 0.5,
    classes: ClassRule = "any",
    well_seen: WellSeen | None = WELL_SEEN,
    matcher: Matcher | None = None,
    layout: BeamLayout | None = None,
    scope: ScopeLike = "roi",
    domain: OperatingDomain = DEFAULT_DOMAIN,
    name: str = "an object inserted in the near field => it is detected and the others kept",
) -> MetamorphicRelation:
    """A road user standing right beside, in front of or behind the car is detected, and
    nothing else is lost: :func:`object_insertion` in the ``"near field"`` band of
    ``domain`` (:mod:`~pytest_metamorphic.lidar.followups.insert.reach`).

    The follow-up puts one of the built-in road users, as a whole mesh (a child to an
    articulated lorry,
    :func:`~pytest_metamorphic.lidar.followups.insert.catalogue.solid_road_users`),
    as close to the car as it can stand (0.3 m clear of ``domain.ego_size_m``), on
    every side and both ways round, wholly within ``domain.near_field_m`` (5 m); a lorry
    or a bus, longer than that, with its near end there and tens of thousands of returns.
    It stands on the nearest ground the sensor sees (none is seen under the first metres).
    This is where self-filters, blind zones, minimum ranges, cluster-size caps and
    classifiers that never saw a person this close live: faults no recording's templates
    reach (they hold the faces a sensor saw from metres away, and from a metre or two a
    sensor looks down onto the roof they lack).

    The check is :func:`object_insertion`'s, with ``classes="any"``: each must be found,
    and a well-seen pedestrian or cyclist not demoted to ``"unknown"`` (``well_seen``),
    but which road-user class it is called is not judged. Close by, a sensor sees a
    road user from above and partly outside its vertical field of view, and a
    shape-based classifier's cyclist, pedestrian and car meet (measured: the reference
    calls a cyclist standing across the line of sight 3.4 m behind a VLP-32C a car, the
    returns of its rider's shoulders spanning 0.7-0.9 m as a car's rear window does from
    behind, and one beside the doors of an OS1-128 a pedestrian, its wheels below the
    field of view); ``classes="own_or_unknown"`` judges classes there for a detector that
    claims them.

    Precondition: a detector that reports what stands in its first metres; one that
    crops a blind zone on purpose leaves it out of the ROI it is judged in (``scope``).
    Holds for the reference, its whole-scene variant and the DBSCAN-ties detector on the
    six KITTI sweeps, a rendered street and the other sensors' recordings and renders (8
    derandomized follow-ups each); the scikit-learn example's RANSAC plane runs through
    a van beside the car (tests/relations/test_soundness.py, its known weaknesses).
    """
    relation = object_insertion(
        objects=None, road_users=True, clearance=clearance, min_points=min_points,
        min_detected=min_detected, classes=classes, well_seen=well_seen, matcher=matcher,
        layout=layout, scope=scope, reach=("near field",), domain=domain, name=name,
    )  # fmt: skip
    return relation


def object_relocation(
    *,
    kinds: Sequence[MoveKind] = MOVE_KINDS,
    clearance: float = 5.0,
    min_points: int = 30,
    min_detected: float = 0.5,
    classes: ClassRule = "own_or_unknown",
    center_tolerance: float = 0.5,
    yaw_tolerance: float = 30.0,
    matcher: Matcher | None = None,
    layout: BeamLayout | None = None,
    scope: ScopeLike = "roi",
    domain: OperatingDomain = DEFAULT_DOMAIN,
    name: str = "an object moved => it is found where it went, the others kept",
) -> MetamorphicRelation:
    """Moving one real object of the sweep moves its detection, and nothing else changes
    (LiRTest's object translation and rotation, MultiTest's physical checks).

    The follow-up (:func:`~pytest_metamorphic.strategies.relocated_objects`) takes one car,
    pedestrian or cyclist out of the sweep (its beams run on to the ground behind it, as
    :func:`object_removal` does) and re-casts its own returns for the frame's sensor
    (``layout``) after one move of ``kinds``: 5-50 % nearer or 5-200 % farther along its
    bearing (the far field, within 90 % of ``domain``'s far limit; never into the near
    field, whose whole meshes :func:`near_field_insertion` places),
    2-180 degrees around the sensor at the same range, or turned 5-30 degrees in place
    (:class:`~pytest_metamorphic.lidar.followups.insert.relocation.RelocateObject`). The
    new place is free ground judged by ``scope``, in clear view, overlapping nothing.
    Shrinking goes toward the nearest object and the smallest move: a violation comes out
    as the least the object had to move (the range at which its class flips, the angle
    at which it is lost).

    The check is :class:`~pytest_metamorphic.lidar.followups.insert.relocated.RelocatedFound`
    (the object, as the system saw it where it stood, is found where it went: >=
    ``min_detected`` of its moved returns in obstacles of the class the system gave it,
    or ``"unknown"``; the centre of the obstacle holding them within ``center_tolerance``
    metres of its moved footprint, headed within ``yaw_tolerance`` degrees when longer
    than 2.2 m; a turned object's class is not judged) and :class:`OthersKept` (judged
    source obstacles >= ``clearance`` metres from where it stood and where it went, and
    out of both shadows, keep their match).

    Precondition: a detector whose output for an object depends on that object's returns
    and its surroundings within ``clearance``, and whose boxes follow the returns. Sizes
    are not compared: re-sampled at another range, a box fitted to one face changes
    length with how many rows reach its far end, and its centre slides along it (hence
    the footprint). Holds for the reference, the whole-scene detector, the scikit-learn
    example and the DBSCAN-ties detector on the six KITTI sweeps and three rendered
    streets (121 moves each, tests/relations/test_soundness.py).
    """
    check = RelocatedFound(
        min_points=min_points, min_detected=min_detected, classes=classes,
        center_tolerance=center_tolerance, yaw_tolerance=yaw_tolerance, scope=scope,
    )  # fmt: skip
    relation = check & OthersKept(clearance=clearance, matcher=matcher, scope=scope)
    relocated_objects(_PROBE, kinds=kinds, min_returns=min_points, layout=layout, domain=domain)

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return relocated_objects(
            _frame(frame), kinds=kinds, min_returns=min_points, layout=layout, scope=scope,
            domain=domain,
        )  # fmt: skip

    return lidar_relation(name, followup, relation)
