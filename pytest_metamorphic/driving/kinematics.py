"""A fixed-step kinematic simulator for AEB pedestrian scenarios.

Model
-----
* **Car**: an oriented rectangle following the centre of its lane (point-mass longitudinal
  dynamics along the lane, body turned along the chord of its wheelbase on curved roads).
  Each step applies the commanded deceleration (clipped to ``[0, max_deceleration]``) after
  the vehicle's ``brake_delay``; within a step the motion is integrated exactly, so
  stopping distances match ``v * delay + v**2 / (2 a)`` to rounding.
* **Pedestrian**: an oriented box on the straight path derived by the scenario.
* **Parked cars**: fixed boxes; they hide what is behind them from the car's sensor.
* **Sensor**: at the middle of the front bumper; reports every actor within range and
  field of view that is not completely hidden behind another actor (line of sight to its
  centre or one of its corners), as a :class:`Track` in road coordinates relative to the car.
* **Controller**: anything called as ``controller(observation)`` returning a deceleration
  in m/s^2 (or a :class:`BrakeCommand`); ``controller.reset()`` is called before a run when
  it exists.

A run ends at the first contact (refined by bisection inside the step, so the impact time
and speed do not depend on the step size), when the car stands still after braking (as
in the protocol, a dummy walking on into a stopped car is no impact; dummies never
react), once the car has passed every pedestrian, or after ``time_to_collision_point + 5 s``.

Contacts are classified by the face of the car that was hit: ``front``, ``side`` (left or
right) or ``rear``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.scenario import KMH, Footprint, PedestrianMotion, Scenario

__all__ = [
    "Avoidability",
    "BrakeCommand",
    "Collision",
    "Controller",
    "Observation",
    "Sensor",
    "SimulationResult",
    "Track",
    "is_relevant",
    "physically_avoidable",
    "simulate",
    "stopping_distance",
]

_EXTRA_TIME = 5.0
_BISECTION_STEPS = 30
_STANDSTILL = 1e-9


def stopping_distance(speed: float, deceleration: float, delay: float = 0.0) -> float:
    """Closed form: ``speed * delay + speed**2 / (2 * deceleration)`` (metres)."""
    if deceleration <= 0:
        raise InvalidArgument(f"deceleration={deceleration!r} must be > 0")
    return speed * delay + speed**2 / (2 * deceleration)


# ---------------------------------------------------------------------------------------
# What the controller sees and returns


@dataclass(frozen=True)
class Track:
    """One actor as the sensor reports it, relative to the car, in road coordinates.

    Attributes
    ----------
    id : int
    kind : {"pedestrian", "vehicle"}
    s : float
        Distance along the road from the car's front bumper to the actor's centre (m).
    d : float
        Lateral offset of the actor's centre from the car's path (m, left positive).
    vs, vd : float
        Actor velocity along / across the road (m/s, ground frame).
    length, width : float
        The actor's extent along / across the road (m).
    """

    id: int
    kind: str
    s: float
    d: float
    vs: float
    vd: float
    length: float
    width: float

    @property
    def moving(self) -> bool:
        return math.hypot(self.vs, self.vd) >= 0.1

    @property
    def headway(self) -> float:
        """Free distance from the bumper to the actor's near face, along the road."""
        return self.s - self.length / 2


@dataclass(frozen=True)
class Observation:
    """Everything a controller gets each step.

    Attributes
    ----------
    time : float
    dt : float
    ego_speed : float
        m/s.
    ego_length, ego_width : float
    lane_right, lane_left : float
        The car's lane boundaries from the map, relative to its path (m; right negative).
        A controller that uses them selects objects with the road's real geometry.
    road_right, road_left : float
        The carriageway's edges relative to the car's path (m).
    tracks : tuple of Track
    """

    time: float
    dt: float
    ego_speed: float
    ego_length: float
    ego_width: float
    lane_right: float
    lane_left: float
    road_right: float
    road_left: float
    tracks: tuple[Track, ...]


