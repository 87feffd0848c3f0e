"""Run AEB scenarios in highway-env (Farama Foundation), an open-source simulator on PyPI.

highway-env (``pip install 'pytest-metamorphic[highway-env]'``) supplies the physics the
car is tested in: its ``ControlledVehicle`` (kinematic bicycle model, Euler-integrated)
keeps the car in its lane with highway-env's own steering controller, the AEB under test
sets the acceleration, and highway-env's ``Road.step`` moves everything and finds
contacts with its polygon intersection test. What highway-env has no model for is
scripted as in any OpenSCENARIO player: the Euro NCAP dummy walks the protocol's path
(uniform acceleration, then constant speed) and the parked cars are ``Obstacle`` objects.
The AEB sees ground-truth tracks of the actors (highway-env's positions), limited by the
same :class:`~pytest_metamorphic.driving.kinematics.Sensor` as in the built-in simulator,
or, with ``visibility="lidar"``, by highway-env's own ``LidarObservation``: an actor is
seen when it is the nearest return in at least one of the lidar's sectors within the
sensor's range and field of view (rays from the front bumper). With the ideal car (no
brake delay, no latency) the AEB's command then acts at once, as highway-env's vehicles
do, and only the dummy's scripted walk and the collision face labels are ours.

Differences from the built-in simulator, all highway-env's: Euler steps (the built-in
one integrates exactly and finds the contact time by bisection), a car body turned by a
bicycle model on curved streets, and contacts found at step ends (a contact is reported
up to one step late, with the speed then).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.kinematics import (
    BrakeCommand,
    Collision,
    Observation,
    Sensor,
    SimulationResult,
    Track,
)
from pytest_metamorphic.driving.kinematics.brakes import Brakes, loop_settings
from pytest_metamorphic.driving.kinematics.geometry import Box
from pytest_metamorphic.driving.kinematics.simulator import _classify
from pytest_metamorphic.driving.scenario import PedestrianMotion, Scenario

__all__ = ["HighwayEnvSimulator"]

_INSTALL = "pip install 'pytest-metamorphic[highway-env]'"
_EXTRA_TIME = 5.0
_STANDSTILL = 1e-6
_PATH_STEP = 2.0  # metres between the vertices of the lane the car follows
_LANE_BEYOND = 60.0  # metres of lane beyond the collision point


def _highway_env() -> Any:
    # pygame (a highway-env dependency) greets on import unless told not to.
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        from highway_env.road import lane, road
        from highway_env.vehicle import controller, kinematics, objects
    except ImportError:
        raise InvalidArgument(f"HighwayEnvSimulator needs highway-env: {_INSTALL}") from None
    return lane, road, controller, kinematics, objects


class HighwayEnvSimulator:
    """A :data:`~pytest_metamorphic.driving.simulators.Simulator` backed by highway-env.

    Parameters
    ----------
    dt : float
        Step in seconds (the AEB's rate and highway-env's integration step), at most 0.1.
    sensor : Sensor, optional
        Default ``Sensor()``: 100 m, 180 degrees, with occlusion.
    visibility : {"sensor", "lidar"}
        ``"sensor"``: the sensor's line-of-sight test, as in the built-in simulator.
        ``"lidar"``: highway-env's ``LidarObservation`` decides what is hidden (range and
        field of view still from ``sensor``).
    lidar_cells : int
        The lidar's angular sectors over 360 degrees (1440: 0.25 degrees; a crossing
        child, 0.7 m wide as the car sees it, spans more than one sector anywhere within
        the sensor's 100 m, so some sector's ray meets it).

    Examples
    --------
    >>> simulator = HighwayEnvSimulator()                          # doctest: +SKIP
    >>> result = simulator(euro_ncap("CPNA-25"), reference_controller())  # doctest: +SKIP
    """

    def __init__(
        self,
        *,
        dt: float = 0.01,
        sensor: Sensor | None = None,
        visibility: Literal["sensor", "lidar"] = "sensor",
        lidar_cells: int = 1440,
    ) -> None:
        self.dt, self.sensor = loop_settings(dt, sensor)
        if visibility not in ("sensor", "lidar"):
            raise InvalidArgument(f"visibility={visibility!r} must be 'sensor' or 'lidar'")
        if isinstance(lidar_cells, bool) or not isinstance(lidar_cells, int) or lidar_cells < 4:
            raise InvalidArgument(f"lidar_cells={lidar_cells!r} must be an int >= 4")
        self.visibility, self.lidar_cells = visibility, lidar_cells
        self.modules = _highway_env()

    def __repr__(self) -> str:
        lidar = f", visibility='lidar', lidar_cells={self.lidar_cells}"
        return f"HighwayEnvSimulator(dt={self.dt:g}{lidar if self.visibility == 'lidar' else ''})"

    def __call__(
        self,
        scenario: Scenario,
        controller: Callable[[Observation], float | BrakeCommand] | None,
    ) -> SimulationResult:
        if not isinstance(scenario, Scenario):
            raise InvalidArgument(f"scenario={scenario!r} must be a Scenario")
        reset = getattr(controller, "reset", None)
        if callable(reset):
            reset()
        return _Run(self, scenario, controller).run()


class _Run:
    def __init__(
        self,
        simulator: HighwayEnvSimulator,
        scenario: Scenario,
        controller: Callable[[Observation], float | BrakeCommand] | None,
    ) -> None:
        lane_module, road_module, controller_module, kinematics, objects = simulator.modules
        # The AEB sets the acceleration itself: the plain vehicle's act(), not the
        # controlled vehicle's cruise control.
        self.act = kinematics.Vehicle.act
        self.scenario, self.controller = scenario, controller
        self.dt, self.sensor = simulator.dt, simulator.sensor
        road, vehicle = scenario.road, scenario.vehicle
        self.network = road_module.RoadNetwork()
        self.network.add_lane("start", "end", self._ego_lane(lane_module))
        self.road = road_module.Road(network=self.network)
        centre_s = scenario.ego_start_s - vehicle.length / 2
        x, y, heading = road.point(centre_s, scenario.ego_offset)
        self.car = controller_module.ControlledVehicle(
            self.road, [x, y], heading=heading, speed=scenario.ego_speed
        )
        _resize(self.car, vehicle.length, vehicle.width)
        self.motion = scenario.pedestrian()
        self.dummy = _Dummy(kinematics.Vehicle, self.road, scenario, self.motion)
        self.road.vehicles = [self.car, self.dummy.vehicle]
        self.parked = []
        for parked in scenario.obstructions():
            px, py, ph = road.point(parked.s, parked.d)
            obstacle = objects.Obstacle(self.road, [px, py], heading=ph)
            _resize(obstacle, parked.footprint.length, parked.footprint.width)
            self.parked.append((obstacle, parked))
        self.road.objects = [obstacle for obstacle, _ in self.parked]
        self.lidar = (
            _Lidar(self.road, self.car, simulator.sensor, simulator.lidar_cells)
            if simulator.visibility == "lidar"
            else None
        )
        lane_right, lane_left = road.lane_bounds(scenario.ego_lane)
        offset = scenario.ego_offset
        self.lane = (lane_right - offset, lane_left - offset)
        self.edges = (-road.width / 2 - offset, road.width / 2 - offset)
        self.t_end = max(scenario.time_to_collision_point, scenario.dummy_arrival) + _EXTRA_TIME

    def _ego_lane(self, lane_module: Any) -> Any:
        """highway-env's lane along the car's path (its steering controller follows it)."""
        scenario = self.scenario
        road = scenario.road
        width = road.lane_width
        first = min(scenario.ego_start_s - scenario.vehicle.length - 5.0, 0.0)
        if len(road.centerline) == 2:
            start = road.to_world(first, scenario.ego_offset)
            end = road.to_world(road.length + 50.0, scenario.ego_offset)
            return lane_module.StraightLane(start, end, width=width)
        # Only the stretch the car can drive in this run: highway-env's polyline lanes
        # project a point by scanning every vertex.
        last = scenario.conflict_s + _LANE_BEYOND
        s = np.arange(first, last + _PATH_STEP, _PATH_STEP)
        points = road.to_world(s, np.full_like(s, scenario.ego_offset))
        return lane_module.PolyLaneFixedWidth(points.tolist(), width=width)

    # -- per step -------------------------------------------------------------------
    def _bumper(self) -> tuple[tuple[float, float], float]:
        half = self.scenario.vehicle.length / 2
        heading = float(self.car.heading)
        x, y = self.car.position
        return (x + half * math.cos(heading), y + half * math.sin(heading)), heading

    def _front_s(self) -> float:
        bumper, _ = self._bumper()
        s, _ = self.scenario.road.to_frenet(np.asarray(bumper))
        return float(s)

    def _observe(self, t: float, front_s: float) -> Observation:
        road, offset = self.scenario.road, self.scenario.ego_offset
        bumper, heading = self._bumper()
        actors = [(self.dummy.vehicle, "pedestrian", self.dummy.along, self.dummy.across)]
        actors += [(obstacle, "vehicle", p.footprint.length, p.footprint.width)
                   for obstacle, p in self.parked]  # fmt: skip
        boxes = [_box(actor) for actor, *_ in actors]
        vs, vd = self.dummy.road_velocity(t)
        if self.lidar is not None:
            self.lidar.scan(bumper, heading, [actor for actor, *_ in actors])
        tracks = []
        for index, (actor, kind, along, across) in enumerate(actors):
            if self.lidar is not None:
                if not self.lidar.sees(actor):
                    continue
            else:
                occluders = [other for j, other in enumerate(boxes) if j != index]
                if not self.sensor.sees(bumper, heading, boxes[index], occluders):
                    continue
            s, d = road.to_frenet(np.asarray(actor.position))
            velocity = (vs, vd) if index == 0 else (0.0, 0.0)
            tracks.append(
                Track(index, kind, float(s) - front_s, float(d) - offset, *velocity, along, across)
            )
        vehicle = self.scenario.vehicle
        return Observation(
            t, self.dt, float(self.car.speed), vehicle.length, vehicle.width,
            *self.lane, *self.edges, tuple(tracks),
            max_deceleration=vehicle.max_deceleration, system_delay=vehicle.system_delay,
        )  # fmt: skip

    def _collision(self, t: float, front_s: float) -> Collision | None:
        if not self.car.crashed:
            return None
        hit = [(self.dummy.vehicle, "pedestrian")]
        hit += [(obstacle, f"parked car {i}") for i, (obstacle, _) in enumerate(self.parked, 1)]
        actor, name = next(((a, n) for a, n in hit if a.crashed), hit[0])
        location, side = _classify(_box(self.car), float(self.car.heading), _box(actor))
        return Collision(round(t, 9), name, location, side, float(self.car.speed), front_s)  # type: ignore[arg-type]

    def _passed_everyone(self, front_s: float) -> bool:
        rear = front_s - self.scenario.vehicle.length
        s, _ = self.scenario.road.to_frenet(np.asarray(self.dummy.vehicle.position))
        return rear > float(s) + self.dummy.along / 2 + 0.5

    # -- main loop ------------------------------------------------------------------
    def run(self) -> SimulationResult:
        dt = self.dt
        brakes = Brakes(self.scenario, self.controller, dt)
        collision: Collision | None = None
        t, front_s = 0.0, self._front_s()
        for k in range(math.ceil(self.t_end / dt)):
            t = k * dt
            speed = float(self.car.speed)
            applied = brakes.step(t, speed, front_s, lambda: self._observe(t, front_s))  # noqa: B023
            # Brakes stop the car; they never drive it backwards.
            acceleration = -min(applied, speed / dt)
            limit = self.car.MAX_STEERING_ANGLE
            steering = self.car.steering_control(self.car.target_lane_index)
            steering = float(np.clip(steering, -limit, limit))
            self.act(self.car, {"steering": steering, "acceleration": acceleration})
            self.road.step(dt)
            self.dummy.advance(t + dt)
            t += dt
            front_s = self._front_s()
            collision = self._collision(t, front_s)
            if collision is not None:
                break
            if (brakes.braked and self.car.speed <= _STANDSTILL) or self._passed_everyone(front_s):
                break
        return brakes.result(collision, t, max(float(self.car.speed), 0.0), front_s)


class _Dummy:
    """The Euro NCAP dummy as a highway-env vehicle that walks the protocol's path."""

    def __init__(
        self, vehicle_class: Any, road: Any, scenario: Scenario, motion: PedestrianMotion
    ) -> None:
        self.scenario, self.motion = scenario, motion
        self.along, self.across = motion.extent_along_road, motion.extent_across_road
        # A crossing dummy faces across the road, a longitudinal one along it.
        self.turn = motion.facing
        x, y, heading = self._pose(0.0)
        self.vehicle = vehicle_class(road, [x, y], heading=heading, speed=0.0)
        _resize(self.vehicle, motion.footprint.length, motion.footprint.width)
        # highway-env steps every vehicle; this one is moved by advance() instead.
        self.vehicle.step = lambda dt: None
        self.advance(0.0)

    def _pose(self, t: float) -> tuple[float, float, float]:
        s, d = self.motion.road_position(t)
        x, y, heading = self.scenario.road.point(float(s), float(d))
        return x, y, heading + self.turn

    def advance(self, t: float) -> None:
        x, y, heading = self._pose(t)
        self.vehicle.position = np.array([x, y], dtype=np.float64)
        self.vehicle.heading = heading
        self.vehicle.speed = float(self.motion.velocity(t))

    def road_velocity(self, t: float) -> tuple[float, float]:
        speed = float(self.motion.velocity(t))
        return speed * self.motion.ds, speed * self.motion.dd


