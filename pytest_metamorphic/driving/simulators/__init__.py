"""Simulators an AEB is tested in: the built-in fixed-step one, or one that lives elsewhere.

A *simulator* is any callable ``simulator(scenario, controller) -> SimulationResult``:
the :class:`~pytest_metamorphic.driving.scenario.Scenario` (road, car, dummy, parked cars,
all as parameters; :func:`~pytest_metamorphic.driving.openscenario.write_openscenario`
turns it into OpenSCENARIO/OpenDRIVE files for simulators that read those) goes in; the
car's trajectory and the first collision come out as a
:class:`~pytest_metamorphic.driving.kinematics.SimulationResult`. ``controller`` is the AEB
under test (``Observation -> deceleration``), or None for an AEB that lives inside the
simulator (then the simulator ignores it).

Everything downstream only reads the result: the speed relations
(:mod:`pytest_metamorphic.relations.driving`), Iqbal's campaign
(``iqbal_campaign(..., simulator=...)``), the artifacts. Physical avoidability, the
oracle's excuse, is always judged in the built-in simulator, so a simulator under test
cannot excuse itself.

Provided:

* :func:`builtin` -- :func:`~pytest_metamorphic.driving.kinematics.simulate`;
* :class:`~pytest_metamorphic.driving.simulators.highway_env.HighwayEnvSimulator` -- the
  scenario run in `highway-env <https://pypi.org/project/highway-env/>`_ (Farama): its
  kinematic bicycle model and lane-keeping steering drive the car, its polygon collision
  check finds the contact (extra ``highway-env``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.kinematics import (
    BrakeCommand,
    Observation,
    SimulationResult,
    simulate,
)
from pytest_metamorphic.driving.scenario import Scenario

__all__ = ["Simulator", "builtin", "check_simulator", "run_simulator"]

Controller = Callable[[Observation], "float | BrakeCommand"]
Simulator = Callable[[Scenario, "Controller | None"], SimulationResult]
"""``simulator(scenario, controller)`` -> :class:`SimulationResult` (``None``: no AEB)."""


def builtin(scenario: Scenario, controller: Controller | None) -> SimulationResult:
    """The built-in fixed-step simulator (10 ms steps, default sensor)."""
    return simulate(scenario, controller)


def check_simulator(simulator: Any) -> Simulator:
    """``simulator``, or :func:`builtin` for None; InvalidArgument when not callable."""
    if simulator is None:
        return builtin
    if not callable(simulator):
        raise InvalidArgument(
            f"simulator={simulator!r} must be callable(scenario, controller) -> SimulationResult"
        )
    return simulator


def run_simulator(
    simulator: Simulator, scenario: Scenario, controller: Controller | None
) -> SimulationResult:
    """One run; a simulator that returns something else is named."""
    result = simulator(scenario, controller)
    if not isinstance(result, SimulationResult):
        name = getattr(simulator, "__name__", type(simulator).__name__)
        raise InvalidArgument(
            f"simulator {name} returned {type(result).__name__}; it must return a "
            "SimulationResult (see pytest_metamorphic.driving.simulators)"
        )
    return result
