"""Where in the operating domain an object is placed: as seen, in the near field, far out.

:func:`~pytest_metamorphic.lidar.followups.insert.free_placements` keeps an object near the
range it was seen from (80-150 %), so a recording's templates never reach the first metres
around the car nor the sensor's far limit, and the faults that live there (self-filters,
blind-zone handling, cluster-size caps, range cut-offs) are never triggered.
:func:`domain_placements` adds two bands of the
:class:`~pytest_metamorphic.lidar.model.domain.OperatingDomain`:

* ``"near field"``: a whole road user (a solid template,
  :func:`~pytest_metamorphic.lidar.followups.insert.catalogue.solid_road_users`) as close
  to the car as it can stand, 0.3 m clear of the car's own footprint
  (``ego_size_m``), on every side (24 bearings) and both ways round (along the bearing
  and across it; a cyclist only across it: end-on it has a pedestrian's outline),
  wholly within ``near_field_m``. An object longer than the near field (a
  lorry, a bus) cannot fit in it: it is placed as close, its near end within it, and
  holds tens of thousands of returns (dense). A template cut from a recording is never
  placed there: it holds the faces a sensor saw metres away, and from a metre or two the
  sensor looks down onto the roof it lacks;
* ``"far field"``: any template from 35 % to 90 % of the far limit (``max_range_m``, by
  default the sensor's own range: 42-108 m for an HDL-64E's 120 m), every 5 degrees, on
  ground the sensor sees there and in scope (a region that ends at 70 m, as KITTI's
  labelled wedge does, takes the nearer of them), at the ranges where the sensor's beams
  still leave ``min_returns`` on it (with 20 % to spare for returns the frame blocks):
  a pedestrian of 9 returns at 45 m on a VLP-16 judges nothing, so it is not placed
  there.

Ground under a near-field placement is the nearest ground the sensor sees
(:attr:`~pytest_metamorphic.lidar.followups.insert.placement._TargetGround.nearest_ground`):
the road under the car is taken to be as high as just beyond it.
"""

from __future__ import annotations

import math
import weakref
from typing import Literal

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.insert.check import MIN_SPAN
from pytest_metamorphic.lidar.followups.insert.insertion import returns_in_the_open
from pytest_metamorphic.lidar.followups.insert.placement import free_placements, ground_of
from pytest_metamorphic.lidar.followups.insert.template import ObjectTemplate, Placement
from pytest_metamorphic.lidar.judging.scope import ScopeLike, as_scope
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN, OperatingDomain
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.model.obstacles import Box, footprint_distances

__all__ = ["REACHES", "Reach", "domain_placements", "ego_box"]

Reach = Literal["as seen", "near field", "far field"]
REACHES: tuple[Reach, ...] = ("as seen", "near field", "far field")
"""The bands, in the order Hypothesis shrinks toward (first: near where it was seen)."""

_EGO_CLEARANCE = 0.3  # metres between a placed footprint and the car's own
_NEAR_BEARINGS = 24  # every 15 degrees
_FAR_STEP = 5.0  # degrees between far-field bearings
_FAR_SHARES = (0.35, 0.45, 0.55, 0.65, 0.75, 0.9)  # of the far limit
_SCOPE_MARGIN = 0.2  # metres a placed footprint keeps inside the scope
_RETURNS_SPARE = 1.2  # a place must leave this times min_returns on the object in the open


def ego_box(domain: OperatingDomain = DEFAULT_DOMAIN) -> Box:
    """The car carrying the sensor, as a box centred under it (bird's eye)."""
    length, width = domain.ego_size_m
    return Box((0.0, 0.0, 0.0), (length, width, 1.5), 0.0, "car")


def _outline(box: Box, step: float = 0.1) -> np.ndarray:
    """(n, 2) points along ``box``'s footprint edges, ``step`` metres apart."""
    corners = box.corners_bev()
    points = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        count = max(2, math.ceil(float(np.linalg.norm(b - a)) / step) + 1)
        points.append(np.linspace(a, b, count))
    return np.concatenate(points)


