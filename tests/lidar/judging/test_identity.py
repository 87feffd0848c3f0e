"""Obstacles identified by the points they hold (the order and repetition invariances)."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.judging.identity import SameHeldPoints, held_points
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box


def _blob(x: float, y: float, n: int, spread: float = 0.3) -> np.ndarray:
    """n points on a grid around (x, y), 0.5-1.5 m above the sensor's ground."""
    side = int(np.ceil(np.sqrt(n)))
    u, v = np.meshgrid(np.linspace(-spread, spread, side), np.linspace(-spread, spread, side))
    xy = np.column_stack([u.ravel(), v.ravel()])[:n] + np.array([x, y])
    return np.column_stack([xy, np.linspace(0.5, 1.5, n), np.zeros(n)]).astype(np.float32)


def _frame(*blobs: np.ndarray) -> Frame:
    return Frame(PointCloud(np.concatenate(blobs)))


def _box(x: float, y: float, half: float = 0.3, label: str = "pedestrian", **extra) -> Box:
    return Box((x, y, 1.0), (2 * half, 2 * half, 1.0), 0.0, label, **extra)


def _check(source, followup, frame: Frame, relation=None):
    relation = relation or SameHeldPoints()
    return relation.check(source, followup, CheckContext(frame, frame, {}, 0))


def test_held_points_counts_points_on_the_faces_and_nothing_beside() -> None:
    points = np.array([[0.3, 0, 1], [0.34, 0, 1], [0.4, 0, 1], [0, 0, 1.6], [0, 0, 0.2]])
    (held,) = held_points(points, [_box(0, 0)])
    assert held == {0, 1}  # on the face and within the 5 cm growth; not beyond, not below
    assert held_points(points, []) == []
    assert held_points(np.empty((0, 3)), [_box(0, 0)]) == [set()]
    with pytest.raises(InvalidArgument, match="points must be"):
        held_points(np.zeros(3), [_box(0, 0)])


def test_a_border_point_changing_sides_is_the_same_obstacle() -> None:
    # DBSCAN gave the eighth point to the other cluster: the box grows by 30 cm.
    frame = _frame(_blob(10, 0, 7), np.array([[10.6, 0, 1, 0]], np.float32))
    verdict = _check([_box(10, 0)], [Box((10.15, 0, 1), (0.9, 0.6, 1), 0, "pedestrian")], frame)
    assert verdict.holds, verdict.explanation
    assert verdict.details["same_not_identical"][0]["held_iou"] == pytest.approx(7 / 8)
    assert "1 obstacle(s) not identical but holding the same points" in verdict.explanation


def test_identical_outputs_hold_with_nothing_to_report() -> None:
    frame = _frame(_blob(10, 0, 20))
    verdict = _check([_box(10, 0)], [_box(10, 0)], frame)
    assert verdict.holds and verdict.explanation == ""
    assert verdict.details["same_not_identical"] == []


def test_a_score_that_moved_is_information_not_a_violation() -> None:
    frame = _frame(_blob(10, 0, 20))
    verdict = _check([_box(10, 0, score=0.17)], [_box(10, 0, score=0.18)], frame)
    assert verdict.holds and len(verdict.details["same_not_identical"]) == 1


def test_two_obstacles_merged_into_one_are_a_violation_naming_where_the_points_went() -> None:
    frame = _frame(_blob(10, 0, 20), _blob(10, 1.2, 20))
    source = [_box(10, 0), _box(10, 1.2)]
    merged = [Box((10, 0.6, 1), (0.6, 1.8, 1), 0, "pedestrian")]
    verdict = _check(source, merged, frame)
    assert not verdict.holds
    assert verdict.details["changed_source"] == [0, 1] == verdict.details["blamed"]
    assert verdict.details["changed_followup"] == [0]
    assert "its points: 20 in the follow-up pedestrian at (10.0, 0.6)" in verdict.explanation


def test_a_lost_obstacle_and_a_new_one_are_violations() -> None:
    frame = _frame(_blob(10, 0, 20), _blob(20, 0, 20))
    lost = _check([_box(10, 0), _box(20, 0)], [_box(20, 0)], frame)
    assert not lost.holds and "its points: 20 in no follow-up obstacle" in lost.explanation
    new = _check([_box(20, 0)], [_box(10, 0), _box(20, 0)], frame)
    assert not new.holds and new.details["changed_followup"] == [0]
    assert "20 in no source obstacle" in new.explanation


def test_the_class_must_stay_unless_told_otherwise() -> None:
    frame = _frame(_blob(10, 0, 20))
    source = [_box(10, 0, label="pedestrian")]
    followup = [Box((10.02, 0, 1), (0.6, 0.6, 1), 0, "cyclist")]
    assert not _check(source, followup, frame).holds
    assert _check(source, followup, frame, SameHeldPoints(same_label=False)).holds


def test_a_box_without_points_is_compared_by_place() -> None:
    frame = _frame(_blob(10, 0, 20))
    nowhere = [_box(30, 0, half=1.0, label="car")]
    assert _check(nowhere, [_box(30.05, 0, half=1.0, label="car")], frame).holds
    assert not _check(nowhere, [_box(30.5, 0, half=1.0, label="car")], frame).holds


def test_less_than_half_the_same_points_is_another_obstacle() -> None:
    frame = _frame(_blob(10, 0, 40, spread=0.6))
    # The follow-up's box holds only the left third of the blob.
    third = Box((9.8, 0, 1), (0.4, 1.3, 1), 0, "pedestrian")
    verdict = _check([Box((10, 0, 1), (1.3, 1.3, 1), 0, "pedestrian")], [third], frame)
    assert not verdict.holds


def test_outputs_that_are_not_boxes_are_compared_exactly() -> None:
    frame = _frame(_blob(10, 0, 20))
    assert _check(3, 3, frame).holds
    assert not _check(3, 4, frame).holds


@pytest.mark.parametrize("bad", [0.4, 1.0, True, "0.5"])
def test_min_iou_is_checked(bad: object) -> None:
    with pytest.raises(InvalidArgument, match="min_iou"):
        SameHeldPoints(min_iou=bad)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="same_label"):
        SameHeldPoints(same_label=1)  # type: ignore[arg-type]
