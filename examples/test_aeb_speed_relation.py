"""Metamorphic testing of an emergency-braking (AEB) function: Iqbal's speed relation.

Nobody can say exactly how an AEB should brake in every Euro NCAP pedestrian test on
every road, but one relation must hold: **if the car avoided the pedestrian, it still
avoids it when it drives at another speed** and the pedestrian is re-timed so that, without
braking, they would still meet at the same point. The only excuse is physics: a collision
that even full braking, from the moment the pedestrian became a hazard (visible, on the
carriageway, walking towards the car's path) and after the car's own delays, could not
have avoided; an independent judge decides that from the scenario alone
(``pytest_metamorphic.driving.judge.judge_avoidable``). Iqbal found with this relation
that an AEB assumed a 3.6 m lane on a 10 m road; the second test below shows it catching
exactly that fault.

Copy this file to test your own AEB: make ``my_aeb`` return your controller. It is
called every 10 ms with an :class:`~pytest_metamorphic.driving.kinematics.Observation`
(car speed, the car's real lane boundaries, and a ``Track`` per visible actor in road
coordinates relative to the front bumper) and returns a deceleration in m/s^2 (or a
``BrakeCommand``). A ``reset()`` method, if it has one, is called before every run.
To test on real streets, pass ``roads=[RoadGeometry.from_osm(r) for r in load_roads(...)]``
to ``aeb_scenarios``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import Phase, settings

from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic.driving.aeb import mutant_fixed_lane, reference_controller
from pytest_metamorphic.driving.kinematics import SimulationResult, simulate
from pytest_metamorphic.driving.scenario import Scenario
from pytest_metamorphic.driving.simulators import Controller
from pytest_metamorphic.relations.driving import speed_relation
from pytest_metamorphic.strategies import aeb_scenarios, straight_roads


def my_aeb() -> Controller:
    """A fresh instance of the AEB under test (replace with yours)."""
    return reference_controller()


# Crossing tests on straight roads 3.5-12 m wide at the protocol's speeds (10..60 km/h);
# follow-ups at any speed from 15 to 100 km/h.
SCENARIOS = aeb_scenarios(
    kinds=["CPNA-25", "CPNA-75", "CPNCO-50", "CPFA-50"],
    roads=straight_roads(min_width=3.5, max_width=12.0),
)
SPEED_MR = speed_relation(min_speed_kmh=15, max_speed_kmh=100)


def aeb_test(make_controller: Callable[[], Controller], **options: Any) -> Callable[[], None]:
    """The metamorphic test of one AEB; a factory so the faulty variant reuses it."""

    @settings(max_examples=40, database=None, deadline=None, **options)
    @metamorphic(source=SCENARIOS, relations=[SPEED_MR], followups=3)
    def check(scenario: Scenario) -> SimulationResult:
        return simulate(scenario, make_controller())

    return check


test_aeb_keeps_avoided_collisions_avoided = aeb_test(my_aeb)


def test_speed_relation_catches_a_hard_coded_lane_width() -> None:
    # Derandomized so the search is the same on every run; shrinking is left out to keep
    # the suite fast (see the slow test below for the shrunk counterexample).
    faulty = aeb_test(mutant_fixed_lane, derandomize=True, phases=[Phase.generate])
    with pytest.raises(MetamorphicViolation, match="avoided collision stays avoided") as info:
        faulty()
    verdict = info.value.verdict
    assert verdict is not None
    # Not a physics excuse: full braking would have stopped the car in time.
    assert "avoidable: a hazard at" in verdict.explanation
    (details,) = (d for name, d in verdict.details.items() if name.startswith("avoided"))
    assert details["physically_avoidable"] is True
    # The fault only matters where the real lane is wider than the assumed 3.6 m.
    assert info.value.followup.input.road.lane_width > 3.6


@pytest.mark.slow
def test_the_shrunk_counterexample_is_small() -> None:
    with pytest.raises(MetamorphicViolation) as info:
        aeb_test(mutant_fixed_lane, derandomize=True)()
    source = info.value.followup.input
    # Shrinking heads for the protocol's plain case: the 10 m test road, the lowest speed.
    assert source.road.width == 10.0 and source.road.lanes == 1
    assert info.value.source_output.scenario.ego_speed_kmh == 15