@dataclass(frozen=True)
class BrakeCommand:
    """A deceleration request (m/s^2, >= 0) and the controller's stage name, for traces."""

    deceleration: float
    stage: str = ""


@runtime_checkable
class Controller(Protocol):
    """An AEB function: observation in, deceleration (or :class:`BrakeCommand`) out."""

    def __call__(self, observation: Observation) -> float | BrakeCommand: ...


Region = Literal["lane", "road"]


def is_relevant(track: Track, observation: Observation, region: Region = "lane") -> bool:
    """The physical relevance rule (also the reference controller's object selection).

    An actor matters when it is moving (at 0.1 m/s or more, :attr:`Track.moving`) with its
    centre inside the car's real lane (``region="lane"``; ``"road"``: anywhere on the
    carriageway), or when it stands in the car's swept path (laterally overlapping the
    car's body).
    """
    right, left = (
        (observation.lane_right, observation.lane_left)
        if region == "lane"
        else (observation.road_right, observation.road_left)
    )
    if track.moving and right <= track.d <= left:
        return True
    return abs(track.d) < (observation.ego_width + track.width) / 2


# ---------------------------------------------------------------------------------------
# Geometry helpers (plain floats: the simulator calls these a few thousand times per run)

Point = tuple[float, float]
Box = tuple[Point, Point, Point, Point]


def _corners(cx: float, cy: float, heading: float, length: float, width: float) -> Box:
    """Counter-clockwise corners: front-left, rear-left, rear-right, front-right."""
    c, s = math.cos(heading), math.sin(heading)
    hl, hw = length / 2, width / 2
    return (
        (cx + hl * c - hw * s, cy + hl * s + hw * c),
        (cx - hl * c - hw * s, cy - hl * s + hw * c),
        (cx - hl * c + hw * s, cy - hl * s - hw * c),
        (cx + hl * c + hw * s, cy + hl * s - hw * c),
    )


def _separated(a: Box, b: Box) -> bool:
    """Whether one of ``a``'s two edge directions separates the rectangles."""
    for (x0, y0), (x1, y1) in ((a[0], a[1]), (a[1], a[2])):
        nx, ny = y0 - y1, x1 - x0
        pa = [nx * x + ny * y for x, y in a]
        pb = [nx * x + ny * y for x, y in b]
        if max(pa) < min(pb) or max(pb) < min(pa):
            return True
    return False


def _overlap(a: Box, b: Box) -> bool:
    """Separating-axis test for two rectangles."""
    return not (_separated(a, b) or _separated(b, a))


def _segment_hits_box(p: Point, q: Point, box: Box) -> bool:
    """Whether segment ``p``-``q`` passes through the rectangle (Liang-Barsky clipping)."""
    xs, ys = [c[0] for c in box], [c[1] for c in box]
    if (
        max(p[0], q[0]) < min(xs) or min(p[0], q[0]) > max(xs)
        or max(p[1], q[1]) < min(ys) or min(p[1], q[1]) > max(ys)
    ):  # fmt: skip
        return False
    t0, t1 = 0.0, 1.0
    dx, dy = q[0] - p[0], q[1] - p[1]
    for i in range(4):
        (cx, cy), (ex, ey) = box[i], box[(i + 1) % 4]
        nx, ny = ey - cy, -(ex - cx)  # outward normal of a counter-clockwise edge
        denom = nx * dx + ny * dy
        num = nx * (cx - p[0]) + ny * (cy - p[1])
        if abs(denom) < 1e-12:
            if num < 0:
                return False
            continue
        t = num / denom
        if denom < 0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
        if t0 > t1:
            return False
    # Grazing an occluder's edge does not hide anything.
    return t1 - t0 > 1e-6


def _centre(box: Box) -> Point:
    return (sum(c[0] for c in box) / 4, sum(c[1] for c in box) / 4)


# ---------------------------------------------------------------------------------------
# Sensor


