"""An AEB tested in a simulator we did not write: highway-env (Farama Foundation, PyPI).

A *simulator* is any callable ``simulator(scenario, controller) -> SimulationResult``
(:mod:`pytest_metamorphic.driving.simulators`). ``HighwayEnvSimulator`` runs each Euro
NCAP scenario in highway-env: its bicycle-model car keeps its lane with highway-env's own
steering controller, the AEB sets the acceleration, and highway-env's collision check
finds the contact. The relations are the same as with the built-in simulator; only the
system under test changes. To wire up your own simulator (esmini, CARLA, a HIL rig),
write the same kind of callable: take the scenario (or
``write_openscenario(scenario, folder)`` for tools that read OpenSCENARIO), run your
AEB in it and return the car's trajectory and the first collision as a
``SimulationResult``.

Needs ``pip install 'pytest-metamorphic[highway-env]'``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import Phase, settings

from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic.driving.aeb import mutant_fixed_lane, reference_controller
from pytest_metamorphic.driving.kinematics import SimulationResult
from pytest_metamorphic.driving.scenario import Scenario
from pytest_metamorphic.driving.simulators import Controller
from pytest_metamorphic.relations.driving import speed_relation
from pytest_metamorphic.strategies import aeb_scenarios, straight_roads

pytest.importorskip("highway_env", reason="needs the highway-env extra")
from pytest_metamorphic.driving.simulators.highway_env import HighwayEnvSimulator

SIMULATOR = HighwayEnvSimulator(dt=0.01)
SCENARIOS = aeb_scenarios(
    kinds=["CPNA-25", "CPNCO-50", "CPFA-50"],
    roads=straight_roads(min_width=3.5, max_width=12.0),
)
# The pedestrian re-timed to meet the car at its new speed; keep="pedestrian" is Iqbal's
# campaign follow-up (the car arrives early or late), whose violations lie in narrow
# speed bands that a campaign sweeps better than a random search.
SPEED_MR = speed_relation(min_speed_kmh=15, max_speed_kmh=100)


def aeb_in_highway_env(
    make_controller: Callable[[], Controller], *, max_examples: int = 15, **options: Any
) -> Callable[[], None]:
    @settings(max_examples=max_examples, database=None, deadline=None, **options)
    @metamorphic(source=SCENARIOS, relations=[SPEED_MR], followups=3)
    def check(scenario: Scenario) -> SimulationResult:
        return SIMULATOR(scenario, make_controller())

    return check


test_reference_aeb_in_highway_env = aeb_in_highway_env(
    reference_controller, derandomize=True, phases=[Phase.generate]
)


def test_highway_env_run_catches_the_hard_coded_lane_width() -> None:
    faulty = aeb_in_highway_env(
        mutant_fixed_lane, max_examples=25, derandomize=True, phases=[Phase.generate]
    )
    with pytest.raises(MetamorphicViolation, match="avoided collision stays avoided") as info:
        faulty()
    verdict = info.value.verdict
    assert verdict is not None
    (details,) = (d for name, d in verdict.details.items() if name.startswith("avoided"))
    # Not a physics excuse: full braking from the moment the pedestrian stepped onto the
    # road would have stopped the car.
    assert details["source_collided"] is False and details["followup_collided"] is True
    assert details["physically_avoidable"] is True
    assert info.value.followup.input.road.lane_width > 3.6
