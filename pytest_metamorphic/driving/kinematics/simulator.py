"""The fixed-step simulator: :func:`simulate` runs a controller through a scenario until
contact, standstill or the end.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.kinematics.brakes import Brakes, loop_settings
from pytest_metamorphic.driving.kinematics.control import BrakeCommand, Observation, Track
from pytest_metamorphic.driving.kinematics.geometry import Box, Point, _centre, _corners, _overlap
from pytest_metamorphic.driving.kinematics.results import Collision, SimulationResult
from pytest_metamorphic.driving.kinematics.sensor import Sensor
from pytest_metamorphic.driving.scenario import Footprint, PedestrianMotion, Scenario

__all__ = ["simulate"]

_EXTRA_TIME = 5.0
_BISECTION_STEPS = 30
_STANDSTILL = 1e-9


class _Actor:
    """A pedestrian (state per step, precomputed) or a static actor."""

    def __init__(
        self,
        scenario: Scenario,
        name: str,
        kind: str,
        footprint: Footprint,
        times: NDArray[np.float64] | None,
        motion: PedestrianMotion | None = None,
        static: tuple[float, float] | None = None,
    ) -> None:
        self.scenario, self.name, self.kind = scenario, name, kind
        self.footprint, self.motion = footprint, motion
        if motion is not None:
            if times is None:
                raise ValueError("a moving actor needs the simulation's times")
            self.along, self.across = motion.extent_along_road, motion.extent_across_road
            # Crossing dummies face across the road, longitudinal ones along it.
            self.turn = motion.facing
            s, d = motion.road_position(times)
            speed = motion.velocity(times)
            self.s, self.d = s.tolist(), d.tolist()
            self.vs, self.vd = (speed * motion.ds).tolist(), (speed * motion.dd).tolist()
            self.boxes: list[Box] = [self.box_at(a, b) for a, b in zip(self.s, self.d, strict=True)]
        else:
            assert static is not None
            self.along, self.across, self.turn = footprint.length, footprint.width, 0.0
            self.s, self.d, self.vs, self.vd = [static[0]], [static[1]], [0.0], [0.0]
            self.boxes = [self.box_at(*static)]

    def box_at(self, s: float, d: float) -> Box:
        x, y, heading = self.scenario.road.point(s, d)
        return _corners(x, y, heading + self.turn, self.footprint.length, self.footprint.width)

    def state(self, k: int) -> tuple[float, float, float, float, Box]:
        """``(s, d, vs, vd, box)`` at step ``k``."""
        i = 0 if self.motion is None else k
        return self.s[i], self.d[i], self.vs[i], self.vd[i], self.boxes[i]

    def box_at_time(self, t: float) -> tuple[float, Box]:
        """``(s, box)`` at any time (used inside a step)."""
        if self.motion is None:
            return self.s[0], self.boxes[0]
        s, d = self.motion.road_position(t)
        return float(s), self.box_at(float(s), float(d))


def _actors(scenario: Scenario, times: NDArray[np.float64]) -> list[_Actor]:
    motion = scenario.pedestrian()
    actors = [_Actor(scenario, "pedestrian", "pedestrian", motion.footprint, times, motion)]
    for index, parked in enumerate(scenario.obstructions()):
        actors.append(
            _Actor(
                scenario, f"parked car {index + 1}", "vehicle", parked.footprint, None,
                static=(parked.s, parked.d),
            )
        )  # fmt: skip
    return actors


def _ego_pose(scenario: Scenario, front_s: float) -> tuple[Box, Point, float]:
    """Corners of the car, its bumper centre and heading, with the bumper at ``front_s``."""
    vehicle, road = scenario.vehicle, scenario.road
    centre_s = front_s - vehicle.length / 2
    heading = road.chord_heading(centre_s, vehicle.wheelbase)
    cx, cy, _ = road.point(centre_s, scenario.ego_offset)
    half = vehicle.length / 2
    bumper = (cx + half * math.cos(heading), cy + half * math.sin(heading))
    return _corners(cx, cy, heading, vehicle.length, vehicle.width), bumper, heading


def _advance(s: float, v: float, a: float, tau: float) -> tuple[float, float]:
    """Exact constant-deceleration motion for ``tau`` seconds (never reverses)."""
    if a <= 0:
        return s + v * tau, v
    stop = v / a
    if tau >= stop:
        return s + v * v / (2 * a), 0.0
    return s + v * tau - 0.5 * a * tau * tau, v - a * tau


def _classify(ego: Box, heading: float, other: Box) -> tuple[str, str | None]:
    """Which face of the car ``other`` touches: the axis of least overlap decides."""
    cx, cy = _centre(ego)
    axes = ((math.cos(heading), math.sin(heading)), (-math.sin(heading), math.cos(heading)))
    penetration = []
    for ax, ay in axes:
        half = max(abs((x - cx) * ax + (y - cy) * ay) for x, y in ego)
        proj = [(x - cx) * ax + (y - cy) * ay for x, y in other]
        if sum(proj) >= 0:
            penetration.append((half - min(proj), 1))
        else:
            penetration.append((max(proj) + half, -1))
    (pen_x, sign_x), (pen_y, sign_y) = penetration
    if pen_x <= pen_y + 1e-9:
        return ("front" if sign_x > 0 else "rear"), None
    return "side", ("left" if sign_y > 0 else "right")


def simulate(
    scenario: Scenario,
    controller: Callable[[Observation], float | BrakeCommand] | None = None,
    *,
    dt: float = 0.01,
    sensor: Sensor | None = None,
) -> SimulationResult:
    """Run ``scenario`` with ``controller`` in the loop.

    Parameters
    ----------
    scenario : Scenario
    controller : callable(Observation) -> float or BrakeCommand, optional
        The AEB function (None: no braking at all). Its ``reset()`` is called first.
    dt : float
        Fixed step in seconds (controller rate and integration step), at most 0.1.
    sensor : Sensor, optional
        Default ``Sensor()``: 100 m, 180 degrees, with occlusion.

    Returns
    -------
    SimulationResult
    """
    if not isinstance(scenario, Scenario):
        raise InvalidArgument(f"scenario={scenario!r} must be a Scenario")
    if controller is not None and not callable(controller):
        raise InvalidArgument(f"controller={controller!r} must be callable(observation)")
    dt, sensor = loop_settings(dt, sensor)
    reset = getattr(controller, "reset", None)
    if callable(reset):
        reset()
    return _Run(scenario, controller, dt, sensor).run()


class _Run:
    def __init__(
        self,
        scenario: Scenario,
        controller: Callable[[Observation], float | BrakeCommand] | None,
        dt: float,
        sensor: Sensor,
    ) -> None:
        self.scenario = scenario
        self.controller = controller
        self.dt = dt
        self.sensor = sensor
        # Long enough for the car to reach the collision point and for the dummy to walk
        # there (later than the car when a follow-up keeps the dummy's own timing).
        self.t_end = max(scenario.time_to_collision_point, scenario.dummy_arrival) + _EXTRA_TIME
        self.steps = math.ceil(self.t_end / dt)
        self.times = np.arange(self.steps + 1, dtype=np.float64) * dt
        self.actors = _actors(scenario, self.times)
        road, vehicle = scenario.road, scenario.vehicle
        lane_right, lane_left = road.lane_bounds(scenario.ego_lane)
        offset = scenario.ego_offset
        self.lane = (lane_right - offset, lane_left - offset)
        self.edges = (-road.width / 2 - offset, road.width / 2 - offset)
        # Beyond this centre-to-centre distance along the road no contact is possible.
        self.reach = (vehicle.length + max(a.along for a in self.actors)) / 2 + vehicle.width

    # -- per-step pieces ---------------------------------------------------------------
    def _observe(self, t: float, k: int, front_s: float, v: float) -> Observation:
        _, bumper, heading = _ego_pose(self.scenario, front_s)
        states = [actor.state(k) for actor in self.actors]
        tracks = []
        for index, (actor, (s, d, vs, vd, box)) in enumerate(zip(self.actors, states, strict=True)):
            occluders = [state[4] for j, state in enumerate(states) if j != index]
            if not self.sensor.sees(bumper, heading, box, occluders):
                continue
            tracks.append(
                Track(index, actor.kind, s - front_s, d - self.scenario.ego_offset,
                      vs, vd, actor.along, actor.across)
            )  # fmt: skip
        vehicle = self.scenario.vehicle
        return Observation(
            t, self.dt, v, vehicle.length, vehicle.width, *self.lane, *self.edges, tuple(tracks),
            max_deceleration=vehicle.max_deceleration, system_delay=vehicle.system_delay,
        )  # fmt: skip

    def _contact(self, front_s: float, t: float, k: int | None) -> tuple[_Actor, Box] | None:
        centre_s = front_s - self.scenario.vehicle.length / 2
        ego: Box | None = None
        for actor in self.actors:
            if k is None:
                s, box = actor.box_at_time(t)
            else:
                s, _, _, _, box = actor.state(k)
            if abs(s - centre_s) > self.reach:
                continue
            if ego is None:
                ego = _ego_pose(self.scenario, front_s)[0]
            if _overlap(ego, box):
                return actor, box
        return None

    def _passed_everyone(self, front_s: float, k: int) -> bool:
        rear = front_s - self.scenario.vehicle.length
        return all(
            rear > actor.s[k] + actor.along / 2 + 0.5
            for actor in self.actors
            if actor.motion is not None
        )

    # -- main loop ---------------------------------------------------------------------
    def run(self) -> SimulationResult:
        scenario, dt = self.scenario, self.dt
        s, v = scenario.ego_start_s, scenario.ego_speed
        brakes = Brakes(scenario, self.controller, dt)
        collision: Collision | None = None
        t = 0.0
        if (hit := self._contact(s, t, 0)) is not None:
            collision = self._collision(hit, t, s, v)
        for k in range(self.steps if collision is None else 0):
            t = float(self.times[k])
            applied = brakes.step(t, v, s, lambda: self._observe(t, k, s, v))  # noqa: B023
            s_next, v_next = _advance(s, v, applied, dt)
            t_next = float(self.times[k + 1])
            if (hit := self._contact(s_next, t_next, k + 1)) is not None:
                tau = self._refine(s, v, applied, t)
                s, v = _advance(s, v, applied, tau)
                t += tau
                collision = self._collision(self._contact(s, t, None) or hit, t, s, v)
                break
            s, v, t = s_next, v_next, t_next
            # Euro NCAP ends a test when the car stands still: a dummy that walks into the
            # standing car afterwards is not a collision of the car.
            if (brakes.braked and v <= _STANDSTILL) or self._passed_everyone(s, k + 1):
                break
        return brakes.result(collision, t, v, s)

    def _refine(self, s: float, v: float, a: float, t: float) -> float:
        """Earliest contact time within the step (bisection; the motion is analytic)."""
        lo, hi = 0.0, self.dt
        for _ in range(_BISECTION_STEPS):
            mid = (lo + hi) / 2
            if self._contact(_advance(s, v, a, mid)[0], t + mid, None) is None:
                lo = mid
            else:
                hi = mid
        return hi

    def _collision(self, hit: tuple[_Actor, Box], t: float, s: float, v: float) -> Collision:
        actor, box = hit
        ego, _, heading = _ego_pose(self.scenario, s)
        location, side = _classify(ego, heading, box)
        return Collision(round(t, 9), actor.name, location, side, v, s)  # type: ignore[arg-type]