@dataclass(frozen=True)
class Sensor:
    """The car's object sensor (ground truth, limited by range, field of view and occlusion).

    Parameters
    ----------
    range : float
        Metres from the front bumper.
    field_of_view : float
        Full horizontal opening angle in degrees (180: everything ahead of the bumper).
    occlusion : bool
        Hide actors completely behind other actors (the parked cars of CPNCO).
    """

    range: float = 100.0
    field_of_view: float = 180.0
    occlusion: bool = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.range) and self.range > 0):
            raise InvalidArgument(f"Sensor range={self.range!r} must be > 0")
        if not 0 < self.field_of_view <= 360:
            raise InvalidArgument(
                f"Sensor field_of_view={self.field_of_view!r} must be in (0, 360] degrees"
            )

    def sees(self, origin: Point, heading: float, box: Box, occluders: Sequence[Box]) -> bool:
        """Whether ``box`` is visible from ``origin`` looking along ``heading`` (radians).

        Visible means: the box's centre or one of its corners is within range and field of
        view, with a line of sight that passes through no occluder.
        """
        half_fov = math.radians(self.field_of_view) / 2
        for point in (_centre(box), *box):
            dx, dy = point[0] - origin[0], point[1] - origin[1]
            if math.hypot(dx, dy) > self.range:
                continue
            bearing = (math.atan2(dy, dx) - heading + math.pi) % (2 * math.pi) - math.pi
            if abs(bearing) > half_fov + 1e-9:
                continue
            if not self.occlusion or not any(
                _segment_hits_box(origin, point, occluder) for occluder in occluders
            ):
                return True
        return False


# ---------------------------------------------------------------------------------------
# Results


@dataclass(frozen=True)
class Collision:
    """The first contact between the car and another actor.

    Attributes
    ----------
    time : float
        Seconds after the start.
    actor : str
        ``"pedestrian"`` or the parked car's name.
    location : {"front", "side", "rear"}
        The face of the car that was hit.
    side : {"left", "right"} or None
        For side contacts.
    impact_speed : float
        The car's speed at contact (m/s).
    ego_s : float
        Arc length of the front bumper at contact.
    """

    time: float
    actor: str
    location: Literal["front", "side", "rear"]
    side: Literal["left", "right"] | None
    impact_speed: float
    ego_s: float

    @property
    def impact_speed_kmh(self) -> float:
        return self.impact_speed / KMH

    def describe(self) -> str:
        where = self.location if self.side is None else f"{self.side} {self.location}"
        return (
            f"{where} collision with the {self.actor} at {self.impact_speed_kmh:.1f} km/h, "
            f"t={self.time:.2f} s"
        )


@dataclass(frozen=True)
class SimulationResult:
    """What happened in one run.

    Attributes
    ----------
    scenario : Scenario
    collision : Collision or None
    end_time : float
    final_speed : float
        m/s when the run ended.
    ego_s : float
        Front-bumper arc length when the run ended.
    first_brake_time : float or None
        First step with a non-zero deceleration command.
    stages : tuple of (time, stage)
        Every change of the controller's stage name.
    times, speeds, positions, decelerations : (n,) float64
        The trace (``positions`` = front-bumper arc length); not compared for equality.
    """

    scenario: Scenario
    collision: Collision | None
    end_time: float
    final_speed: float
    ego_s: float
    first_brake_time: float | None
    stages: tuple[tuple[float, str], ...]
    times: NDArray[np.float64] = field(compare=False, repr=False)
    speeds: NDArray[np.float64] = field(compare=False, repr=False)
    positions: NDArray[np.float64] = field(compare=False, repr=False)
    decelerations: NDArray[np.float64] = field(compare=False, repr=False)

    @property
    def collided(self) -> bool:
        return self.collision is not None

    @property
    def avoided(self) -> bool:
        return self.collision is None

    @property
    def impact_speed(self) -> float:
        """Impact speed in m/s, 0 when the collision was avoided."""
        return 0.0 if self.collision is None else self.collision.impact_speed

    @property
    def impact_speed_kmh(self) -> float:
        return self.impact_speed / KMH

    def describe(self) -> str:
        outcome = (
            self.collision.describe()
            if self.collision
            else f"avoided (car at {self.final_speed / KMH:.1f} km/h when the run ended)"
        )
        return f"{self.scenario.kind} at {self.scenario.ego_speed_kmh:g} km/h: {outcome}"


