"""The relation over the road's shape: the same street rendered on a slope, before a crest
or across a cambered road, keeps its road users."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.judging.equivariance import TerrainObstacles
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN, OperatingDomain
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.terrain import Terrain
from pytest_metamorphic.lidar.synthetic.render import rendering_of
from pytest_metamorphic.relations.lidar._common import _frame, lidar_relation

__all__ = ["road_terrain"]

#: Why a recording's road cannot be bent (the follow-up's not-applicable reason).
NOT_RENDERED = (
    "the road's shape is varied on rendered scenes only (render(), mst.scene_frames(), "
    "street_scene()): bending a recorded sweep's ground would move returns off the scan "
    "pattern a sloped road gives (beams meet a slope at other ranges, and what an uphill "
    "road hides no recording holds)"
)
_STARTS = (5.0, 10.0, 15.0, 20.0, 30.0)  # metres ahead where the grade begins
_CURVES = (20.0, 10.0, 40.0)  # vertical curve lengths, gentlest first after 20 m


def _terrains(domain: OperatingDomain) -> st.SearchStrategy[Terrain]:
    """Terrains within ``domain``: whole-percent grades, camber in tenths, shrinking toward
    a gentle grade from 5 m ahead (never flat)."""
    low, high = domain.grade_percent
    grades = st.integers(round(low), round(high))
    camber_low, camber_high = domain.camber_percent
    cambers = st.integers(round(camber_low * 10), round(camber_high * 10))
    return (
        st.tuples(grades, st.sampled_from(_STARTS), st.sampled_from(_CURVES), cambers)
        .filter(lambda drawn: drawn[0] != 0 or drawn[3] != 0)
        .map(lambda drawn: Terrain(drawn[0], drawn[1], drawn[2], drawn[3] / 10))
    )


def road_terrain(
    *,
    domain: OperatingDomain | None = None,
    center_tolerance: float = 0.5,
    size_tolerance: float = 0.8,
    yaw_tolerance: float = 30.0,
    min_points: int = 100,
    boundary_margin: float = 1.0,
    same_label: bool = False,
    scope: ScopeLike = "roi",
    name: str = "road sloped, crested or cambered => road users kept",
) -> MetamorphicRelation:
    """The same street on another road shape keeps its road users: each is still found
    where it stands, raised or lowered with the road.

    The source must be a rendered frame (:func:`~pytest_metamorphic.lidar.synthetic.render`,
    :func:`~pytest_metamorphic.strategies.scene_frames`); the follow-up renders its scene
    again, with the same beams and noise, on a
    :class:`~pytest_metamorphic.lidar.model.terrain.Terrain` drawn from ``domain``
    (default grades ±8 %, the steepest of urban arterials in AASHTO's Green Book,
    camber 0-2.5 %): a grade change 5-30 m ahead over a 10-40 m vertical curve (uphill
    ahead: a sag; downhill: a crest), and the road falling from its crown to both sides.
    Every obstacle and background object stands on the new road, tilted with it. On a
    recording the follow-up is not applicable, with the reason (a recorded ground cannot
    be bent honestly): pass rendered streets, e.g. with the clutter of a real one
    (:func:`~pytest_metamorphic.lidar.synthetic.streetscape.street_scene`), rendered with your
    sensor. Opt-in for that reason: not in
    :func:`~pytest_metamorphic.relations.lidar.lidar_relations`.

    The check is :class:`~pytest_metamorphic.lidar.judging.equivariance.TerrainObstacles`
    with ``extras_judged=False``: every source road user of >= ``min_points`` returns
    needs its own follow-up obstacle where it stands, with the tolerances of
    :func:`~pytest_metamorphic.relations.lidar.sensor_pose` for its place and size (a
    road user standing on a slope is tilted with it, as under a pitched sensor) and of
    :func:`~pytest_metamorphic.relations.lidar.object_relocation` for its heading (30
    degrees, compared only for footprints at least 2.2 m long and 1.5 times as long as
    wide: the object is cast anew, and a cyclist's MinBox turned by 23 degrees on a 1 %
    grade, another's by 32 on a 0.3 % camber), its class
    compared with ``same_label`` (off by default: measured, the reference calls the
    street's cyclist 18 m ahead a pedestrian on an 8 % downhill road or a 2.5 % camber,
    its box where it was). New road users are not judged (a sag shows the sensor road
    users a flat road hid), but a *phantom* is: an obstacle of >= 30 returns in scope
    more than 1 m from every object of the scene and every source obstacle, where
    nothing but road stands (the road became an obstacle: a car brakes for it).

    Precondition: a detector that estimates the ground from the returns and follows
    slopes of the domain's grades. One that takes the ground to be a level sensor's plane
    or caps the slope it follows below the domain's grades does not claim it: that is
    what it finds.
    """
    if domain is None:
        domain = DEFAULT_DOMAIN
    if not isinstance(domain, OperatingDomain):
        raise InvalidArgument(f"domain={domain!r} must be an OperatingDomain or None")
    if domain.grade_percent == (0.0, 0.0) and domain.camber_percent == (0.0, 0.0):
        raise InvalidArgument(f"domain={domain!r} varies neither grade nor camber")
    terrains = _terrains(domain)
    relation = TerrainObstacles(
        center_tolerance=center_tolerance,
        size_tolerance=size_tolerance,
        yaw_tolerance=yaw_tolerance,
        min_points=min_points,
        boundary_margin=boundary_margin,
        same_label=same_label,
        extras_judged=False,
        scope=scope,
    )

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        rendering = rendering_of(frame)
        if rendering is None or rendering.scene.terrain is not None:
            return st.just(Followup.not_applicable(frame, NOT_RENDERED))
        return terrains.map(lambda terrain: _on(frame, rendering, terrain))

    return lidar_relation(name, followup, relation)


def _on(frame: Frame, rendering: Any, terrain: Terrain) -> Followup:
    scene = rendering.scene.on_terrain(terrain)
    followup = rendering.again(scene)
    objects = [*scene.boxes, *(_footprint(item) for item in scene.background)]
    return Followup(
        followup,
        params={**terrain.params(), "terrain": terrain.describe(), "scene_objects": objects},
    )


def _footprint(item: Any) -> Box:
    """A background object's footprint as a box (for the phantom check)."""
    return Box((*item.center, 0.0), item.size, item.yaw, "unknown")
