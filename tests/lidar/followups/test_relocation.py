"""Moving a real object within its sweep: removed where it stood, re-cast where it goes,
and judged where it went."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pytest_metamorphic import Followup, InvalidArgument, MetamorphicViolation, metamorphic
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.edit import RemoveObject, removal_candidates
from pytest_metamorphic.lidar.followups.insert import InsertObject, ObjectTemplate, Placement
from pytest_metamorphic.lidar.followups.insert.relocated import RelocatedFound
from pytest_metamorphic.lidar.followups.insert.relocation import (
    MAX_TURN,
    Movable,
    Move,
    RelocateObject,
    moved_box,
)
from pytest_metamorphic.lidar.judging.scope import as_scope
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors import frame_sensor
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.relations.lidar import object_relocation
from pytest_metamorphic.strategies import relocated_objects
from tests.core.lidar_cases import labelled_kitti, street

REFERENCE = ReferencePerception()


def _movable(frame, index: int = 0) -> Movable:  # type: ignore[no-untyped-def]
    box = removal_candidates(frame, scope="roi")[index]
    item = Movable.of(frame, box)
    assert item is not None
    return item


def test_a_move_is_a_rigid_motion_of_the_plane() -> None:
    template = _movable(street()).template
    where = template.box_at(Placement(template.bearing, template.range, 0.0))
    for move in (Move("range", -20), Move("bearing", 30), Move("turn", 15)):
        placed = template.box_at(move.placement(template, 0.0))
        expected = moved_box(where, move.motion(template))
        assert expected.center[:2] == pytest.approx(placed.center[:2], abs=1e-9)
        assert math.remainder(expected.yaw - placed.yaw, 2 * math.pi) == pytest.approx(0, abs=1e-9)
    assert Move("range", -20).describe() == "20 % nearer along its bearing"
    assert Move("turn", -15).describe() == "turned -15 degrees in place"
    for bad in (("slide", 1), ("range", -100), ("turn", math.nan), ("bearing", True)):
        with pytest.raises(InvalidArgument):
            Move(*bad)  # type: ignore[arg-type]


def test_moves_are_listed_smallest_first_on_free_ground_in_scope() -> None:
    frame = labelled_kitti(3)
    item = _movable(frame)
    moves = item.moves(layout=frame_sensor(frame).sensor, scope=as_scope("roi"))
    assert set(moves) <= {"range", "bearing", "turn"} and moves
    for kind, listed in moves.items():
        sizes = [move.size() for move in listed]
        assert sizes == sorted(sizes), kind
        assert all(abs(move.amount) <= MAX_TURN for move in moves.get("turn", []))
    # The probe of each listed move stands in the ROI.
    for move in moves["range"]:
        probe = item.template.box_at(move.placement(item.template, -1.7))
        assert as_scope("roi").judged([probe], frame)[0]


def test_a_relocation_takes_the_object_out_and_casts_it_where_it_goes() -> None:
    frame = labelled_kitti(3)
    item = _movable(frame)
    layout = frame_sensor(frame).sensor
    relocation = item.relocate(Move("range", 20), layout=layout)
    assert relocation is not None
    moved = relocation.apply(frame)
    # Nothing of the object is left where it stood (above its ground); its re-cast returns
    # are where it went.
    without = relocation.removal.apply(frame).cloud.xyz
    above = without[:, 2] > item.box.bottom_z + 0.2
    assert (item.box.grown(0.1).contains(without) & above).sum() <= 0.02 * len(relocation.original)
    assert len(moved.cloud) == len(without) - len(relocation.insertion.hidden) + len(relocation)
    assert relocation.box.grown(0.2).contains(moved.cloud.xyz).sum() >= len(relocation)
    # Farther away, fewer returns (density follows the range).
    near = item.relocate(Move("range", -20), layout=layout)
    assert near is not None and len(near) > len(relocation)
    # The recorded box moves with it.
    assert relocation.expected(item.box).center[0] == pytest.approx(
        item.box.center[0] * 1.2, rel=0.02
    )
    params = relocation.params()
    assert params["relocate_object"] is relocation and "20 % farther" in params["move"]
    again = RelocateObject.from_json(relocation.to_json())
    assert again.apply(frame).cloud.equals(moved.cloud)
    assert again.move == relocation.move and again.motion == relocation.motion


def test_a_car_re_cast_where_it_stood_keeps_its_extent() -> None:
    """The template casts a patch per return: before, KITTI sweep 3's car 13.5 m away, cast
    again where it stood, lost 84 of its 683 returns and its far end (the reference's box
    came out 1 m shorter)."""
    frame = labelled_kitti(3)
    box = removal_candidates(frame, scope="roi")[0]
    template = ObjectTemplate.from_frame(frame, box)
    removal = RemoveObject(box)
    ground_z, _ = removal.ground_height(frame)
    again = InsertObject.onto(
        removal.apply(frame),
        template,
        Placement(template.bearing, template.range, ground_z),
        layout=frame_sensor(frame).sensor,
    )
    assert len(again) >= len(template.vertices)

    def along(points: np.ndarray) -> np.ndarray:
        offset = points[:, :2] - np.asarray(box.center[:2])
        return offset @ np.array([math.cos(box.yaw), math.sin(box.yaw)])

    cast, seen = along(again.points[:, :3]), template.vertices[:, 0]
    assert cast.min() == pytest.approx(seen.min(), abs=0.15)
    assert cast.max() == pytest.approx(seen.max(), abs=0.15)


def test_the_check_holds_for_the_reference_and_names_a_lost_class() -> None:
    frame = labelled_kitti(0)  # a pedestrian 8.9 m away
    item = _movable(frame)
    relocation = item.relocate(Move("range", 10), layout=frame_sensor(frame).sensor)
    assert relocation is not None and item.box.label == "pedestrian"
    followup = relocation.apply(frame)
    context = CheckContext(frame, followup, relocation.params(), 0)
    check = RelocatedFound()
    verdict = check.check(REFERENCE(frame), REFERENCE(followup), context)
    assert verdict.holds and verdict.details["judged"] == 1

    def as_cars(boxes: list[Box]) -> list[Box]:
        return [dataclasses.replace(box, label="car") for box in boxes]

    source = REFERENCE(frame)
    wrong = check.check(source, as_cars(REFERENCE(followup)), context)
    assert not wrong.holds and "is found as a car, not a pedestrian" in wrong.explanation
    assert wrong.details["blamed"]
    # A system that did not find the object where it stood makes no claim about it.
    elsewhere = [box for box in source if not box.grown(0.1).contains(relocation.original).any()]
    assert check.check(elsewhere, [], context).details["judged"] == 0


def test_a_heading_off_is_a_violation_and_a_square_box_has_none() -> None:
    frame = street()
    car = next(box for box in removal_candidates(frame, scope="roi") if box.label == "car")
    item = Movable.of(frame, car)
    assert item is not None
    relocation = item.relocate(Move("bearing", 10), layout=frame_sensor(frame).sensor)
    assert relocation is not None
    followup = relocation.apply(frame)
    context = CheckContext(frame, followup, relocation.params(), 0)
    source = REFERENCE(frame)
    before = next(b for b in source if b.grown(0.1).contains(relocation.original).sum() > 100)
    expected = relocation.expected(before)
    check = RelocatedFound()
    # One box holding the whole moved car, centred where it should be, headed 60 degrees off.
    for size, holds in (((9.0, 5.5, 3.0), False), ((7.0, 6.0, 3.0), True)):
        claimed = dataclasses.replace(expected, size=size, yaw=expected.yaw + math.radians(60))
        verdict = check.check(source, [claimed], context)
        assert verdict.holds is holds, verdict.explanation
    assert (
        "headed 60 degrees off"
        in check.check(
            source,
            [dataclasses.replace(expected, size=(9.0, 5.5, 3.0), yaw=expected.yaw + 1.0472)],
            context,
        ).explanation
    )


def test_relocation_is_sound_on_the_reference_and_finds_a_sparse_heading_flip() -> None:
    frames = st.sampled_from([labelled_kitti(3), labelled_kitti(4), street()])

    @settings(max_examples=25, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))  # fmt: skip
    @metamorphic(source=frames, relations=[object_relocation()])
    def reference(frame):  # type: ignore[no-untyped-def]
        return REFERENCE(frame)

    reference()
    # KITTI sweep 2's car 34.8 m away has 83 returns: moved 4 degrees aside, it has fewer
    # than 80 and the mutant turns its box.
    faulty = mutant("sparse_heading_flip")

    @settings(max_examples=60, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))  # fmt: skip
    @metamorphic(source=st.just(labelled_kitti(2)), relations=[object_relocation()])
    def flipped(frame):  # type: ignore[no-untyped-def]
        return faulty(frame)

    with pytest.raises(MetamorphicViolation, match="moved"):
        flipped()


def _draw(strategy: st.SearchStrategy[Followup]) -> Followup:
    drawn: list[Followup] = []

    @settings(max_examples=1, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))  # fmt: skip
    @given(strategy)
    def take(value: Followup) -> None:
        drawn.append(value)

    take()
    return drawn[0]


def test_the_strategy_draws_moves_and_says_why_nothing_moves() -> None:
    frame = labelled_kitti(3)
    assert _draw(relocated_objects(frame, kinds=("turn",))).params["move"].startswith("turned")
    with pytest.raises(InvalidArgument, match="kinds"):
        relocated_objects(frame, kinds=("jump",))  # type: ignore[arg-type]
    # No object has returns enough for a template of 100,000.
    assert "can move" in (_draw(relocated_objects(frame, min_returns=100_000)).skipped or "")
