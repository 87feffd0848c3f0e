"""Per-point outputs: labellings and partitions, and the checks a component's output meets."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.point_outputs import (
    GROUND,
    NOISE,
    NOT_GROUND,
    Partition,
    PointLabels,
    as_point_output,
)


def test_a_ground_mask_reads_as_ground_labels() -> None:
    labels = PointLabels(np.array([True, False, True]))
    assert labels.labels.tolist() == [GROUND, NOT_GROUND, GROUND]
    assert repr(labels) == "PointLabels(3 points; not ground: 1, ground: 2)"


def test_partitions_are_equal_whatever_their_ids_are_called() -> None:
    assert Partition([0, 0, 1, -1]) == Partition([5, 5, 2, -7])
    assert Partition([0, 0, 1, -1]) != Partition([5, 5, 5, -1])  # a merge
    assert Partition([0, 0, 1, -1]) != Partition([0, 0, 1, 2])  # noise joined a cluster
    assert Partition([0, 0, 1, -1]) != Partition([0, 1, 1, -1])
    assert Partition([3, -2]).labels.tolist() == [3, NOISE]
    assert Partition([0, 0, 1, -1]).count == 2


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (np.zeros((3, 2)), "must be 1-D"),
        (np.array([0.5, 1.0]), "must hold ints"),
        (["car", "car"], "a list of str"),
    ],
)
def test_outputs_that_are_not_one_id_per_point_are_refused(value, message) -> None:
    with pytest.raises(InvalidArgument, match=message):
        as_point_output(value, "labels", points=len(value), name="the source output")


def test_an_output_of_the_wrong_length_names_both_counts() -> None:
    with pytest.raises(
        InvalidArgument, match=r"the follow-up output has 2 entries but its input cloud has 3"
    ):
        as_point_output(np.array([0, 1]), "clusters", points=3, name="the follow-up output")


def test_a_labelling_is_not_a_partition() -> None:
    with pytest.raises(InvalidArgument, match="is a PointLabels, but the relation judges clusters"):
        as_point_output(PointLabels([0, 1]), "clusters", points=2, name="the source output")
    assert as_point_output(np.array([0, 1]), "clusters", points=2, name="x") == Partition([4, 2])
