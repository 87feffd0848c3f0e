"""Mutants whose faults show only when objects move, are bigger, or come after other sweeps
(issue 41): each is killed by the relation aimed at it on a fixed case where the reference
holds."""

from __future__ import annotations

from typing import Any

import pytest

import conftest
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.edit import removal_candidates
from pytest_metamorphic.lidar.followups.history import EarlierSweeps
from pytest_metamorphic.lidar.followups.insert import InsertObject, free_placements
from pytest_metamorphic.lidar.followups.insert.catalogue import road_user_templates
from pytest_metamorphic.lidar.followups.insert.relocation import Movable, Move
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.sensors import frame_sensor
from pytest_metamorphic.lidar.synthetic import Obstacle, Scene, render
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.relations.lidar import (
    history_independence,
    object_insertion,
    object_relocation,
)
from tests.core.lidar_cases import ROAD, labelled_kitti, standing


def _moved(frame: Frame, index: int, move: Move) -> tuple[Frame, dict[str, Any]]:
    box = removal_candidates(frame, scope="roi")[index]
    item = Movable.of(frame, box)
    assert item is not None
    relocation = item.relocate(move, layout=frame_sensor(frame).sensor)
    assert relocation is not None
    return relocation.apply(frame), relocation.params()


def _holds(system: Any, relation: Any, frame: Frame, followup: Frame, params: Any) -> Any:
    context = CheckContext(frame, followup, params, 0)
    return relation.check(system(frame), system(followup), context)


def test_a_yaw_correction_by_view_turns_a_car_turned_in_place() -> None:
    car = standing(10.0, 2.0, (4.5, 1.9, 1.6), -0.7, "car")
    frame = render(Scene(roi=ROAD, obstacles=(Obstacle(car),), name="one car"))
    followup, params = _moved(frame, 0, Move("turn", -10))
    relation = object_relocation().relation
    assert _holds(ReferencePerception(), relation, frame, followup, params).holds
    verdict = _holds(mutant("view_yaw_correction"), relation, frame, followup, params)
    assert not verdict.holds and "degrees off" in verdict.explanation


def test_a_sparse_heading_flip_turns_a_far_car_moved_around_the_sensor() -> None:
    frame = labelled_kitti(2)  # a car 34.8 m away, 83 returns moved 4 degrees aside
    followup, params = _moved(frame, 0, Move("bearing", 4))
    relation = object_relocation().relation
    assert _holds(ReferencePerception(), relation, frame, followup, params).holds
    verdict = _holds(mutant("sparse_heading_flip"), relation, frame, followup, params)
    assert not verdict.holds and "degrees off" in verdict.explanation


def test_a_long_cluster_filter_misses_an_inserted_bus() -> None:
    frame = labelled_kitti(2)
    bus = next(t for t in road_user_templates() if "[bus]" in t.source)
    place = free_placements(frame, bus, layout=frame_sensor(frame).sensor, limit=1)[0]
    insertion = InsertObject.onto(frame, bus, place, layout=frame_sensor(frame).sensor)
    followup = insertion.apply(frame)
    relation = object_insertion().relation
    reference = _holds(ReferencePerception(), relation, frame, followup, insertion.params())
    assert reference.holds
    verdict = _holds(mutant("long_cluster_filter"), relation, frame, followup, insertion.params())
    assert not verdict.holds and "[bus]" in verdict.explanation


@pytest.mark.parametrize("name", ["temporal_ground"])
def test_a_ground_smoothed_over_sweeps_fails_history(name: str) -> None:
    conftest.shared_data_path("kitti_openpcdet")
    frame = labelled_kitti(1)
    relation = history_independence().relation
    history = EarlierSweeps(("mirrored",))

    def after_history(system: Any) -> tuple[Any, Any]:
        system(frame)
        settled = system(frame)  # as the engine does: the source right after itself
        for earlier in history.inputs(frame):
            system(earlier)
        return settled, system(frame)

    context = CheckContext(frame, frame, history.params(), 0)
    assert relation.check(*after_history(ReferencePerception()), context).holds
    verdict = relation.check(*after_history(mutant(name)), context)
    assert not verdict.holds
