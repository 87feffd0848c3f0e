"""The reference pipeline: stages on controlled inputs, invariances on real and synthetic frames."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.lidar.io import read_bin
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic import BackgroundObject, Obstacle, Scene, render
from pytest_metamorphic.lidar.systems.perception import PerceptionParams, ReferencePerception
from pytest_metamorphic.lidar.systems.perception.classify import (
    ClassifierParams,
    ClassRule,
    ObjectShape,
    classify,
)
from pytest_metamorphic.lidar.systems.perception.clustering import ClusterParams, cluster_points
from pytest_metamorphic.lidar.systems.perception.ground import GroundParams, ground_heights

GROUND_Z = -1.73
ROAD = ROI.from_polygons([[(-30.0, -6.0), (60.0, -6.0), (60.0, 6.0), (-30.0, 6.0)]])


def _standing(x: float, y: float, size: tuple[float, float, float], yaw: float, label: str) -> Box:
    return Box((x, y, GROUND_Z + size[2] / 2), size, yaw, label)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def street() -> Frame:
    """A rendered HDL-64E sweep: a car, a pedestrian and a cyclist on a road, clutter beside."""
    scene = Scene(
        roi=ROAD,
        obstacles=(
            Obstacle(_standing(12.0, -2.0, (4.2, 1.8, 1.5), 0.3, "car")),
            Obstacle(_standing(8.0, 3.0, (0.6, 0.5, 1.75), 0.0, "pedestrian")),
            Obstacle(_standing(20.0, 2.5, (1.8, 0.6, 1.75), 1.5, "cyclist")),
        ),
        background=(
            BackgroundObject("building", (20.0, 15.0), (10.0, 6.0, 8.0)),
            BackgroundObject("tree", (10.0, -9.0), (3.0, 3.0, 6.0)),
            BackgroundObject("pole", (5.0, -7.0), (0.3, 0.3, 5.0)),
        ),
        name="street",
    )
    return render(scene)


@pytest.fixture(scope="module")
def kitti_frame() -> PointCloud:
    from conftest import shared_data_path

    return read_bin(shared_data_path("kitti_openpcdet", "training", "velodyne", "000003.bin"))


SUT = ReferencePerception()


def test_detects_and_classifies_the_rendered_street(street: Frame) -> None:
    boxes = SUT(street)  # the frame's own ROI
    assert [box.label for box in boxes] == ["pedestrian", "car", "cyclist"]
    for found, truth in zip(boxes, sorted(street.boxes, key=lambda b: b.center), strict=True):
        assert found.center_distance(truth) < 0.3
        # The box is fitted to the visible points: never larger than the object, and
        # for the fully visible car within 10 cm of the truth on each side.
        assert found.size[0] <= truth.size[0] + 0.1
    car = boxes[1]
    assert car.size[:2] == pytest.approx((4.2, 1.8), abs=0.1)
    assert math.remainder(car.yaw - 0.3, math.pi) == pytest.approx(0.0, abs=0.03)


def test_output_is_sorted_and_deterministic(street: Frame) -> None:
    first, second = SUT(street), SUT(street)
    assert first == second
    assert [b.center for b in first] == sorted(b.center for b in first)


def test_boxes_are_what_the_checked_constructor_builds(kitti_frame: PointCloud) -> None:
    # The pipeline builds its boxes with Box._quick (Box's checks without the frozen
    # dataclass's __init__): they must be exactly what the constructor makes of them.
    boxes = SUT(kitti_frame, kitti_label_region())
    assert len(boxes) > 10
    for box in boxes:
        checked = Box(box.center, box.size, box.yaw, box.label, box.score, box.points)
        assert repr(checked) == repr(box)
        assert checked == box and hash(checked) == hash(box)
        values = (*box.center, *box.size, box.yaw)
        assert all(type(v) is float for v in values)


def test_a_stage_that_returns_a_bad_box_is_still_refused(street: Frame) -> None:
    class BadLabels(ReferencePerception):
        def classify(self, features):  # type: ignore[no-untyped-def]
            return ["truck"] * len(features.length)

    with pytest.raises(InvalidArgument, match="label 'truck' must be one of"):
        BadLabels()(street)
    quick = Box._quick(np.float32([1, 2, 3]), (4, 2, 1.5), np.float64(0.5), "car", 7)
    assert quick == Box((1.0, 2.0, 3.0), (4.0, 2.0, 1.5), 0.5, "car", points=7)
    assert all(type(v) is float for v in (*quick.center, *quick.size, quick.yaw))
    for center, size, match in [
        ((0, 0, math.nan), (1, 1, 1), "non-finite"),
        ((0, 0, 0), (1, 0, 1), "must be positive"),
        ((0, 0), (1, 1, 1), "need 3 values"),
    ]:
        with pytest.raises(InvalidArgument, match=match):
            Box._quick(center, size, 0.0, "car", None)


def test_accepts_frames_clouds_and_arrays(street: Frame) -> None:
    expected = SUT(street)
    assert SUT(street.cloud, ROAD) == expected
    assert SUT(street.cloud.points, ROAD) == expected
    assert SUT(street.cloud.points[:, :3], ROAD) == expected  # intensity is not used


def test_no_roi_keeps_every_point(street: Frame) -> None:
    everything = SUT.run(street.cloud)
    assert everything.in_roi == len(street.cloud)
    assert len(everything.boxes) > len(SUT(street))  # the building, tree and pole appear


def test_run_reports_every_stage(street: Frame) -> None:
    stages = SUT.run(street)
    in_roi = int(ROAD.contains(street.cloud.points).sum())
    assert stages.in_roi == in_roi
    assert 0 < stages.obstacle_points < in_roi
    assert stages.clusters >= len(stages.boxes) == 3


def test_point_order_repeats_and_outside_points_do_not_matter(kitti_frame: PointCloud) -> None:
    roi = kitti_label_region()
    expected = SUT(kitti_frame, roi)
    assert len(expected) > 10
    rng = np.random.default_rng(1)
    points = kitti_frame.points
    shuffled = points[rng.permutation(len(points))]
    assert SUT(shuffled, roi) == expected
    repeated = np.concatenate([points, points[rng.choice(len(points), 20_000)]])
    assert SUT(repeated, roi) == expected
    outside = points[~roi.contains(points)]
    inside = points[roi.contains(points)]
    assert len(outside) > 50_000
    assert SUT(inside, roi) == expected


def test_empty_and_tiny_clouds_give_no_obstacles() -> None:
    assert SUT(np.zeros((0, 4), np.float32), ROAD) == []
    assert SUT(np.array([[10.0, 0.0, GROUND_Z, 0.0]]), ROAD) == []
    # Everything outside the ROI:
    assert SUT(np.array([[10.0, 50.0, 0.0], [11.0, 50.0, 0.0]]), ROAD) == []


def test_bad_input_names_the_argument() -> None:
    with pytest.raises(InvalidArgument, match="roi"):
        SUT(np.zeros((3, 4), np.float32), roi="road")
    with pytest.raises(InvalidArgument, match="params"):
        ReferencePerception(params={"min_cells": 2})  # type: ignore[arg-type]
    with pytest.raises(Exception, match="shape"):
        SUT(np.zeros((3, 2)), ROAD)
    with pytest.raises(Exception, match="NaN"):
        SUT(np.array([[1.0, 2.0, math.nan, 0.0]]), ROAD)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"roi_method": "bitmap"}, "roi_method"),
        ({"max_height": 0.0}, "max_height"),
        ({"min_cells": 0}, "min_cells"),
        ({"sensor": (0.0, 0.0)}, "sensor"),
        ({"hull_start": "first"}, "hull_start"),
        ({"ground": None}, None),
    ],
)
def test_parameters_are_validated(change: dict, match: str | None) -> None:
    if match is None:
        with pytest.raises(InvalidArgument, match="window"):
            GroundParams(window=4)
        with pytest.raises(InvalidArgument, match="max_slope"):
            GroundParams(max_slope=-0.1)
        with pytest.raises(InvalidArgument, match="cell_size"):
            ClusterParams(cell_size=0)
        with pytest.raises(InvalidArgument, match="low <= high"):
            ClassRule(length=(2.0, 1.0), width=(0, 1), top=(0, 2))
        return
    with pytest.raises(InvalidArgument, match=match):
        dataclasses.replace(PerceptionParams(), **change)


# -- stages -----------------------------------------------------------------------------------


def _plane(slope: float, n: int = 4000, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-20, 20, (n, 2))
    z = GROUND_Z + slope * xy[:, 0] + rng.normal(0, 0.02, n)
    return np.column_stack([xy, z]).astype(np.float32)


@pytest.mark.parametrize("slope", [0.0, 0.05, 0.12])
def test_ground_follows_roads_up_to_the_slope_limit(slope: float) -> None:
    plane = _plane(slope)
    heights = ground_heights(plane)
    assert np.all(plane[:, 2] < heights + 0.25)


def test_steeper_than_the_slope_limit_is_not_all_ground() -> None:
    plane = _plane(0.4)
    heights = ground_heights(plane)
    assert np.mean(plane[:, 2] < heights + 0.25) < 0.6


def test_objects_stand_above_the_ground_and_low_outliers_are_ignored() -> None:
    plane = _plane(0.0)
    # From 0.45 m up: the slope allowance (0.15 m over one cell) plus the tolerance
    # (0.25 m) is what an object standing on flat ground loses to the ground.
    body = np.column_stack(
        [np.full(200, 5.0), np.linspace(-0.3, 0.3, 200), np.linspace(-1.28, 0.0, 200)]
    ).astype(np.float32)
    outlier = np.array([[5.5, 0.5, -6.0]], np.float32)  # a multipath return under the road
    points = np.concatenate([plane, body, outlier])
    heights = ground_heights(points)
    above = points[:, 2] - heights
    assert np.all(above[len(plane) : len(plane) + 200] >= 0.25)
    assert np.all(above[: len(plane)] < 0.25)


def test_clusters_are_connected_cells() -> None:
    xy = np.array(
        [[0.1, 0.1], [0.3, 0.1], [0.55, 0.35], [2.0, 2.0], [2.1, 2.1], [2.1, 2.1]], np.float32
    )
    clusters = cluster_points(xy)
    assert clusters.count == 2
    assert clusters.labels.tolist() == [0, 0, 0, 1, 1, 1]
    assert clusters.cells.tolist() == [3, 1]  # the repeated point adds no cell


@settings(max_examples=30)
@given(st.integers(0, 2**32 - 1), st.randoms(use_true_random=False))
def test_clusters_do_not_depend_on_point_order(seed: int, random) -> None:
    xy = np.random.default_rng(seed).uniform(-5, 5, (60, 2)).astype(np.float32)
    order = list(range(len(xy)))
    random.shuffle(order)
    a, b = cluster_points(xy), cluster_points(xy[order])
    assert a.count == b.count
    assert np.array_equal(a.labels[order], b.labels)


def test_classification_rules() -> None:
    shape = ObjectShape(
        length=np.array([4.0, 0.7, 1.8, 1.7, 0.7, 3.0]),
        width=np.array([1.7, 0.5, 0.6, 0.5, 0.05, 0.1]),
        height=np.array([1.2, 1.5, 1.5, 0.9, 1.5, 1.0]),
        top=np.array([1.5, 1.7, 1.7, 1.4, 1.7, 1.5]),
        bottom=np.array([0.3, 0.25, 0.3, 0.5, 0.25, 0.5]),
    )
    labels = classify(shape)
    # car; pedestrian; cyclist; a car seen from behind; a pole; a wall.
    assert labels == ["car", "pedestrian", "cyclist", "car", "unknown", "unknown"]
    no_cars = ClassifierParams(car=())
    assert classify(shape, no_cars)[0] == "unknown"


def test_a_cars_rear_and_a_cyclist_are_told_apart_by_the_crown() -> None:
    """Same footprint and height (1.45 x 0.45 x 1.30 m): a car's roof edge reaches along
    its rear (crown 1.2 m), a rider's head and shoulders do not (0.45 m). Without a crown
    measured the rule is not checked, and the car rule, tried first, takes both."""
    common = {
        "length": np.array([1.45, 1.45]),
        "width": np.array([0.45, 0.45]),
        "height": np.array([1.3, 1.3]),
        "top": np.array([1.6, 1.6]),
        "bottom": np.array([0.3, 0.3]),
    }
    assert classify(ObjectShape(**common, crown=np.array([1.2, 0.45]))) == ["car", "cyclist"]
    assert classify(ObjectShape(**common)) == ["car", "car"]


def test_the_reference_measures_each_objects_crown_along_its_box() -> None:
    # A 1.5 m bar 1.6 m up on posts: its crown is the bar's length.
    posts = [(10.0, y, z) for y in (-0.75, 0.75) for z in np.arange(-1.5, -0.2, 0.1)]
    bar = [(10.0, y, -0.15) for y in np.arange(-0.75, 0.76, 0.05)]
    ground = [(x, y, -1.73) for x in np.arange(7.0, 13.0, 0.2) for y in np.arange(-3, 3, 0.2)]
    cloud = np.array(posts + bar + ground, dtype=np.float32)
    cloud = np.column_stack([cloud, np.full(len(cloud), 0.5, np.float32)])
    features: list[ObjectShape] = []

    class Spy(ReferencePerception):
        def classify(self, shape: ObjectShape) -> list[str]:
            features.append(shape)
            return super().classify(shape)

    Spy()(cloud)
    assert features and features[0].crown is not None
    assert features[0].crown.max() == pytest.approx(1.5, abs=0.1)
