"""An avoidability judge that shares nothing with the controllers or the simulator.

A violation of the speed relation (the source avoided the collision, a follow-up did not)
is only a finding when the follow-up's collision could have been avoided at all. Judging
that with the reference controller's own object selection, or in the simulator the
controllers drive in, would let both share one blind spot. :func:`judge_avoidable`
answers from the :class:`~pytest_metamorphic.driving.scenario.Scenario` alone:

**Standard.** The pedestrian is a *hazard* from the first moment it is both

* *visible*: a straight line from the middle of the car's front bumper to the dummy's
  centre or one of its corners passes through no parked car, the point is ahead of the
  bumper and within 100 m; and
* *in the car's way*, by one of three stated standards (``relevance``):

  - ``"carriageway"`` (default): its centre is on the carriageway (kerb to kerb, from the
    road: it has stepped onto the road) and it walks towards the car's path: the moment a
    pedestrian stepping off the kerb towards the car is recognisable as crossing;
  - ``"lane"``: its centre is inside the car's lane (the lane's real boundaries): later
    on wide roads, so fewer collisions count as avoidable;
  - ``"path"``: its body overlaps the car's swept path (the car's width along its path),
    the laxest standard for the car.

From then the car reacts after ``reaction_time`` = ``decision_time`` (default 0.1 s, one
perception cycle to confirm) + the car's ``sensor_latency`` + ``brake_delay``, then
brakes at its ``max_deceleration`` until it stands. The collision is *physically
avoidable* when this car touches the pedestrian at no moment before it stands still (the
Euro NCAP test ends at standstill; a dummy walking into a standing car is no impact).
Until the reaction, the car drives at its initial speed: the judge asks what any
controller in this car could have done, not what the one under test did.

**Geometry.** Everything in road coordinates ``(s, d)``: the car is the rectangle
``[front - length, front] x [path - width/2, path + width/2]``, the dummy its footprint
around its derived position, parked cars their rectangles; on curved roads this is the
road-aligned (Frenet) approximation, exact on straight ones. Time is sampled every
millisecond. Nothing here calls a controller, the simulator, its sensor or
:func:`~pytest_metamorphic.driving.kinematics.is_relevant`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.arguments import check_number
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.scenario import KMH, Scenario

__all__ = ["JUDGE_RANGE", "RELEVANCE_STANDARDS", "Judgement", "judge_avoidable"]

Relevance = Literal["carriageway", "lane", "path"]
#: The judge's relevance standards (:func:`judge_avoidable`).
RELEVANCE_STANDARDS: tuple[str, ...] = ("carriageway", "lane", "path")
#: How far ahead of the bumper the judge's line of sight reaches (m).
JUDGE_RANGE = 100.0
_STEP = 0.001
_EXTRA_TIME = 5.0


class _Walk(NamedTuple):
    """The dummy sampled over time: road coordinates and half its extents."""

    s: NDArray[np.float64]
    d: NDArray[np.float64]
    half_along: float
    half_across: float


@dataclass(frozen=True)
class Judgement:
    """The judge's verdict on one scenario.

    Attributes
    ----------
    avoidable : bool
    relevant_time : float or None
        When the pedestrian became a hazard (visible and in the car's way); None if it
        never did before the unbraked car reached it.
    visible_time : float or None
        When it first became visible (before or after it entered the car's way).
    brake_time : float or None
        ``relevant_time + reaction_time``: when full braking takes effect.
    gap : float
        Avoidable: free distance (m, along the road) between the stopped car's bumper and
        the dummy. Unavoidable: minus the car's speed at the first contact (m/s).
    standard : str
        The relevance standard and reaction time, for reports.
    """

    avoidable: bool
    relevant_time: float | None
    visible_time: float | None
    brake_time: float | None
    gap: float
    standard: str

    def describe(self) -> str:
        if not self.avoidable and self.standard.endswith("passes first"):
            return (
                f"unavoidable by braking: a hazard at t={self.relevant_time:.2f} s, braking "
                f"from {self.brake_time:.2f} s misses the pedestrian only by passing before "
                f"it arrives ({self.standard.removesuffix(', passes first')})"
            )
        if self.relevant_time is None:
            return (
                "unavoidable: the pedestrian was never visible and in the car's way before "
                f"the contact ({self.standard})"
            )
        when = f"a hazard at t={self.relevant_time:.2f} s, braking from {self.brake_time:.2f} s"
        if self.avoidable and self.gap < 0:
            return f"avoidable: {when} lets the pedestrian cross first ({self.standard})"
        if self.avoidable:
            return f"avoidable: {when} stops {self.gap:.2f} m short ({self.standard})"
        return f"unavoidable: {when} still hits at {-self.gap / KMH:.1f} km/h ({self.standard})"


def _overlap(
    a0: NDArray[np.float64],
    a1: NDArray[np.float64],
    b0: NDArray[np.float64] | float,
    b1: NDArray[np.float64] | float,
) -> NDArray[np.bool_]:
    """Open-interval overlap of ``[a0, a1]`` and ``[b0, b1]`` (element-wise)."""
    return (a0 < b1) & (b0 < a1)


def _segments_cross_box(
    x0: NDArray[np.float64],
    y0: NDArray[np.float64],
    x1: NDArray[np.float64],
    y1: NDArray[np.float64],
    box: tuple[float, float, float, float],
) -> NDArray[np.bool_]:
    """Whether segments ``(x0, y0) -> (x1, y1)`` pass through the axis-aligned ``box``
    ``(s_low, s_high, d_low, d_high)`` (Liang-Barsky clipping, vectorised)."""
    low = np.zeros_like(x0)
    high = np.ones_like(x0)
    for delta, start, lo, hi in (
        (x1 - x0, x0, box[0], box[1]),
        (y1 - y0, y0, box[2], box[3]),
    ):
        moving = np.abs(delta) > 1e-12
        with np.errstate(divide="ignore", invalid="ignore"):
            t_a = np.where(moving, (lo - start) / delta, -np.inf)
            t_b = np.where(moving, (hi - start) / delta, np.inf)
        enter, leave = np.minimum(t_a, t_b), np.maximum(t_a, t_b)
        # A segment parallel to this axis misses the box unless it lies within its slab.
        outside = ~moving & ((start < lo) | (start > hi))
        low = np.where(outside, 2.0, np.maximum(low, enter))
        high = np.minimum(high, leave)
    return low < high


def judge_avoidable(
    scenario: Scenario,
    *,
    relevance: Relevance = "carriageway",
    decision_time: float = 0.1,
) -> Judgement:
    """Could braking alone have avoided a collision in ``scenario``? (module docstring)

    Parameters
    ----------
    scenario : Scenario
    relevance : {"carriageway", "lane", "path"}
        When the pedestrian counts as in the car's way (module docstring).
    decision_time : float
        Seconds the car needs to confirm a hazard, besides its own sensor latency and
        brake delay (``scenario.vehicle``).
    """
    if not isinstance(scenario, Scenario):
        raise InvalidArgument(f"scenario={scenario!r} must be a Scenario")
    if relevance not in RELEVANCE_STANDARDS:
        raise InvalidArgument(f"relevance={relevance!r} must be one of {list(RELEVANCE_STANDARDS)}")
    check_number(decision_time, "decision_time")
    vehicle = scenario.vehicle
    reaction = decision_time + vehicle.system_delay
    standard = (
        f"{relevance} standard, reaction {reaction:.2f} s, {vehicle.max_deceleration:g} m/s^2"
    )
    speed, start = scenario.ego_speed, scenario.ego_start_s
    t_end = max(scenario.time_to_collision_point, scenario.dummy_arrival) + _EXTRA_TIME
    times = np.arange(0.0, t_end + _STEP, _STEP)
    motion = scenario.pedestrian()
    ped_s, ped_d = motion.road_position(times)
    walk = _Walk(ped_s, ped_d, motion.extent_along_road / 2, motion.extent_across_road / 2)
    half_along, half_across = walk.half_along, walk.half_across
    path = scenario.ego_offset
    if relevance == "carriageway":
        road = scenario.road
        on_road = np.abs(ped_d) <= road.width / 2  # its centre: it has stepped onto the road
        lateral = np.gradient(ped_d, _STEP)
        in_way = on_road & (lateral * (path - ped_d) > 1e-3)
    elif relevance == "lane":
        lane_low, lane_high = scenario.road.lane_bounds(scenario.ego_lane)
        in_way = (ped_d >= lane_low) & (ped_d <= lane_high)  # its centre has stepped in
    else:
        half = vehicle.width / 2
        in_way = _overlap(ped_d - half_across, ped_d + half_across, path - half, path + half)
    cruise_front = start + speed * times
    visible = _visible(scenario, cruise_front, walk)
    hazard = np.flatnonzero(in_way & visible)
    first_visible = np.flatnonzero(visible)
    visible_time = float(times[first_visible[0]]) if len(first_visible) else None
    # The unbraked car's first contact bounds when a hazard still counts.
    contact = _contacts(scenario, cruise_front, walk)
    first_contact = int(np.argmax(contact)) if contact.any() else len(times)
    if not len(hazard) or hazard[0] >= first_contact:
        return Judgement(False, None, visible_time, None, -speed, standard)
    relevant = float(times[hazard[0]])
    brake = relevant + reaction
    braking = np.maximum(times - brake, 0.0)
    stop = speed / vehicle.max_deceleration
    tau = np.minimum(braking, stop)
    front = (
        start
        + speed * np.minimum(times, brake)
        + speed * tau
        - 0.5 * vehicle.max_deceleration * tau**2
    )
    velocity = np.where(
        times < brake, speed, np.maximum(speed - vehicle.max_deceleration * braking, 0.0)
    )
    moving = velocity > 1e-9
    hits = _contacts(scenario, front, walk) & moving
    if hits.any():
        return Judgement(
            False, relevant, visible_time, brake, -float(velocity[np.argmax(hits)]), standard
        )
    stopped = int(np.argmax(~moving)) if (~moving).any() else len(times) - 1
    gap = float(ped_s[stopped] - half_along - front[stopped])
    if gap < 0 and not _crossed_first(scenario, front, walk):
        # The braking car still reached the crossing before the pedestrian: it missed only
        # because it passed first, which braking cannot be credited with.
        return Judgement(False, relevant, visible_time, brake, 0.0, standard + ", passes first")
    return Judgement(True, relevant, visible_time, brake, gap, standard)


def _crossed_first(
    scenario: Scenario,
    front: NDArray[np.float64],
    walk: _Walk,
) -> bool:
    """Whether the pedestrian was clear beyond the car's path when the car reached its line."""
    ped_s, ped_d, half_along, half_across = walk
    reached = np.flatnonzero(front >= ped_s - half_along)
    direction = scenario.pedestrian().dd
    if not len(reached) or abs(direction) < 0.5:
        return True
    k, path, half = int(reached[0]), scenario.ego_offset, scenario.vehicle.width / 2
    if direction > 0:
        return bool(ped_d[k] - half_across >= path + half)
    return bool(ped_d[k] + half_across <= path - half)


def _contacts(
    scenario: Scenario,
    front: NDArray[np.float64],
    walk: _Walk,
) -> NDArray[np.bool_]:
    """Whether the car with its bumper at ``front`` overlaps the dummy, per sample."""
    ped_s, ped_d, half_along, half_across = walk
    vehicle, path = scenario.vehicle, scenario.ego_offset
    along = _overlap(front - vehicle.length, front, ped_s - half_along, ped_s + half_along)
    across = _overlap(
        ped_d - half_across, ped_d + half_across, path - vehicle.width / 2, path + vehicle.width / 2
    )
    return along & across


def _visible(
    scenario: Scenario,
    front: NDArray[np.float64],
    walk: _Walk,
) -> NDArray[np.bool_]:
    """Line of sight from the bumper's middle to the dummy's centre or a corner, per sample."""
    ped_s, ped_d, half_along, half_across = walk
    boxes = [
        (p.s - p.footprint.length / 2, p.s + p.footprint.length / 2,
         p.d - p.footprint.width / 2, p.d + p.footprint.width / 2)
        for p in scenario.obstructions()
    ]  # fmt: skip
    path = scenario.ego_offset
    seen = np.zeros(len(front), dtype=bool)
    for ds, dd in ((0, 0), (-1, -1), (-1, 1), (1, -1), (1, 1)):
        ts, td = ped_s + ds * half_along, ped_d + dd * half_across
        ahead = (ts > front) & (np.hypot(ts - front, td - path) <= JUDGE_RANGE)
        clear = ahead.copy()
        for box in boxes:
            clear &= ~_segments_cross_box(front, np.full_like(front, path), ts, td, box)
        seen |= clear
    return seen