def _gap(a: Box, b: Box) -> float:
    """Bird's-eye gap between two footprints, 0 when they overlap (edges sampled both
    ways: two crossing boxes need not hold a corner of each other)."""
    return float(
        min(
            footprint_distances(_outline(a), [b]).min(),
            footprint_distances(_outline(b), [a]).min(),
        )
    )


def _near_candidates(template: ObjectTemplate, domain: OperatingDomain) -> list[Placement]:
    """:func:`_near_placements`, once per template and domain (they depend on no frame)."""
    known = _NEAR_PLACES.setdefault(template, {})
    if domain not in known:
        known[domain] = [placement for _, placement in _near_placements(template, domain)]
    return known[domain]


_NEAR_PLACES: weakref.WeakKeyDictionary[ObjectTemplate, dict[OperatingDomain, list[Placement]]] = (
    weakref.WeakKeyDictionary()
)


def _near_placements(
    template: ObjectTemplate, domain: OperatingDomain
) -> list[tuple[float, Placement]]:
    """(order key, placement at ground 0) in the near field: per bearing and way round,
    from as close to the car as ``template`` stands outward in 0.25 m steps while it stays
    wholly within the near field (an object longer than the near field: while its near
    end does), ordered closest and straightest ahead first."""
    ego = ego_box(domain)
    limit = domain.near_field_m
    long = template.size[0] > limit
    found = []
    # A cyclist seen end-on has a pedestrian's outline (0.6 m wide, 1.7 m tall): which
    # of the two it is cannot be told from its returns (measured: the reference calls it
    # a pedestrian 3.5 m behind a VLP-32C), so it stands across the line of sight.
    turns = (math.pi / 2,) if template.label == "cyclist" else (0.0, math.pi / 2)
    for step in range(_NEAR_BEARINGS):
        bearing = math.remainder(2 * math.pi * step / _NEAR_BEARINGS, 2 * math.pi)
        for turn in turns:
            closest = None
            for quarter in range(2, int(limit * 4) + 40):
                placement = Placement(bearing, quarter / 4, 0.0, turn)
                box = template.box_at(placement)
                if closest is None:
                    if _gap(box, ego) < _EGO_CLEARANCE:
                        continue
                    closest = placement.range
                reach = np.hypot(*box.corners_bev().T)
                if float(reach.min() if long else reach.max()) > limit:
                    break
                key = abs(bearing) + turn / 10 + 4 * (placement.range - closest)
                found.append((key, placement))
    return sorted(found, key=lambda item: item[0])


