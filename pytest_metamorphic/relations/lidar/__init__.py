"""Ready metamorphic relations for LiDAR obstacle perception (systems ``frame -> list[Box]``).

Each function returns a :class:`~pytest_metamorphic.core.engine.MetamorphicRelation`
(an input transform of a :class:`~pytest_metamorphic.lidar.model.frame.Frame` plus an output
relation) to pass to ``@metamorphic(relations=[...])``; :func:`lidar_relations` returns
them all. The source input must be a ``Frame`` with an ROI (``frame.roi``).

================================  ===================================  ======================
relation                          follow-up                            expected output
================================  ===================================  ======================
:func:`mr1_subset`                noise outside the ROI (paper's MR1)  O ⊆ O' (one-to-one)
:func:`mr1_cardinality`           the same                             abs O <= abs O'
:func:`outside_noise_invariance`  the same                             O == O'
:func:`outside_removal`           outside-ROI points removed           O == O'
:func:`permutation_invariance`    points reordered                     O == O'
:func:`duplication_invariance`    some points repeated                 O == O'
:func:`rotation_equivariance`     cloud and ROI turned by θ            O turned by θ (*)
:func:`mirror_symmetry`           cloud and ROI mirrored (y -> -y)     O mirrored (*)
:func:`beam_loss`                 1-4 of the sensor's lasers dead      well-covered O kept (*)
:func:`packet_loss`               1-10 of its packets lost             well-covered O kept (*)
:func:`range_quantization`        ranges rounded to 5/10/20 cm         O kept
:func:`object_removal`            one car/pedestrian/cyclist removed   the others kept
:func:`object_insertion`          a real object put on free ground,    it is found (its class),
                                  as seen or far out                   others kept
:func:`near_field_insertion`      a whole road user within 5 m of the  the same
                                  car, every side; lorries close by
:func:`object_relocation`         one object moved nearer, farther,    found where it went (its
                                  around the sensor or turned          class), others kept
:func:`adverse_weather`           fog or rain of 200/100/50 m          well-covered O kept
:func:`sensor_pose`               the sensor pitched, rolled or        road users of >= 100
                                  raised within the operating domain   returns kept where moved (*)
:func:`history_independence`      the sweep again, after other sweeps  O == O'
:func:`history_under_faults`      the sweep with dead lasers or lost   O == O' (its output
                                  packets, after other sweeps          right after itself)
================================  ===================================  ======================

(*) Cars, pedestrians and cyclists only: ``unknown`` obstacles are not judged by these.
Beam and packet loss need the frame's sensor
(:func:`~pytest_metamorphic.lidar.model.sensors.frame_sensor`); insertion needs objects to
insert (the frame's labels, or ``objects=``). Where a relation cannot act on a frame its
follow-up is not applicable, and a relation that tested nothing in a whole test is
reported so (``NothingTestedWarning``; ``--mt-strict-tested`` fails the test): every
relation's checks count the obstacles they judged (the summary's *judged* column).

MR1 follows Zhou & Sun (CACM 2019): 1000 points by default (the largest of their 10,
100 and 1000) scattered outside the ROI, z and intensity uniform over the frame's ranges, "outside"
holding for the exact polygons and for Apollo's 0.25 m bitmap with a free cell in
between. The paper checked only the cardinality; :func:`mr1_subset` checks what MR1
says, every source obstacle keeping its own match
(:func:`~pytest_metamorphic.core.matching.one_to_one`) in the follow-up.

The equalities are exact: a perception stack that filters by ROI first and treats the
cloud as a set of points (as
:class:`~pytest_metamorphic.lidar.systems.perception.ReferencePerception`
does) cannot tell the inputs apart. Rotation and reflection move the obstacles; see
:func:`rotation_equivariance` and :func:`mirror_symmetry` for their tolerances.
:func:`translation_equivariance` (a shift along x by whole grid cells) is optional and not
in :func:`lidar_relations`: it tests only detectors that claim translation invariance.
Nor is :func:`road_terrain` (the street on a slope, before a crest, across a camber): it
renders its source's scene again, so it needs rendered frames, not recordings.
"""

from __future__ import annotations

from typing import Any, Literal

from pytest_metamorphic.core.engine import MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.perturb import PAPER_NOISE_SIZES
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.judging.tolerance import (
    EXACT,
    LEARNED,
    Tolerance,
    ToleranceLike,
    as_tolerance,
)
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN, OperatingDomain
from pytest_metamorphic.relations.lidar.faults import (
    PACKET_DEGREES,
    CoveredObstaclesKept,
    beam_loss,
    packet_loss,
    range_quantization,
)
from pytest_metamorphic.relations.lidar.geometry import (
    MirroredObstacles,
    MovedObstacles,
    RotatedObstacles,
    ShiftedObstacles,
    mirror_symmetry,
    rotation_equivariance,
    translation_equivariance,
)
from pytest_metamorphic.relations.lidar.history import (
    history_independence,
    history_under_faults,
)
from pytest_metamorphic.relations.lidar.invariance import (
    PACKET_POINTS,
    duplication_invariance,
    permutation_invariance,
)
from pytest_metamorphic.relations.lidar.noise import (
    DEFAULT_NOISE,
    NoiseSize,
    mr1_cardinality,
    mr1_subset,
    outside_noise_invariance,
    outside_removal,
)
from pytest_metamorphic.relations.lidar.objects import (
    near_field_insertion,
    object_insertion,
    object_relocation,
    object_removal,
    object_templates,
    removal_candidates,
)
from pytest_metamorphic.relations.lidar.pose import POSE_DIMENSIONS, sensor_pose
from pytest_metamorphic.relations.lidar.terrain import road_terrain
from pytest_metamorphic.relations.lidar.weather import DEFAULT_VISIBILITIES, adverse_weather

