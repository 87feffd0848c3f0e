"""What became of an obstacle a violation blames (lidar/judging/fates.py), on boxes and
on the reference pipeline's own campaign."""

from __future__ import annotations

import pytest

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.judging.fates import FATES, obstacle_fates
from pytest_metamorphic.lidar.model.obstacles import Box


def box(x: float, y: float, length: float = 4.0, width: float = 2.0, label: str = "car") -> Box:
    return Box(center=(x, y, 0.0), size=(length, width, 1.5), yaw=0.0, label=label)  # type: ignore[arg-type]


A, B = box(10, 0), box(10, 2.5)


@pytest.mark.parametrize(
    ("followup", "fate"),
    [
        ([], "lost"),
        ([box(30, 0)], "lost"),  # something elsewhere does not explain it
        ([box(10, 1.25, width=4.5), B], "merged"),  # one box over both source cars
        ([box(9, 0, length=1.8), box(11, 0, length=1.8), B], "split"),
        ([box(10, 0, label="pedestrian"), B], "relabelled"),
        ([box(11.5, 0), B], "changed"),  # moved beyond the matcher's IoU
    ],
)
def test_each_fate(followup: list[Box], fate: str) -> None:
    assert obstacle_fates([A, B], followup, [0]) == [fate]
    assert fate in FATES


def test_a_merge_names_both_obstacles() -> None:
    assert obstacle_fates([A, B], [box(10, 1.25, width=4.5)], [0, 1]) == ["merged", "merged"]


def test_bad_indices_are_refused() -> None:
    with pytest.raises(InvalidArgument, match="index 2 is not one of the 2 source boxes"):
        obstacle_fates([A, B], [], [2])
    with pytest.raises(InvalidArgument, match="indices must be ints"):
        obstacle_fates([A, B], [], [True])


def test_a_lidar_campaign_counts_violations_by_fate() -> None:
    """The paper's campaign on the count_scaled_radius mutant: its violations (obstacles
    grouped differently when the sweep holds more points) are told apart by fate, the
    fates add up to the violations, and each blamed obstacle is named with its class."""
    from pytest_metamorphic.core.campaign import run_campaign
    from pytest_metamorphic.lidar.campaign import mr1_campaign
    from pytest_metamorphic.lidar.systems.perception.mutants import mutant

    faulty = mutant("count_scaled_radius")

    def system(frame):  # type: ignore[no-untyped-def]
        return faulty(frame.cloud, frame.roi)

    result = run_campaign(
        mr1_campaign(system, name="fates", sources=12, sizes=(1000,), scope="all")
    )
    counts = result.sizes[1000]
    assert counts.violations > 0
    assert sum(counts.fates.values()) == counts.violations
    assert set(counts.fates) <= set(FATES)
    for example in result.examples:
        assert example["violated"], example
        assert all(e["fate"] in FATES and e["category"] for e in example["violated"])