# ---------------------------------------------------------------------------------------
# The simulator


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
            self.along, self.across = motion.extent_along_road, motion.extent_across_road
            # Crossing dummies face across the road, longitudinal ones along it.
            self.turn = math.copysign(math.pi / 2, motion.dd) if abs(motion.dd) > 0.5 else 0.0
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


def _as_command(output: Any) -> BrakeCommand:
    if isinstance(output, BrakeCommand):
        command = output
    else:
        try:
            command = BrakeCommand(float(output))
        except (TypeError, ValueError):
            raise InvalidArgument(
                f"the controller returned {output!r}; it must return a deceleration in m/s^2 "
                "(float >= 0) or a BrakeCommand"
            ) from None
    if not math.isfinite(command.deceleration):
        raise InvalidArgument(f"the controller returned a non-finite deceleration {command}")
    return command


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
    if isinstance(dt, bool) or not (
        isinstance(dt, (int, float)) and math.isfinite(dt) and 0 < dt <= 0.1
    ):
        raise InvalidArgument(f"dt={dt!r} must be in (0, 0.1] seconds")
    sensor = Sensor() if sensor is None else sensor
    if not isinstance(sensor, Sensor):
        raise InvalidArgument(f"sensor={sensor!r} must be a Sensor")
    reset = getattr(controller, "reset", None)
    if callable(reset):
        reset()
    return _Run(scenario, controller, float(dt), sensor).run()


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
        self.t_end = scenario.time_to_collision_point + _EXTRA_TIME
        self.steps = math.ceil(self.t_end / dt)
        self.times = np.arange(self.steps + 1) * dt
        self.actors = _actors(scenario, self.times)
        road, vehicle = scenario.road, scenario.vehicle
        lane_right, lane_left = road.lane_bounds(scenario.ego_lane)
        offset = scenario.ego_offset
        self.lane = (lane_right - offset, lane_left - offset)
        self.edges = (-road.width / 2 - offset, road.width / 2 - offset)
        self.delay_steps = round(vehicle.brake_delay / dt)
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
            t, self.dt, v, vehicle.length, vehicle.width, *self.lane, *self.edges, tuple(tracks)
        )

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
        max_deceleration = scenario.vehicle.max_deceleration
        s, v = scenario.ego_start_s, scenario.ego_speed
        pending = [0.0] * self.delay_steps
        times: list[float] = []
        speeds: list[float] = []
        positions: list[float] = []
        decels: list[float] = []
        stages: list[tuple[float, str]] = []
        first_brake: float | None = None
        collision: Collision | None = None
        braked = False
        t = 0.0
        if (hit := self._contact(s, t, 0)) is not None:
            collision = self._collision(hit, t, s, v)
        for k in range(self.steps if collision is None else 0):
            t = float(self.times[k])
            command = BrakeCommand(0.0)
            if self.controller is not None:
                command = _as_command(self.controller(self._observe(t, k, s, v)))
            if command.stage and (not stages or stages[-1][1] != command.stage):
                stages.append((round(t, 9), command.stage))
            requested = min(max(command.deceleration, 0.0), max_deceleration)
            if requested > 0 and first_brake is None:
                first_brake = t
            pending.append(requested)
            applied = pending.pop(0)
            braked = braked or applied > 0
            times.append(t)
            speeds.append(v)
            positions.append(s)
            decels.append(applied)
            s_next, v_next = _advance(s, v, applied, dt)
            t_next = float(self.times[k + 1])
            if (hit := self._contact(s_next, t_next, k + 1)) is not None:
                tau = self._refine(s, v, applied, t)
                s, v = _advance(s, v, applied, tau)
                t += tau
                collision = self._collision(self._contact(s, t, None) or hit, t, s, v)
                break
            s, v, t = s_next, v_next, t_next
            if (braked and v <= _STANDSTILL) or self._passed_everyone(s, k + 1):
                break
        return SimulationResult(
            scenario=scenario,
            collision=collision,
            end_time=round(t, 9),
            final_speed=v,
            ego_s=s,
            first_brake_time=first_brake,
            stages=tuple(stages),
            times=np.asarray(times),
            speeds=np.asarray(speeds),
            positions=np.asarray(positions),
            decelerations=np.asarray(decels),
        )

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


