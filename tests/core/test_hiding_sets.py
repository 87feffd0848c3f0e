"""Minimal hiding sets on real perception faults: MR1 noise reduced to the points that matter.

Every reduced set is re-checked without the reducer (:func:`assert_minimal_hiding_set`):
the system runs on the source plus the set (an obstacle must vanish), then on each
one-point removal (none may vanish).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import Phase, settings
from hypothesis import strategies as st

from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic.core.perturbation import as_reducible
from pytest_metamorphic.core.reduction import reduce_followup
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.minimize import (
    IndexEditReduction,
    InjectedPointsReduction,
    changed_obstacles,
    lost_obstacles,
)
from pytest_metamorphic.lidar.followups.perturb import DropPoints, DuplicatePoints, NoiseOutsideROI
from pytest_metamorphic.lidar.model.obstacles import Box, footprint_distances
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.relations.lidar import duplication_invariance, mr1_subset, outside_removal
from tests.core.lidar_cases import (
    MR1,
    assert_minimal_hiding_set,
    failing_noise,
    kitti,
    mr1_holds,
    street,
)


def _reduce(system, frame, noise, source_output, output):
    return reduce_followup(
        noise.params(),
        source=frame,
        source_output=source_output,
        followup_output=output,
        run=system,
        check=MR1.relation.check,
    )


@pytest.mark.slow
def test_global_ground_plane_hiding_set_on_a_rendered_street() -> None:
    # One plane fitted to the whole sweep: hundreds of far points are needed to tilt it
    # enough (since the reference classifier weighs the crown of an object, 100-300 do
    # not turn the cyclist into a car for any of 40 seeds), so the set stays large and the
    # reduction's call budget runs out before it is proven minimal: it must say so, and
    # what it returns must still hide the obstacle.
    system = mutant("global_ground_plane")
    frame = street()
    noise, source_output, output = failing_noise(system, frame, 1000)
    result = _reduce(system, frame, noise, source_output, output)
    points = result.perturbation.points
    assert np.array_equal(points, noise.points[list(result.indices)])
    assert len(points) < 1000
    if result.proven_minimal:
        assert_minimal_hiding_set(system, frame, points)
    else:
        assert "NOT proven minimal" in result.summary()
        assert not mr1_holds(system, frame, points, source_output)


@pytest.mark.parametrize(
    ("name", "index", "n"),
    [
        ("full_cloud_ground", 1, 1000),  # Apollo's use_full_cloud (issue #3341)
        ("grid_anchored_at_sweep", 1, 1000),
        ("random_point_budget", 0, 100),
    ],
)
def test_hiding_sets_of_mutants_on_kitti_sweeps(name: str, index: int, n: int) -> None:
    system = mutant(name)
    frame = kitti(index)
    noise, source_output, output = failing_noise(system, frame, n)
    result = _reduce(system, frame, noise, source_output, output)
    assert result.proven_minimal and result.original_size == n
    points = result.perturbation.points
    assert len(points) == result.size < n
    # A subset of the injected points, in their original order, still outside the ROI.
    assert np.array_equal(points, noise.points[list(result.indices)])
    assert not frame.roi.contains(points).any()
    assert not frame.roi.contains(points, method="exact").any()
    assert_minimal_hiding_set(system, frame, points)
    assert lost_obstacles(source_output, result.output) and not result.verdict.holds
    assert result.calls < 60  # ranked ddmin: a few dozen calls, not one per point


def test_the_reference_pipeline_has_no_hiding_set() -> None:
    frame = kitti(1)
    system = ReferencePerception()
    noise = NoiseOutsideROI.sample(frame, 1000, rng=np.random.default_rng(0))
    source_output = system(frame)
    output = system(noise.apply(frame))
    assert MR1.relation.check(source_output, output, CheckContext(frame, noise.apply(frame))).holds
    with pytest.raises(Exception, match="does not violate the relation"):
        _reduce(system, frame, noise, source_output, output)


def test_repeated_points_reduce_to_the_ones_that_flip_an_object() -> None:
    # raw_point_count keeps small objects by raw point count, so repeating the points of
    # a small object makes it appear: duplication invariance fails. Every ROI point is
    # repeated; the reduction finds the few that matter.
    system = mutant("raw_point_count")
    frame = kitti(1)
    relation = duplication_invariance()
    edit = DuplicatePoints(np.flatnonzero(frame.roi.contains(frame.cloud.points)))
    source_output = system(frame)
    output = system(edit.apply(frame))
    assert output != source_output
    result = reduce_followup(
        edit.params() | {"edit": edit},
        source=frame,
        source_output=source_output,
        followup_output=output,
        run=system,
        check=relation.relation.check,
    )
    assert result.proven_minimal and isinstance(result.perturbation, IndexEditReduction)
    kept = result.perturbation.indices
    assert system(DuplicatePoints(kept).apply(frame)) != source_output
    for position in range(len(kept)):
        rest = np.delete(kept, position)
        assert system(DuplicatePoints(rest).apply(frame)) == source_output
    assert len(kept) < 10 and result.calls < 60
    lines = result.element_lines()
    assert lines[0].startswith(f"point #{kept[0]} repeated: (")


def test_engine_reports_k_points_the_hidden_obstacle_and_calls() -> None:
    system = mutant("grid_anchored_at_sweep")
    frame = kitti(1)

    # No shrinking phase: the engine's reduction alone brings 1000 points down.
    @settings(database=None, derandomize=True, max_examples=5, phases=[Phase.generate])
    @metamorphic(source=st.just(frame), relations=[mr1_subset(n=1000)], followups=1)
    def test(frame):
        return system(frame)

    with pytest.raises(MetamorphicViolation) as caught:
        test()
    record = caught.value.record
    reduction = record.reduction
    # All the drawn points (1000 slots; a slot may be drawn empty).
    assert reduction.original_size == record.followup.params["n"] > 900
    assert reduction.proven_minimal
    points = reduction.perturbation.points
    assert_minimal_hiding_set(system, frame, points)
    message = str(caught.value)
    assert f"minimal follow-up: {len(points)} of {reduction.original_size} element(s)" in message
    assert "proven 1-minimal" in message and f"{reduction.calls} SUT calls" in message
    x, y = points[0, :2]
    assert f"({x:.2f}, {y:.2f}, " in message and "m from the sensor" in message
    hidden = [
        record.source_output[i] for i in lost_obstacles(record.source_output, record.minimal_output)
    ]
    assert hidden and f"({hidden[0].describe()}) of the source has no match" in message
    assert f"  hidden: {hidden[0].describe()} (" in message and " m from th" in message
    assert "inside the ROI's edge, footprint" in message


def test_ranking_puts_points_near_the_lost_obstacle_first() -> None:
    lost = Box((20.0, 0.0, 0.0), (4.0, 2.0, 1.5), 0.0, "car")
    kept = Box((-20.0, 0.0, 0.0), (4.0, 2.0, 1.5), 0.0, "car")
    points = np.array(
        [[80, 50, 0, 0], [23, 0, 0, 0], [-19, 1, 0, 0], [21, 4, 0, 0], [0, 60, 0, 0]],
        dtype=np.float32,
    )
    reduction = InjectedPointsReduction(NoiseOutsideROI(points))
    order = reduction.ranking(None, [lost, kept], [kept])
    assert order[:2] == [1, 3] and sorted(order) == list(range(5))
    # Nothing lost but something changed: rank by distance to the changed boxes.
    moved = Box((-20.0, 0.5, 0.0), (4.0, 2.0, 1.5), 0.0, "car")
    assert reduction.ranking(None, [lost, kept], [lost, moved])[0] == 2
    # Not boxes at all: the original order.
    assert reduction.ranking(None, 3, 4) == [0, 1, 2, 3, 4]
    # The fallback pass orders by height, highest first.
    raised = NoiseOutsideROI(
        points + np.array([0, 0, 1, 0], dtype=np.float32) * [[3], [1], [5], [2], [4]]
    )
    first, by_height = InjectedPointsReduction(raised).rankings(None, [lost, kept], [kept])
    assert first == order and by_height == [2, 4, 0, 3, 1]


def test_lost_and_changed_obstacles() -> None:
    car = Box((10.0, 0.0, 0.0), (4.0, 2.0, 1.5), 0.0, "car")
    walker = Box((5.0, 3.0, 0.0), (0.6, 0.6, 1.7), 0.0, "pedestrian")
    as_unknown = Box((5.0, 3.0, 0.0), (0.6, 0.6, 1.7), 0.0, "unknown")
    assert lost_obstacles([car, walker], [car]) == [1]
    assert lost_obstacles([car, walker], [as_unknown, car]) == [1]  # a class change loses it
    assert lost_obstacles([car, car], [car]) == [1]  # one-to-one
    assert lost_obstacles([], [car]) == []
    assert changed_obstacles([car, walker], [walker, as_unknown]) == ([0], [1])
    distances = footprint_distances(np.array([[10.0, 0.0], [13.0, 0.0], [10.0, 4.0]]), [car])
    assert np.allclose(distances, [0.0, 1.0, 3.0])
    assert math.isinf(footprint_distances(np.zeros((1, 2)), [])[0])


def test_lidar_perturbations_are_reducible_lazily() -> None:
    noise = NoiseOutsideROI(np.zeros((3, 4), dtype=np.float32))
    reducible = as_reducible(noise)
    assert isinstance(reducible, InjectedPointsReduction) and len(reducible) == 3
    restricted = reducible.restrict([0, 2])
    assert type(restricted.perturbation) is NoiseOutsideROI and len(restricted) == 2
    assert restricted.params()["n"] == 2
    assert restricted.to_json()["type"] == "NoiseOutsideROI"
    drop = as_reducible(DropPoints(np.array([4, 9, 2])))
    assert isinstance(drop, IndexEditReduction) and drop.restrict([2]).indices.tolist() == [2]
    assert drop.to_json() == {"type": "DropPoints", "indices": [4, 9, 2]}


@pytest.mark.parametrize(
    ("name", "relation", "index", "key"),
    [
        ("raw_point_count", duplication_invariance(), 1, "duplicate_points"),
        ("roi_off_by_one", outside_removal(scope="all"), 3, "drop_points"),
    ],
)
def test_engine_reduces_repeated_and_removed_points(name, relation, index, key) -> None:
    # Point edits carry their DuplicatePoints / DropPoints object in the follow-up's
    # params, so the engine reduces them like injected points.
    system = mutant(name)
    frame = kitti(index)

    @settings(database=None, derandomize=True, max_examples=20, phases=[Phase.generate])
    @metamorphic(source=st.just(frame), relations=[relation], followups=2)
    def test(frame):
        return system(frame)

    with pytest.raises(MetamorphicViolation) as caught:
        test()
    record = caught.value.record
    reduction = record.reduction
    assert reduction is not None and reduction.key == key
    assert reduction.proven_minimal and len(reduction.indices) < reduction.original_size
    kept = reduction.perturbation.indices
    edit = type(record.followup.params[key])
    assert system(edit(kept).apply(frame)) != system(frame)
    for position in range(len(kept)):
        assert system(edit(np.delete(kept, position)).apply(frame)) == system(frame)
    assert f"minimal follow-up: {len(kept)} of {reduction.original_size}" in str(caught.value)
