"""The car's brakes in a simulation loop: an AEB's commands turned into applied
decelerations, and the trace a :class:`SimulationResult` records. Shared by every
simulator, so each applies commands the same way."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.kinematics.control import BrakeCommand, Observation
from pytest_metamorphic.driving.kinematics.results import Collision, SimulationResult
from pytest_metamorphic.driving.kinematics.sensor import Sensor
from pytest_metamorphic.driving.scenario import Scenario

__all__ = ["Brakes", "as_command", "loop_settings"]


def loop_settings(dt: Any, sensor: Sensor | None) -> tuple[float, Sensor]:
    """A simulation loop's step (seconds, in (0, 0.1]) and sensor (default ``Sensor()``)."""
    if isinstance(dt, bool) or not (
        isinstance(dt, (int, float)) and math.isfinite(dt) and 0 < dt <= 0.1
    ):
        raise InvalidArgument(f"dt={dt!r} must be in (0, 0.1] seconds")
    sensor = Sensor() if sensor is None else sensor
    if not isinstance(sensor, Sensor):
        raise InvalidArgument(f"sensor={sensor!r} must be a Sensor")
    return float(dt), sensor


def as_command(output: Any) -> BrakeCommand:
    """A controller's output as a :class:`BrakeCommand` (a number is a deceleration)."""
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


class Brakes:
    """Asks the controller each step, clips its request to the car's brakes, delays it by
    the car's ``brake_delay``, and records the step (time, speed, bumper position,
    applied deceleration, stage changes, first brake request).

    With a ``sensor_latency`` the controller is shown the observation made that many
    seconds earlier (the first one until then): the whole frame is old, the car's own
    speed included, as with a real perception stack.
    """

    def __init__(
        self,
        scenario: Scenario,
        controller: Callable[[Observation], float | BrakeCommand] | None,
        dt: float,
    ) -> None:
        self.scenario, self.controller = scenario, controller
        self.max_deceleration = scenario.vehicle.max_deceleration
        self.pending = [0.0] * round(scenario.vehicle.brake_delay / dt)
        self.latency_steps = round(scenario.vehicle.sensor_latency / dt)
        self.seen: list[Observation] = []
        self.times: list[float] = []
        self.speeds: list[float] = []
        self.positions: list[float] = []
        self.decelerations: list[float] = []
        self.stages: list[tuple[float, str]] = []
        self.first_brake: float | None = None
        self.braked = False

    def step(
        self, t: float, speed: float, position: float, observe: Callable[[], Observation]
    ) -> float:
        """The deceleration applied during the step that starts at ``t`` (m/s^2)."""
        command = BrakeCommand(0.0)
        if self.controller is not None:
            command = as_command(self.controller(self._delayed(observe)))
        if command.stage and (not self.stages or self.stages[-1][1] != command.stage):
            self.stages.append((round(t, 9), command.stage))
        requested = min(max(command.deceleration, 0.0), self.max_deceleration)
        if requested > 0 and self.first_brake is None:
            self.first_brake = t
        self.pending.append(requested)
        applied = self.pending.pop(0)
        self.braked = self.braked or applied > 0
        self.times.append(t)
        self.speeds.append(speed)
        self.positions.append(position)
        self.decelerations.append(applied)
        return applied

    def _delayed(self, observe: Callable[[], Observation]) -> Observation:
        if not self.latency_steps:
            return observe()
        self.seen.append(observe())
        if len(self.seen) > self.latency_steps + 1:
            self.seen.pop(0)
        return self.seen[0]

    def result(
        self, collision: Collision | None, end_time: float, final_speed: float, ego_s: float
    ) -> SimulationResult:
        return SimulationResult(
            scenario=self.scenario,
            collision=collision,
            end_time=round(end_time, 9),
            final_speed=final_speed,
            ego_s=ego_s,
            first_brake_time=self.first_brake,
            stages=tuple(self.stages),
            times=np.asarray(self.times),
            speeds=np.asarray(self.speeds),
            positions=np.asarray(self.positions),
            decelerations=np.asarray(self.decelerations),
        )
