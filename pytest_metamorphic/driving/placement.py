"""Where a Euro NCAP scenario's actors stand on a real road (``Scenario(placement="road")``).

The protocol places the dummy and the parked cars relative to the car's path (a crossing
dummy ``E`` = 4 or 6 m beside it, CPNCO's parked cars 1 m beside the car), which is right
on a test track and wrong on a street: on a 6 m street the dummy would start in the garden,
on a wide one in the next lane, and the parked cars could straddle the kerb or stand in a
traffic lane. On a road the placement follows the road's cross-section instead:

* a crossing dummy starts :data:`KERB_OFFSET` beyond the kerb on the side the protocol
  names (the right kerb for the near side, the left kerb of the whole carriageway for the
  far side), on the footway where one is mapped, else on the verge, and walks from there;
* CPNCO's parked cars stand centred in the parking lane at the near-side kerb (parallel
  parking). A road without one cannot host the test: the error says so and how to state a
  parking lane the map lacks (``Road.with_tags({"parking:right": "lane"})``).

Longitudinal (CPLA) dummies keep the protocol's placement (in the car's lane).
"""

from __future__ import annotations

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.roads import RoadGeometry

__all__ = ["KERB_OFFSET", "crossing_start", "parked_lateral"]

#: How far beyond the kerb a crossing dummy waits (m): its centre half a metre onto the
#: footway or verge, the child's own width (0.3 m) and a step clear of the kerb stone.
KERB_OFFSET = 0.5


def crossing_start(road: RoadGeometry, side: str) -> float:
    """Lateral offset ``d`` where a dummy crossing from ``side`` ("right"/"left") starts."""
    kerb = road.kerb(side)
    return kerb - KERB_OFFSET if side == "right" else kerb + KERB_OFFSET


def parked_lateral(road: RoadGeometry, width: float, *, side: str = "right") -> float:
    """Lateral offset ``d`` of a parked car's centre: the middle of the ``side`` parking lane.

    Raises
    ------
    InvalidArgument
        The road has no parking lane there, or one narrower than the car.
    """
    lane = road.parking_lane(side)
    if lane is None:
        raise InvalidArgument(
            f"{road.name or 'the road'} has no parking lane at the {side} kerb, so CPNCO's "
            "parked cars would stand in a traffic lane; state one the map lacks with "
            f"Road.with_tags({{'parking:{side}': 'lane'}}) or use placement='protocol'"
        )
    low, high = lane
    if high - low < width:
        raise InvalidArgument(
            f"the {side} parking lane of {road.name or 'the road'} is {high - low:g} m wide, "
            f"narrower than the {width:g} m parked car"
        )
    return (low + high) / 2
