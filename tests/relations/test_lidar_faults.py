"""Sensor-fault relations: validity on real sweeps, the mutant they catch, the check itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.core.reduction import reduce_followup
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.faults import DropAzimuthBlock, DropRings
from pytest_metamorphic.lidar.followups.perturb import NoiseOutsideROI
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception
from pytest_metamorphic.relations.lidar import (
    CoveredObstaclesKept,
    beam_loss,
    lidar_relations,
    mr1_subset,
    packet_loss,
)
from tests.core.lidar_cases import kitti, street

BEAMS, PACKETS = beam_loss().relation, packet_loss().relation
FOLLOWUPS = 12  # per frame and fault


def _faults(rng: np.random.Generator) -> tuple[DropRings, DropAzimuthBlock]:
    rings = DropRings(rng.choice(64, size=int(rng.integers(1, 5)), replace=False).tolist())
    start, packets = rng.integers(0, 3600) / 10, int(rng.integers(1, 11))
    block = DropAzimuthBlock(math.radians(start), math.radians(1.04 * packets))
    return rings, block


def _violations(system, frames: list[Frame], seed: int) -> tuple[int, int, list[str]]:  # type: ignore[no-untyped-def]
    """(follow-ups, well-covered obstacles judged, violation messages)."""
    rng = np.random.default_rng(seed)
    runs, covered, messages = 0, 0, []
    for frame in frames:
        source_output = system(frame)
        for _ in range(FOLLOWUPS):
            for fault, relation in zip(_faults(rng), (BEAMS, PACKETS), strict=True):
                followup = fault.apply(frame)
                verdict = relation.check(
                    source_output, system(followup), CheckContext(frame, followup, {}, 0)
                )
                runs += 1
                covered += verdict.details["covered"]
                if not verdict.holds:
                    messages.append(f"{fault!r}: {verdict.explanation}")
    return runs, covered, messages


@pytest.mark.parametrize("system", [ReferencePerception(), WholeScenePerception()], ids=repr)
def test_fault_relations_hold_on_every_kitti_sweep_and_a_rendered_street(system) -> None:  # type: ignore[no-untyped-def]
    """Validity: 0 violations in 168 follow-ups (7 frames x 12 x dead beams and lost
    packets), with hundreds of well-covered obstacles judged."""
    frames = [street(), *(kitti(index) for index in range(6))]
    runs, covered, messages = _violations(system, frames, seed=0)
    assert runs == 2 * FOLLOWUPS * len(frames)
    assert covered > 300
    assert messages == []


def test_beam_loss_catches_a_detector_tuned_to_a_dense_sensor() -> None:
    faulty = mutant("dense_min_points")
    _, _, messages = _violations(faulty, [kitti(index) for index in range(6)], seed=0)
    beams = [m for m in messages if m.startswith("DropRings")]
    assert beams and "lost although" in beams[0]
    # MR1 cannot see it: added points never take any from an obstacle in the ROI.
    mr1 = mr1_subset().relation
    for index in range(6):
        frame = kitti(index)
        noise = NoiseOutsideROI.from_seeds(frame, list(range(1000)))
        followup = noise.apply(frame)
        context = CheckContext(frame, followup, noise.params(), 0)
        assert mr1.check(faulty(frame), faulty(followup), context)
    assert {"beams missing", "packets lost"} <= {r.name.split(" =>")[0] for r in lidar_relations()}


def test_a_beam_loss_violation_reduces_to_the_fewest_dead_beams() -> None:
    faulty = mutant("dense_min_points")
    rng = np.random.default_rng(0)
    for index in range(6):
        frame = kitti(index)
        source_output = faulty(frame)
        for _ in range(FOLLOWUPS):
            fault = DropRings((*rng.choice(64, size=3, replace=False).tolist(),))
            followup = fault.apply(frame)
            context = CheckContext(frame, followup, fault.params(), 0)
            if BEAMS.check(source_output, faulty(followup), context).holds:
                continue
            reduction = reduce_followup(
                fault.params(),
                source=frame,
                source_output=source_output,
                followup_output=faulty(followup),
                run=faulty,
                check=BEAMS.check,
            )
            assert reduction.proven_minimal and 1 <= reduction.size <= 3
            kept = reduction.perturbation.rings
            assert set(kept) <= set(fault.rings)
            assert "ring" in reduction.element_lines()[0]
            return
    pytest.fail("no dead-beam violation of dense_min_points found")


def _frame_with_box(points: np.ndarray) -> Frame:
    from pytest_metamorphic.lidar.model.cloud import PointCloud

    cloud = PointCloud(np.column_stack([points, np.zeros(len(points))]).astype(np.float32))
    return Frame(cloud, roi=None)


def test_the_check_needs_enough_points_left_and_an_overlapping_box() -> None:
    car = Box((10.0, 0.0, -1.0), (4.0, 1.8, 1.5), 0.0, "car")
    inside = np.column_stack(
        [np.linspace(8.5, 11.5, 60), np.linspace(-0.5, 0.5, 60), np.full(60, -1.0)]
    )
    source, fewer = _frame_with_box(inside), _frame_with_box(inside[:40])
    check = CoveredObstaclesKept(scope="all")
    shifted = Box((10.5, 0.0, -1.0), (3.0, 1.8, 1.5), 0.0, "unknown")
    assert check.check([car], [shifted], CheckContext(source, fewer, {}, 0))  # any label
    lost = check.check([car], [], CheckContext(source, fewer, {}, 0))
    assert (
        not lost
        and "lost although its box still holds 40 points after the fault (60 before"
        in lost.explanation
    )
    # 25 points left: not well covered, nothing required.
    assert check.check([car], [], CheckContext(source, _frame_with_box(inside[:25]), {}, 0))
    with pytest.raises(InvalidArgument, match="min_share"):
        CoveredObstaclesKept(min_share=1.5)
    with pytest.raises(InvalidArgument, match="min_points"):
        beam_loss(min_points=0)
    with pytest.raises(InvalidArgument, match="max_packets"):
        packet_loss(max_packets=0)


def test_unknown_obstacles_are_judged_unless_labels_says_otherwise() -> None:
    # A lost 60-point unknown object is as much a loss as a car (issue 26); labels= narrows.
    wall = Box((10.0, 0.0, -1.0), (4.0, 1.8, 1.5), 0.0, "unknown")
    inside = np.column_stack(
        [np.linspace(8.5, 11.5, 60), np.linspace(-0.5, 0.5, 60), np.full(60, -1.0)]
    )
    source, fewer = _frame_with_box(inside), _frame_with_box(inside[:40])
    context = CheckContext(source, fewer, {}, 0)
    lost = CoveredObstaclesKept(scope="all").check([wall], [], context)
    assert not lost and "unknown at (10.0, 0.0) lost" in lost.explanation
    named = CoveredObstaclesKept(scope="all", labels=("car", "pedestrian", "cyclist"))
    assert (
        named.check([wall], [], context)
        and named.check([wall], [], context).details["covered"] == 0
    )
    for bad in ("car", (), ("car", "truck")):
        with pytest.raises(InvalidArgument, match="labels="):
            CoveredObstaclesKept(labels=bad)  # type: ignore[arg-type]


def test_dead_lower_lasers_can_take_the_ground_under_a_far_car_from_the_grid_ground() -> None:
    # Found by the docs' own lidar.md example in a random search (2026-11-28): a known
    # weakness of the reference's ground, each cell's lowest return. Rings 50 and 53 of
    # sweep 4 are what lights the ground beside a car 41 m away; without them that cell's
    # lowest return is the car's own underside (-1.44 m instead of -1.69 m), so most of its
    # returns fall under the minimum obstacle height and the car is lost, though 38 of its
    # 58 points remain over its height (the whole-scene variant, same ground, too). The
    # relation's precondition (well covered) does not yet ask that the ground around the
    # obstacle stay seen, as insertion's does: an open soundness gap, documented in
    # docs/soundness.md; this test pins the case until the precondition covers it.
    frame = kitti(4)
    reference = ReferencePerception()
    fault = DropRings([50, 53])
    followup = fault.apply(frame)
    verdict = BEAMS.check(
        reference(frame), reference(followup), CheckContext(frame, followup, fault.params(), 0)
    )
    assert not verdict.holds
    assert "car at (38.3, 15.6) lost although its box still holds 38 points" in verdict.explanation
    near = np.hypot(*(followup.cloud.xyz[:, :2] - (38.3, 15.6)).T) < 2.5
    before = np.hypot(*(frame.cloud.xyz[:, :2] - (38.3, 15.6)).T) < 2.5
    assert frame.cloud.xyz[before, 2].min() < -1.65 < followup.cloud.xyz[near, 2].min()
