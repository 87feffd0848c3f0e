"""Mutants that judge a cluster by its returns (lasers, ranges, reflectance, azimuth fill):
each is killed by the fault relation aimed at the fault that changes that property, on a
KITTI sweep where the reference keeps every obstacle (issue 26: power on faults nobody
wrote for it)."""

from __future__ import annotations

import math

import pytest

from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.faults import DropAzimuthBlock, DropRings, QuantizeRange
from pytest_metamorphic.lidar.followups.weather import Weather
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.relations.lidar import (
    adverse_weather,
    beam_loss,
    packet_loss,
    range_quantization,
)
from tests.core.lidar_cases import kitti

CASES = [
    # (mutant, sweep, fault, relation, the obstacle it loses)
    ("few_lasers_filter", 5, DropRings((60,)), beam_loss, "car at (53.4, -12.6) lost"),
    ("constant_range_filter", 0, QuantizeRange(0.2), range_quantization,
     "unknown at (14.3, -4.8) lost"),
    ("dim_cluster_filter", 5, Weather(50.0, "rain", 344), adverse_weather,
     "unknown at (14.9, 10.2) lost"),
    ("see_through_filter", 0, DropAzimuthBlock(math.radians(353.026), math.radians(1.04)),
     packet_loss, "unknown at (13.5, -0.8) lost"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("name", "sweep", "fault", "relation", "lost"), CASES, ids=[c[0] for c in CASES]
)
def test_the_fault_relation_aimed_at_the_property_kills_it(
    name, sweep, fault, relation, lost
) -> None:  # type: ignore[no-untyped-def]
    frame = kitti(sweep)
    followup = fault.apply(frame)
    context = CheckContext(frame, followup, fault.params(), 0)
    check = relation().relation
    faulty, reference = mutant(name), ReferencePerception()
    verdict = check.check(faulty(frame), faulty(followup), context)
    assert not verdict.holds and lost in verdict.explanation, verdict.explanation
    assert check.check(reference(frame), reference(followup), context).holds


def test_each_filter_drops_only_what_its_rule_names_on_a_complete_sweep() -> None:
    # On the sweep as recorded the filters keep the road users the reference finds within
    # 40 m (they drop clutter: single-laser ghosts, far shallow returns, dark debris).
    frame = kitti(0)
    near = [
        b
        for b in ReferencePerception()(frame)
        if b.label != "unknown" and math.hypot(*b.center[:2]) < 40
    ]
    assert near
    for name, *_ in CASES:
        kept = mutant(name)(frame)
        assert all(box in kept for box in near), name