__all__ = [
    "DEFAULT_NOISE",
    "DEFAULT_VISIBILITIES",
    "EXACT",
    "LEARNED",
    "PACKET_DEGREES",
    "PACKET_POINTS",
    "PAPER_NOISE_SIZES",
    "POSE_DIMENSIONS",
    "CoveredObstaclesKept",
    "MirroredObstacles",
    "MovedObstacles",
    "ObstacleScope",
    "RotatedObstacles",
    "ShiftedObstacles",
    "Tolerance",
    "adverse_weather",
    "beam_loss",
    "duplication_invariance",
    "history_independence",
    "history_under_faults",
    "lidar_relations",
    "mirror_symmetry",
    "mr1_cardinality",
    "mr1_subset",
    "near_field_insertion",
    "object_insertion",
    "object_relocation",
    "object_removal",
    "object_templates",
    "outside_noise_invariance",
    "outside_removal",
    "packet_loss",
    "permutation_invariance",
    "range_quantization",
    "removal_candidates",
    "road_terrain",
    "rotation_equivariance",
    "sensor_pose",
    "translation_equivariance",
]


def lidar_relations(
    *,
    noise: NoiseSize = DEFAULT_NOISE,
    rotation: Literal["quarter_turns", "any"] = "quarter_turns",
    scope: ScopeLike = "roi",
    tolerance: ToleranceLike = "exact",
    history: bool = True,
    domain: OperatingDomain | None = None,
) -> list[MetamorphicRelation]:
    """The whole library, for ``@metamorphic(relations=lidar_relations())``.

    ``noise`` is the ``n`` of the three noise relations; ``rotation`` the ``angles`` of
    :func:`rotation_equivariance`; ``scope`` which obstacles the ROI-related relations
    judge (default: those wholly inside the ROI; ``"all"`` for every obstacle);
    ``tolerance`` how much the outputs of equivalent inputs may differ: ``"exact"``
    (geometric pipelines) or ``"learned"`` (neural networks, whose outputs jitter: see
    :mod:`pytest_metamorphic.lidar.judging.tolerance`); ``history``: whether to include
    :func:`history_independence` and :func:`history_under_faults` (False for a tracker
    or a detector that accumulates sweeps on purpose: they are not per-frame); ``domain``
    the :class:`~pytest_metamorphic.lidar.model.domain.OperatingDomain` the insertions,
    the relocation and the sensor poses cover (default
    :data:`~pytest_metamorphic.lidar.model.domain.DEFAULT_DOMAIN`; e.g. ``max_range_m``
    for a detector that claims less than its sensor's range, ``near_field_m``).
    """
    as_scope(scope)
    if domain is not None and not isinstance(domain, OperatingDomain):
        raise InvalidArgument(f"domain={domain!r} must be an OperatingDomain or None")
    chosen = DEFAULT_DOMAIN if domain is None else domain
    if not isinstance(history, bool):
        raise InvalidArgument(f"history={history!r} must be True or False")
    profile = as_tolerance(tolerance)
    moved: dict[str, Any] = {}
    if profile.moved is not None:
        center, size, yaw, points = profile.moved
        moved = {"center_tolerance": center, "size_tolerance": size, "yaw_tolerance": yaw,
                 "min_points": points}  # fmt: skip
    if profile.moved_same_label is not None:
        moved["same_label"] = profile.moved_same_label
    if profile.moved_shared:
        moved["exclusive"] = False
    same, kept, support = profile.same, profile.kept, profile.same_min_points
    place, heading = _relocation_tolerance(profile)
    posed: dict[str, Any] = {}
    if profile.moved is not None:  # a network's sizes, headings and classes jitter
        posed = {"size_tolerance": max(profile.moved[1], 0.8),
                 "yaw_tolerance": max(profile.moved[2], 20.0)}  # fmt: skip
    return [
        mr1_subset(n=noise, scope=scope, matcher=kept),
        mr1_cardinality(n=noise, scope=scope),
        outside_noise_invariance(n=noise, scope=scope, matcher=same, min_points=support),
        outside_removal(scope=scope, matcher=same, min_points=support),
        permutation_invariance(matcher=same, min_points=support),
        duplication_invariance(matcher=same, min_points=support),
        rotation_equivariance(angles=rotation, scope=scope, **moved),
        mirror_symmetry(scope=scope, **moved),
        beam_loss(scope=scope),
        packet_loss(scope=scope),
        range_quantization(scope=scope),
        object_removal(scope=scope, matcher=kept),
        object_insertion(scope=scope, matcher=kept, domain=chosen),
        near_field_insertion(scope=scope, matcher=kept, domain=chosen),
        object_relocation(
            scope=scope,
            matcher=kept,
            center_tolerance=place,
            yaw_tolerance=heading,
            domain=chosen,
        ),
        adverse_weather(scope=scope),
        sensor_pose(scope=scope, center_tolerance=place, domain=chosen, **posed),
        *([history_independence(), history_under_faults()] if history else []),
    ]


def _relocation_tolerance(profile: Tolerance) -> tuple[float, float]:
    """A moved object's place and heading tolerances under ``profile`` (metres, degrees):
    the relation's own (0.5 m outside its moved footprint, 30 degrees) or looser ones (a
    learned detector's headings are not compared)."""
    if profile.moved is None:
        return 0.5, 30.0
    center, _, yaw, _ = profile.moved
    return max(center, 0.5), max(yaw, 30.0)
