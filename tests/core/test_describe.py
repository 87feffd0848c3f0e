"""Failure messages show outputs readably (core/comparison.describe_value)."""

from __future__ import annotations

from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.lidar.model.obstacles import Box


def test_a_list_of_boxes_reads_as_boxes_not_as_reprs() -> None:
    # Before: "[Box(center=(-37.56363487243652, -23.99875831604004, ..." cut after one box.
    boxes = [
        Box(center=(-37.56363487243652, -23.9987583, -1.0), size=(4, 2, 1.5), yaw=0.0, label="car"),
        Box(center=(4.0, 2.2, -1.0), size=(0.6, 0.6, 1.7), yaw=0.0, label="pedestrian"),
    ]
    assert describe_value(boxes) == "2 element(s): car at (-37.6, -24.0); pedestrian at (4.0, 2.2)"
    many = describe_value(boxes * 5)
    assert many.startswith("10 element(s): car at (-37.6, -24.0); pedestrian at (4.0, 2.2);")
    assert many.endswith("; ... and 4 more")


def test_other_values_keep_their_repr() -> None:
    assert describe_value([1, 2.5, "x"]) == "[1, 2.5, 'x']"
    assert describe_value([]) == "[]"
    assert describe_value(list(range(100))).endswith("...")
