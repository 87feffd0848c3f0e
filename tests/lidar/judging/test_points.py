"""Point-by-point judging: which follow-up return is which source return, and when a
labelling or a partition changed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.perturb import (
    DuplicatePoints,
    PermutePoints,
    RotateAboutSensor,
)
from pytest_metamorphic.lidar.judging.correspondence import corresponding_points
from pytest_metamorphic.lidar.judging.points import PointsKeepLabels, changed_clusters
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import Partition, PointLabels


def _frame(xyz) -> Frame:
    xyz = np.asarray(xyz, dtype=np.float32)
    return Frame(PointCloud(np.column_stack([xyz, np.zeros(len(xyz), np.float32)])))


def _line(n: int = 10, y: float = 0.0) -> np.ndarray:
    return np.column_stack([np.arange(n, dtype=float) + 2.0, np.full(n, y), np.zeros(n)])


def _check(relation, source, followup, a, b, params=None):
    return relation.check(a, b, CheckContext(source, followup, params=params or {}))


def test_reordered_returns_are_found_and_judged_against_their_own_labels() -> None:
    source = _frame(_line())
    permutation = PermutePoints(3)
    followup = permutation.apply(source)
    order = permutation.order(len(source.cloud))
    labels = np.arange(10) % 2
    relation = PointsKeepLabels("labels")
    assert _check(relation, source, followup, PointLabels(labels), PointLabels(labels[order])).holds
    # A component that labels by position in the array does not keep its labels.
    verdict = _check(relation, source, followup, PointLabels(labels), PointLabels(labels))
    assert not verdict.holds
    assert verdict.details["changed"] == int(np.count_nonzero(labels != labels[order]))
    assert "judged returns changed" in verdict.explanation
    assert "the follow-up added and removed no return" in verdict.explanation


def test_a_repeated_return_takes_its_originals_label() -> None:
    source = _frame(_line())
    followup = DuplicatePoints([2, 2, 7]).apply(source)
    labels = np.arange(10) % 3
    relation = PointsKeepLabels("labels")
    good = np.concatenate([labels, labels[[2, 2, 7]]])
    assert _check(relation, source, followup, PointLabels(labels), PointLabels(good)).holds
    bad = good.copy()
    bad[-1] = (labels[7] + 1) % 3
    verdict = _check(relation, source, followup, PointLabels(labels), PointLabels(bad))
    assert not verdict.holds and verdict.details["followup_points"] == [12]
    assert verdict.details["changed_points"] == [7]


def test_returns_near_the_change_are_not_judged_and_those_beyond_are() -> None:
    source = _frame(_line(20))
    noise = np.array([[2.0, 3.0, 0.0]])  # 3 m from the first return
    followup = _frame(np.concatenate([_line(20), noise]))
    labels = np.zeros(20, dtype=int)
    near = labels.copy()
    near[0] = 1  # 3 m from the noise
    relation = PointsKeepLabels("labels", radius=3.5)
    verdict = _check(
        relation, source, followup, PointLabels(labels), PointLabels(np.append(near, 0))
    )
    assert verdict.holds and verdict.details["near_change"] == 2  # 3 m and 3.16 m away
    far = labels.copy()
    far[10] = 1
    verdict = _check(
        relation, source, followup, PointLabels(labels), PointLabels(np.append(far, 0))
    )
    assert not verdict.holds
    assert "the nearest is 10.44 m from the follow-up's change" in verdict.explanation


def test_a_removed_return_is_a_change_too() -> None:
    source = _frame(_line(20))
    followup = _frame(_line(20)[1:])
    match = corresponding_points(source, followup, {})
    assert not match.kept[0] and match.kept[1:].all()
    assert match.changed.tolist() == [[2.0, 0.0, 0.0]]


def test_turned_returns_are_turned_back_before_they_are_matched() -> None:
    source = _frame(_line(5, y=1.25))
    turn = RotateAboutSensor(math.radians(90))
    followup = turn.apply(source)
    match = corresponding_points(source, followup, turn.params())
    assert match.origin.tolist() == [0, 1, 2, 3, 4] and len(match.changed) == 0
    assert (corresponding_points(source, followup, {}).origin == -1).all()


def test_copies_the_source_labelled_differently_are_not_judged() -> None:
    xyz = np.concatenate([_line(4), _line(4)[:1]])
    source = _frame(xyz)
    followup = PermutePoints(0).apply(source)
    labels = np.array([1, 0, 0, 0, 0])  # return 0 and its copy 4 disagree
    relation = PointsKeepLabels("labels")
    verdict = _check(relation, source, followup, PointLabels(labels), PointLabels(np.zeros(5, int)))
    assert verdict.holds and verdict.details["ambiguous_copies"] == 2


def test_cluster_ids_do_not_matter_but_merges_splits_and_noise_do() -> None:
    a = np.array([0, 0, 0, 1, 1, 1, -1])
    assert not changed_clusters(a, np.array([7, 7, 7, 3, 3, 3, -1]))[0].any()
    merged, _ = changed_clusters(a, np.array([0, 0, 0, 0, 0, 0, -1]))
    assert merged.tolist() == [False, False, False, True, True, True, False]
    split, _ = changed_clusters(a, np.array([0, 0, 2, 1, 1, 1, -1]))
    assert split.tolist() == [False, False, True, False, False, False, False]
    noise, _ = changed_clusters(a, np.array([0, 0, 0, 1, 1, -1, 1]))
    assert noise.tolist() == [False] * 5 + [True, True]


def test_a_dbscan_border_point_may_change_sides_only_when_allowed() -> None:
    # Two clusters 1 m apart; the return between them, 0.5 m from each, is a border point.
    xyz = np.array(
        [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.7, 0, 0], [1.2, 0, 0], [1.3, 0, 0], [1.4, 0, 0]]
    )
    source = _frame(xyz)
    followup = PermutePoints(1).apply(source)
    order = PermutePoints(1).order(7)
    before = np.array([0, 0, 0, 0, 1, 1, 1])
    after = np.array([0, 0, 0, 1, 1, 1, 1])[order]
    strict = PointsKeepLabels("clusters")
    verdict = _check(strict, source, followup, Partition(before), Partition(after))
    assert not verdict.holds and "1 joined another cluster" in verdict.explanation
    allowed = PointsKeepLabels("clusters", border=0.5)
    verdict = _check(allowed, source, followup, Partition(before), Partition(after))
    assert verdict.holds and verdict.details["border_allowed"] == 1
    # A whole cluster merged into its neighbour is no border effect.
    merged = np.zeros(7, dtype=int)[order]
    assert not _check(allowed, source, followup, Partition(before), Partition(merged)).holds


def test_a_followup_that_leaves_nothing_to_judge_says_so() -> None:
    source = _frame(_line(3))
    followup = _frame(_line(3) + 100.0)
    verdict = _check(
        PointsKeepLabels("labels"), source, followup, PointLabels([0, 0, 0]), PointLabels([1, 1, 1])
    )
    assert (
        verdict.holds
        and verdict.details["judged_nothing"]
        and verdict.explanation == "no return judged"
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kind": "boxes"}, "kind='boxes' must be 'labels' or 'clusters'"),
        ({"kind": "labels", "radius": -1}, "radius=-1 must be a finite number of metres >= 0"),
        ({"kind": "labels", "border": 0.5}, "border= applies to partitions"),
        ({"kind": "labels", "within": "box"}, "within='box' must be 'all' or 'roi'"),
        ({"kind": "labels", "max_changed": -2}, "max_changed=-2 must be an int >= 0"),
    ],
)
def test_bad_arguments_are_named(kwargs, message) -> None:
    with pytest.raises(InvalidArgument, match=message):
        PointsKeepLabels(**kwargs)