# ---------------------------------------------------------------------------------------
# Physical avoidability


@dataclass(frozen=True)
class Avoidability:
    """Could the car have stopped in time?

    Attributes
    ----------
    avoidable : bool
    relevant_time : float or None
        When the pedestrian first became relevant (see :func:`physically_avoidable`);
        None if it never did before the contact.
    gap : float
        With ideal braking from then on: free distance left between the car and the
        pedestrian when the car stopped (negative: the impact speed in m/s with a minus
        sign, when even ideal braking collides).
    """

    avoidable: bool
    relevant_time: float | None
    gap: float

    def describe(self) -> str:
        if self.relevant_time is None:
            return "unavoidable: the pedestrian never became relevant before the contact"
        when = f"relevant at t={self.relevant_time:.2f} s"
        if self.avoidable:
            return f"avoidable: {when}, full braking stops {self.gap:.2f} m short"
        return f"unavoidable: {when}, full braking still hits at {-self.gap / KMH:.1f} km/h"


class _IdealBraking:
    """Full braking from the first step the pedestrian is relevant (+ ``slack``)."""

    def __init__(self, deceleration: float, slack: float, region: Region) -> None:
        self.deceleration = deceleration
        self.slack = slack
        self.region = region
        self.relevant_time: float | None = None

    def reset(self) -> None:
        self.relevant_time = None

    def __call__(self, observation: Observation) -> float:
        if self.relevant_time is None and any(
            track.kind == "pedestrian"
            and track.headway > -0.5
            and is_relevant(track, observation, self.region)
            for track in observation.tracks
        ):
            self.relevant_time = observation.time
        if (
            self.relevant_time is not None
            and observation.time >= self.relevant_time + self.slack - 1e-9
        ):
            return self.deceleration
        return 0.0


def physically_avoidable(
    scenario: Scenario,
    *,
    slack: float = 0.1,
    relevance: Region = "road",
    dt: float = 0.01,
    sensor: Sensor | None = None,
) -> Avoidability:
    """Whether a collision in ``scenario`` could have been avoided by braking alone.

    Definition: the pedestrian becomes *relevant* at the first moment it is visible to the
    car's sensor (not hidden by the parked cars) and either moving with its centre on the
    carriageway (from the road geometry; ``relevance="lane"``: only inside the car's own
    lane, a laxer standard for the car) or standing in the car's swept path.
    The collision is *physically avoidable* when the car, braking at its
    ``max_deceleration`` (after its ``brake_delay``) from ``slack`` seconds after that
    moment, stops or is overtaken without touching the pedestrian. ``slack`` absorbs one
    control step and the rounding of a fixed-step controller.
    """
    if not (isinstance(slack, (int, float)) and math.isfinite(slack) and slack >= 0):
        raise InvalidArgument(f"slack={slack!r} must be >= 0")
    if relevance not in ("lane", "road"):
        raise InvalidArgument(f"relevance={relevance!r} must be 'lane' or 'road'")
    ideal = _IdealBraking(scenario.vehicle.max_deceleration, slack, relevance)
    result = simulate(scenario, ideal, dt=dt, sensor=sensor)
    if ideal.relevant_time is None:
        return Avoidability(False, None, -result.impact_speed)
    if result.collision is not None:
        return Avoidability(False, ideal.relevant_time, -result.collision.impact_speed)
    motion = scenario.pedestrian()
    ped_s, _ = motion.road_position(result.end_time)
    gap = float(ped_s) - motion.extent_along_road / 2 - result.ego_s
    return Avoidability(True, ideal.relevant_time, gap)
