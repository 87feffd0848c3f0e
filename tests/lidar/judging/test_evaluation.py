"""Recall/precision scoring, and the reference pipeline's quality on six labelled KITTI frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.lidar.io import read_bin, read_kitti_labels
from pytest_metamorphic.lidar.judging.evaluation import (
    ClassScore,
    Evaluation,
    evaluate,
    kitti_label_region,
    visible_truth,
)
from pytest_metamorphic.lidar.model.obstacles import Box, IoUMatcher
from pytest_metamorphic.lidar.systems.perception import ReferencePerception


def _box(x: float, y: float, label: str = "car", size=(4.0, 1.8, 1.5)) -> Box:
    return Box((x, y, -1.0), size, 0.0, label)  # type: ignore[arg-type]


def test_matching_is_one_to_one() -> None:
    truth = [_box(10, 0)]
    detections = [_box(10.5, 0), _box(9.6, 0.2)]
    result = evaluate(detections, truth)
    car = result["car"]
    assert (car.true_positives, car.false_positives, car.false_negatives) == (1, 1, 0)
    assert car.recall == 1.0 and car.precision == 0.5
    # The closer detection is the match.
    assert result.matches == [("car", 1, 0)]


def test_classes_are_scored_separately() -> None:
    truth = [_box(10, 0), _box(5, 3, "pedestrian", (0.6, 0.6, 1.7))]
    detections = [_box(10, 0, "pedestrian"), _box(5.2, 3, "pedestrian", (0.6, 0.6, 1.7))]
    result = evaluate(detections, truth)
    assert result["car"].recall == 0.0 and result["car"].precision is None
    assert result["pedestrian"].true_positives == 1
    assert result["pedestrian"].false_positives == 1
    assert "car: recall 0/1 = 0.00, precision 0/0 = n/a" in result.describe()


def test_match_radius_and_custom_matchers() -> None:
    truth = [_box(10, 0)]
    far = [_box(12.5, 0)]
    assert evaluate(far, truth)["car"].true_positives == 0  # 2.5 m > 2 m for cars
    near = [_box(11.5, 0)]
    assert evaluate(near, truth)["car"].true_positives == 1
    # BEV IoU of 2.5/5.5 is below 0.5: a stricter matcher rejects the same pair.
    assert evaluate(near, truth, matcher=IoUMatcher(0.5))["car"].true_positives == 0
    assert (
        evaluate(near, truth, matcher={"car": IoUMatcher(0.4)}, labels=["car"])[
            "car"
        ].true_positives
        == 1
    )


def test_evaluations_pool_across_frames() -> None:
    a = evaluate([_box(10, 0)], [_box(10, 0)])
    b = evaluate([], [_box(3, 3)])
    pooled = a + b
    assert pooled["car"] == ClassScore("car", 1, 0, 1)
    assert pooled["car"].recall == 0.5
    assert isinstance(pooled, Evaluation)


def test_bad_arguments_are_named() -> None:
    with pytest.raises(InvalidArgument, match="labels contains 'truck'"):
        evaluate([], [], labels=["truck"])
    with pytest.raises(InvalidArgument, match="not a string"):
        evaluate([], [], labels="car")
    with pytest.raises(InvalidArgument, match=r"truth\[0\] is \(1, 2\)"):
        evaluate([], [(1, 2)])
    with pytest.raises(InvalidArgument, match="matcher"):
        evaluate([], [], matcher=lambda a, b: True)
    with pytest.raises(InvalidArgument, match="no entry for label 'pedestrian'"):
        evaluate([_box(1, 1, "pedestrian")], [_box(1, 1, "pedestrian")], matcher={})
    with pytest.raises(InvalidArgument, match="min_points"):
        visible_truth([], np.zeros((0, 3)), min_points=-1)
    with pytest.raises(InvalidArgument, match="half_angle"):
        kitti_label_region(half_angle=95)


def test_visible_truth_needs_points_and_the_region() -> None:
    region = kitti_label_region()
    seen, empty, behind = _box(10, 0), _box(20, 0), _box(-10, 0)
    points = np.concatenate(
        [np.tile([10.0, 0.0, -1.0], (12, 1)), np.tile([-10.0, 0.0, -1.0], (50, 1))]
    )
    assert visible_truth([seen, empty, behind], points, roi=region) == [seen]
    assert visible_truth([seen, empty, behind], points) == [seen, behind]


def test_kitti_label_region_is_the_camera_wedge() -> None:
    region = kitti_label_region()
    slope = math.tan(math.radians(40))
    inside = [[10, 0], [69, 0], [50, 50 * slope - 1], [5, -5 * slope + 0.5]]
    outside = [[2, 0], [-10, 0], [50, 50 * slope + 1], [71, 0]]
    assert region.contains(inside, method="exact").all()
    assert not region.contains(outside, method="exact").any()


# -- quality of the reference pipeline on real data -----------------------------------------

# Counts over KITTI training frames 000000-000005 (OpenPCDet's sample), visible ground
# truth (>= 10 points, centre in the camera wedge), default matching radii. KITTI maps
# Van/Truck/Tram to "car". A regression guard: true positives may only go up, false
# positives only down. Many "false" cars are parked cars or hedges KITTI did not label.
EXPECTED = {
    "car": {"true_positives": 3, "false_positives": 15, "false_negatives": 2},
    "pedestrian": {"true_positives": 2, "false_positives": 8, "false_negatives": 0},
}


@pytest.fixture(scope="module")
def kitti_scores() -> Evaluation:
    from conftest import shared_data_path

    folder = shared_data_path("kitti_openpcdet", "training")
    region = kitti_label_region()
    perception = ReferencePerception()
    total = Evaluation({})
    for frame in range(6):
        name = f"{frame:06d}"
        cloud = read_bin(folder / "velodyne" / f"{name}.bin")
        labels = read_kitti_labels(
            folder / "label_2" / f"{name}.txt", folder / "calib" / f"{name}.txt"
        )
        truth = visible_truth(labels, cloud, roi=region)
        total = total + evaluate(perception(cloud, region), truth)
    return total


@pytest.mark.parametrize("label", ["car", "pedestrian"])
def test_kitti_recall_and_precision_do_not_regress(kitti_scores: Evaluation, label: str) -> None:
    score = kitti_scores[label]
    expected = EXPECTED[label]
    print(score.describe())
    assert score.true_positives + score.false_negatives == (
        expected["true_positives"] + expected["false_negatives"]
    ), "the visible ground truth changed: the labels or the reader changed"
    assert score.true_positives >= expected["true_positives"], score.describe()
    assert score.false_positives <= expected["false_positives"], score.describe()
