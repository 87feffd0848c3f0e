"""What ``detection_quality`` scores: KITTI's rules with the issue's range and returns."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.cnnseg.quality import detection_quality

SEEN = Box((20.0, 0.0, -1.0), (4.0, 1.8, 1.5), 0.0, "car")  # 50 returns
SPARSE = Box((30.0, 5.0, -1.0), (4.0, 1.8, 1.5), 0.0, "car")  # 4 returns


def _frame() -> Frame:
    rng = np.random.default_rng(0)
    parts = [
        np.c_[rng.uniform(-0.5, 0.5, (n, 2)) * box.size[:2] + box.center[:2], np.full(n, -1.0)]
        for box, n in ((SEEN, 50), (SPARSE, 4))
    ]
    points = np.c_[np.concatenate(parts), np.full(54, 0.3)].astype(np.float32)
    return Frame(PointCloud(points), roi=kitti_label_region(max_range=70.0), boxes=(SEEN, SPARSE))


def _score(found: list[Box], **options: object) -> tuple[int, int, int]:
    car = detection_quality(lambda frame: found, [_frame()], max_range=70.0, **options)["car"]
    return car.true_positives, car.false_positives, car.false_negatives


def _moved(box: Box, dx: float = 0.0, dy: float = 0.0) -> Box:
    return Box((box.center[0] + dx, box.center[1] + dy, box.center[2]), box.size, box.yaw, "car")


def test_a_detection_of_a_counted_object_is_found_and_a_stray_one_is_false() -> None:
    assert _score([_moved(SEEN, 0.2)]) == (1, 0, 0)
    assert _score([_moved(SEEN, 0.2), _moved(SEEN, 0, -12)]) == (1, 1, 0)
    assert _score([]) == (0, 0, 1)


def test_a_detection_of_an_object_too_sparse_to_count_counts_neither_way() -> None:
    assert _score([SEEN, _moved(SPARSE, 0.3)]) == (1, 0, 0)
    # With the object's returns counted (min_points=4) it is found.
    car = detection_quality(lambda f: [SEEN, SPARSE], [_frame()], max_range=70.0, min_points=4)
    assert car["car"].true_positives == 2


def test_detections_where_nothing_is_labelled_are_not_scored() -> None:
    behind = Box((-15.0, 0.0, -1.0), (4.0, 1.8, 1.5), 0.0, "car")  # outside the camera wedge
    far = Box((90.0, 0.0, -1.0), (4.0, 1.8, 1.5), 0.0, "car")
    assert _score([SEEN, behind, far]) == (1, 0, 0)


@pytest.mark.parametrize("in_region", [True, False])
def test_dont_care_drops_only_detections_no_counted_object_takes(in_region: bool) -> None:
    stray = _moved(SEEN, 0, -12)
    dont_care = lambda frame, box: in_region  # noqa: E731  (every box is in the region)
    tp, fp, fn = _score([SEEN, stray], ignore=dont_care)
    assert (tp, fn) == (1, 0)
    assert fp == (0 if in_region else 1)