def domain_placements(
    frame: Frame,
    template: ObjectTemplate,
    *,
    reach: Reach,
    domain: OperatingDomain = DEFAULT_DOMAIN,
    scope: ScopeLike = "roi",
    layout: BeamLayout = HDL64E,
    limit: int = 32,
    min_returns: int = 0,
) -> list[Placement]:
    """Up to ``limit`` free places for ``template`` in ``frame`` within ``reach`` (module
    docstring), each on free ground (no return more than 0.3 m above the local ground in
    the footprint grown by 0.5 m), in clear view and judged by ``scope`` with 0.2 m to
    spare.

    ``"as seen"`` is :func:`free_placements` (a car seen 25 m away holds 20 returns at
    1.5 times that on a VLP-16: kept only where it holds enough, as below);
    ``"near field"`` takes solid templates only
    (any other gives none) and orders its places from straight ahead round to behind;
    ``"far field"`` goes from the nearest share of the far limit outward and keeps the
    shares where ``layout``'s beams leave at least 1.2 times ``min_returns`` on the
    object in the open, over at least
    :data:`~pytest_metamorphic.lidar.followups.insert.check.MIN_SPAN` of its height
    (:func:`~pytest_metamorphic.lidar.followups.insert.insertion.returns_in_the_open`,
    cast once per range, turn and ground height); so does
    the near field, where a child in front of the bumper is below a VLP-16's lowest
    laser but for the top of its head."""
    if not isinstance(frame, Frame):
        raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
    if not isinstance(template, ObjectTemplate):
        raise InvalidArgument(f"template={template!r} must be an ObjectTemplate")
    if reach not in REACHES:
        raise InvalidArgument(f"reach={reach!r} must be one of {REACHES}")
    if not isinstance(domain, OperatingDomain):
        raise InvalidArgument(f"domain={domain!r} must be an OperatingDomain")
    if isinstance(min_returns, bool) or not isinstance(min_returns, int) or min_returns < 0:
        raise InvalidArgument(f"min_returns={min_returns!r} must be an int >= 0")
    if reach == "as seen":
        enough = _EnoughReturns(template, layout, min_returns)
        seen = free_placements(frame, template, scope=scope, layout=layout, limit=4 * limit)
        return [placement for placement in seen if enough(placement)][:limit]
    chosen = as_scope(scope)
    ground = ground_of(frame)
    if reach == "near field":
        if not template.solid:
            return []
        candidates = _near_candidates(template, domain)
        stand = ground.blind_ground_under
    else:
        far = domain.far_limit(layout.max_range)
        steps = int(180 / _FAR_STEP)
        candidates = [
            Placement(
                math.remainder(template.bearing + math.radians(turn * _FAR_STEP), 2 * math.pi),
                share * far,
                0.0,
            )
            for share in _FAR_SHARES
            if share * far > max(domain.near_field_m, layout.min_range + 2.0)
            for turn in sorted(range(-steps, steps), key=abs)
        ]
        stand = ground.ground_under
    enough = _EnoughReturns(template, layout, min_returns)
    found: list[Placement] = []
    for candidate in candidates:
        probe = template.box_at(candidate)
        z = stand(probe)
        if z is None or not ground.in_clear_view(probe):
            continue
        placement = Placement(candidate.bearing, candidate.range, z, candidate.turn)
        # Grown by 0.2 m: the scope samples a footprint, and the face of a lorry a few
        # centimetres outside a wedge's tip holds most of its returns.
        if not chosen.judged([template.box_at(placement).grown(_SCOPE_MARGIN)], frame)[0]:
            continue
        if not enough(placement):
            continue
        found.append(placement)
        if len(found) == limit:
            break
    return found


class _EnoughReturns:
    """Whether ``template`` at a placement is judged in the open: it holds ``min_returns``
    (with 20 % to spare) spanning :data:`~pytest_metamorphic.lidar.followups.insert.check.MIN_SPAN`
    or more (not the top of a child's head below a VLP-16's lowest laser). Cast once per
    template, layout, range, turn and ground height (to 5 cm), for every frame, at the
    first bearing asked (the count barely changes with the bearing; the ring pattern does
    with range and height)."""

    def __init__(self, template: ObjectTemplate, layout: BeamLayout, min_returns: int) -> None:
        self.template, self.layout, self.min_returns = template, layout, min_returns
        self.known = _IN_THE_OPEN.setdefault(template, {})

    def __call__(self, placement: Placement) -> bool:
        if self.min_returns == 0:
            return True
        key = (
            id(self.layout),
            self.min_returns,
            round(placement.range, 2),
            round(placement.turn, 3),
            round(placement.ground_z / 0.05),
        )
        known = self.known.get(key)
        if known is None or known[0] is not self.layout:  # an id may be reused
            points = returns_in_the_open(self.template, placement, layout=self.layout)
            span = float(np.ptp(points[:, 2])) if len(points) else 0.0
            judged = len(points) >= _RETURNS_SPARE * self.min_returns and span >= MIN_SPAN
            known = self.known[key] = (self.layout, judged)
        return known[1]


# Per template: (layout id, min_returns, range, turn, ground) -> (layout, judged in the open).
# A frame's placements of the built-in road users are mostly those of the frame before.
_IN_THE_OPEN: weakref.WeakKeyDictionary[
    ObjectTemplate, dict[tuple[int, int, float, float, int], tuple[BeamLayout, bool]]
] = weakref.WeakKeyDictionary()
