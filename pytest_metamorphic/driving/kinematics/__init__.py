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

Modules: :mod:`.control` (what a controller sees and returns), :mod:`.geometry`
(oriented boxes as plain floats), :mod:`.sensor`, :mod:`.results`, :mod:`.simulator`
(:func:`simulate`) and :mod:`.avoidability` (:func:`physically_avoidable`).
"""

from pytest_metamorphic.driving.kinematics.avoidability import Avoidability, physically_avoidable
from pytest_metamorphic.driving.kinematics.control import (
    BrakeCommand,
    Controller,
    Observation,
    Track,
    is_relevant,
    stopping_distance,
)
from pytest_metamorphic.driving.kinematics.results import Collision, SimulationResult
from pytest_metamorphic.driving.kinematics.sensor import Sensor
from pytest_metamorphic.driving.kinematics.simulator import simulate

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
