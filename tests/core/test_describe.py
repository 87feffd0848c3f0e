"""Failure messages show outputs readably (core/comparison.describe_value)."""

from __future__ import annotations

from pytest_metamorphic.core.comparison import describe_outputs, describe_value
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


def _box(x: float, label: str = "car") -> Box:
    return Box(center=(x, 1.0, -1.0), size=(4, 2, 1.5), yaw=0.0, label=label)  # type: ignore[arg-type]


def test_outputs_of_boxes_show_only_what_differs_rounded() -> None:
    shared = [_box(float(x)) for x in range(10, 20)]
    source = [*shared, _box(5.04321, "pedestrian")]
    followup = [*shared, _box(30.0), _box(31.0)]
    lines = describe_outputs(source, followup)
    assert (
        lines[0] == "outputs: 11 element(s) in the source, 12 in the follow-up, 10 described alike"
    )
    assert lines[1] == "  only in the source (1): pedestrian at (5.0, 1.0)"
    assert lines[2] == "  only in the follow-up (2): car at (30.0, 1.0); car at (31.0, 1.0)"
    assert not any("10.0, 1.0" in line for line in lines)  # shared boxes are counted, not listed


def test_outputs_alike_as_described_name_their_first_difference() -> None:
    lines = describe_outputs([_box(10.0)], [_box(10.001)])
    assert lines[0].endswith("1 described alike")
    assert "alike as described; the first difference: output[0]" in lines[1]


def test_repeated_descriptions_are_counted() -> None:
    lines = describe_outputs([_box(1.0)] * 3, [_box(1.0)])
    assert lines[1] == "  only in the source (2): car at (1.0, 1.0) (x2)"


def test_plain_outputs_are_shown_side_by_side() -> None:
    assert describe_outputs([0, 1, 3], [0, 1, 2, 3]) == [
        "source output:    [0, 1, 3]",
        "follow-up output: [0, 1, 2, 3]",
    ]