class _Lidar:
    """Visibility by highway-env's ``LidarObservation`` (its ray-rectangle distances).

    Each actor is traced alone; its trace's grid is what the whole road's trace writes
    for it (``trace`` keeps, per sector, the nearest return of any obstacle), so the
    scene's nearest returns are the minimum over the actors, at half the cost of tracing
    the road as well. An actor is seen when, in some sector whose direction lies in the
    sensor's field of view, it is within range and no other actor's return is nearer.
    """

    def __init__(self, road: Any, observer: Any, sensor: Sensor, cells: int) -> None:
        from highway_env.envs.common.observation import LidarObservation

        self.observer, self.range = observer, float(sensor.range)
        self.half_fov = math.radians(sensor.field_of_view) / 2
        # LidarObservation reads env.road (vehicles and objects) and env.vehicle (the
        # observer) only: a road holding one actor at a time.
        self.alone = SimpleNamespace(vehicles=[], objects=[])
        self.lidar = LidarObservation(
            SimpleNamespace(road=self.alone, vehicle=observer),
            cells=cells,
            maximum_range=self.range,
            normalize=False,
        )
        self.directions = np.arange(cells) * (2 * math.pi / cells)  # each sector's centre
        self.returns: dict[int, NDArray[np.float32]] = {}
        self.nearest = np.full(cells, self.range, dtype=np.float32)
        self.ahead = np.zeros(cells, dtype=bool)

    def scan(self, origin: tuple[float, float], heading: float, actors: list[Any]) -> None:
        """Trace every actor from ``origin`` (the front bumper) looking along ``heading``."""
        position = np.asarray(origin, dtype=np.float64)
        self.returns = {}
        for actor in actors:
            self.alone.vehicles = [actor]
            grid = self.lidar.trace(position, self.observer.velocity)
            self.returns[id(actor)] = grid[:, 0].copy()
        self.nearest = np.min(list(self.returns.values()), axis=0)
        bearing = (self.directions - heading + math.pi) % (2 * math.pi) - math.pi
        self.ahead = np.abs(bearing) <= self.half_fov + 1e-9

    def sees(self, actor: Any) -> bool:
        own = self.returns[id(actor)]
        return bool(np.any(self.ahead & (own < self.range) & (own <= self.nearest)))


def _resize(actor: Any, length: float, width: float) -> None:
    """highway-env sizes objects by class attributes; ours differ per actor."""
    actor.LENGTH, actor.WIDTH = float(length), float(width)
    actor.diagonal = math.hypot(length, width)


def _box(actor: Any) -> Box:
    (x0, y0), (x1, y1), (x2, y2), (x3, y3) = actor.polygon()[:4]
    return (
        (float(x0), float(y0)),
        (float(x1), float(y1)),
        (float(x2), float(y2)),
        (float(x3), float(y3)),
    )
