"""CNNSegmentation's post-processing on synthetic network outputs (no model needed), and
its input handling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.systems.perception.cnnseg import (
    CNNSegmentation,
    CNNSegParams,
    GridSpec,
    NetworkOutput,
    point_cells,
)

GRID = GridSpec(size=160, range=40.0)
GROUND = -1.73


class FakeNetwork:
    """Predicts one object: every cell holding a return above the ground of ``box_xy``'s
    region is an object cell pointing at ``centre``, with the given class probabilities."""

    def __init__(
        self,
        centre: tuple[float, float],
        region: tuple[float, float, float, float],
        classes: tuple[float, float, float] = (0.7, 0.2, 0.1),
        top: float = 0.0,
        yaw: float | None = None,
    ):
        self.grid = GRID
        self.centre, self.region, self.classes, self.top = centre, region, classes, top
        self.yaw = yaw  # the heading map's yaw everywhere; None: a model without one
        self.batches: list[int] = []

    def predict(self, features: np.ndarray) -> list[NetworkOutput]:
        self.batches.append(len(features))
        n = GRID.size
        cx, cy = GRID.cell_centers()
        x0, x1, y0, y1 = self.region
        inside = (cx >= x0) & (cx <= x1) & (cy >= y0) & (cy <= y1)
        outputs = []
        for frame_features in features:
            objectness = np.where(inside & (frame_features[5] > 0), 0.9, 0.01).astype(np.float32)
            offset = np.stack([self.centre[0] - cx, self.centre[1] - cy]).astype(np.float32)
            class_prob = np.broadcast_to(np.array(self.classes, np.float32)[:, None, None],
                                         (3, n, n)).copy()  # fmt: skip
            height = np.full((n, n), self.top, dtype=np.float32)
            heading = None
            if self.yaw is not None:
                doubled = np.array([math.cos(2 * self.yaw), math.sin(2 * self.yaw)], np.float32)
                heading = np.broadcast_to(doubled[:, None, None], (2, n, n)).copy()
            outputs.append(NetworkOutput(objectness, offset, class_prob, height, heading))
        return outputs


def _street(car_face: np.ndarray) -> np.ndarray:
    """Flat ground returns around the sensor plus ``car_face`` returns."""
    rng = np.random.default_rng(0)
    ground = np.column_stack([rng.uniform(-30, 30, (20000, 2)), np.full(20000, GROUND),
                              rng.uniform(0, 0.3, 20000)])  # fmt: skip
    return np.concatenate([ground, car_face]).astype(np.float32)


def _rear_face(x: float, y: float, width: float = 1.8) -> np.ndarray:
    """Returns of a car's rear seen from behind: a 1.8 m wide, 1.4 m high sheet at x."""
    ys, zs = np.meshgrid(np.linspace(y - width / 2, y + width / 2, 19),
                         np.linspace(GROUND + 0.2, GROUND + 1.4, 13))  # fmt: skip
    return np.column_stack([np.full(ys.size, x), ys.ravel(), zs.ravel(), np.full(ys.size, 0.5)])


def test_a_car_seen_from_behind_is_completed_about_the_predicted_centre() -> None:
    # The rear face at x = 15; the network says the car's centre is 2.1 m behind it.
    network = FakeNetwork(centre=(17.1, 0.0), region=(14, 19, -2, 2))
    detector = CNNSegmentation(network=network)
    (box,) = detector(PointCloud(_street(_rear_face(15.0, 0.0))))
    assert box.label == "car" and box.score == pytest.approx(0.9)
    # At least the class's mean size (3.9 x 1.6 m), centred on 17.1 as far as the face
    # allows: the face (15) stays the box's rear, so 15 to 18.9.
    assert box.center[:2] == pytest.approx((16.95, 0.0), abs=0.01)
    assert box.size[:2] == pytest.approx((3.9, 1.8), abs=0.01)
    assert abs(math.cos(box.yaw)) == pytest.approx(1.0, abs=1e-6)
    # Its z span is the face's returns more than 0.25 m above the ground (the ground model's
    # tolerance: the face's lowest row, 0.2 m up, counts as ground, like the road under it).
    assert box.center[2] - box.size[2] / 2 == pytest.approx(GROUND + 0.3, abs=1e-4)
    assert box.center[2] + box.size[2] / 2 == pytest.approx(GROUND + 1.4, abs=1e-4)
    assert network.batches == [1]


def test_an_implausible_centre_never_stretches_the_box() -> None:
    # A centre 10 m behind the face: the car keeps the class's mean length from its face.
    network = FakeNetwork(centre=(25.0, 0.0), region=(14, 19, -2, 2))
    (box,) = CNNSegmentation(network=network)(PointCloud(_street(_rear_face(15.0, 0.0))))
    assert box.size[0] == pytest.approx(3.9, abs=0.01)
    assert box.center[0] == pytest.approx(15.0 + 1.95, abs=0.01)


def test_a_car_seen_from_the_side_lays_its_length_along_the_side() -> None:
    # A 3 m long side at y = 4 (the car drives along x), its centre predicted 0.8 m
    # beyond it: the length lies along the side, the width across it (not 3.9 m across).
    xs, zs = np.meshgrid(np.linspace(13.5, 16.5, 31), np.linspace(GROUND + 0.4, GROUND + 1.3, 10))
    side = np.column_stack([xs.ravel(), np.full(xs.size, 4.0), zs.ravel(), np.full(xs.size, 0.5)])
    network = FakeNetwork(centre=(15.0, 4.8), region=(12, 18, 2, 7))
    (box,) = CNNSegmentation(network=network)(PointCloud(_street(side)))
    assert box.size[:2] == pytest.approx((3.9, 1.6), abs=0.01)
    assert abs(math.cos(box.yaw)) == pytest.approx(1.0, abs=1e-6)
    assert box.center[:2] == pytest.approx((15.0, 4.8), abs=0.01)


@pytest.mark.parametrize("yaw", [0.3, -1.2, math.pi / 2])
def test_a_cars_heading_comes_from_the_network_where_it_predicts_one(yaw: float) -> None:
    # The rear face alone says nothing of which way the car points; the heading map does.
    # The length (3.9 m) lies along it, whatever the outline's own axes.
    network = FakeNetwork(centre=(17.1, 0.0), region=(14, 19, -2, 2), yaw=yaw)
    (box,) = CNNSegmentation(network=network)(PointCloud(_street(_rear_face(15.0, 0.0))))
    assert box.label == "car"
    assert math.remainder(box.yaw - yaw, math.pi) == pytest.approx(0.0, abs=1e-5)
    assert box.size[0] >= 3.9 - 0.01 and box.size[1] < box.size[0]
    # The visible face stays inside the box.
    corners = box.corners_bev()
    face = _rear_face(15.0, 0.0)[:, :2]
    axes = np.array(
        [[math.cos(box.yaw), math.sin(box.yaw)], [-math.sin(box.yaw), math.cos(box.yaw)]]
    )
    local, bounds = (face - box.center[:2]) @ axes.T, (corners - box.center[:2]) @ axes.T
    assert np.all(local >= bounds.min(axis=0) - 1e-4) and np.all(local <= bounds.max(axis=0) + 1e-4)


def test_a_pedestrians_box_keeps_its_outlines_heading() -> None:
    # The network's heading is trained on cars and cyclists only.
    face = _rear_face(15.0, 0.0, width=0.6)
    expected = CNNSegmentation(
        network=FakeNetwork(centre=(15.1, 0.0), region=(14, 19, -2, 2), classes=(0.1, 0.8, 0.1))
    )(PointCloud(_street(face)))
    with_heading = CNNSegmentation(
        network=FakeNetwork(
            centre=(15.1, 0.0), region=(14, 19, -2, 2), classes=(0.1, 0.8, 0.1), yaw=0.7
        )
    )(PointCloud(_street(face)))
    assert with_heading == expected and expected[0].label == "pedestrian"


def test_class_height_and_size_rules() -> None:
    face = _rear_face(15.0, 0.0)
    pedestrian = FakeNetwork(centre=(15.1, 0.0), region=(14, 19, -2, 2), classes=(0.1, 0.8, 0.1))
    (box,) = CNNSegmentation(network=pedestrian)(PointCloud(_street(face)))
    assert box.label == "pedestrian"
    # Returns more than height_thresh (0.5 m) above the predicted top are left out.
    low_top = FakeNetwork(centre=(17.1, 0.0), region=(14, 19, -2, 2), top=GROUND + 0.5)
    (box,) = CNNSegmentation(network=low_top)(PointCloud(_street(face)))
    assert box.center[2] + box.size[2] / 2 <= GROUND + 1.0 + 1e-6
    # Objects with fewer than min_points points are dropped.
    few = face[:5]
    network = FakeNetwork(centre=(17.1, 0.0), region=(14, 19, -2, 2))
    assert (
        CNNSegmentation(network=network, params=CNNSegParams(min_points=6))(
            PointCloud(_street(few))
        )
        == []
    )


def test_only_roi_points_are_clustered_and_full_cloud_decides_what_the_network_sees() -> None:
    points = _street(_rear_face(15.0, 0.0))
    roi = ROI.from_polygons([[(5, -5), (30, -5), (30, 5), (5, 5)]])
    outside = np.array([[15.0, 12.0, 0.0, 0.5]] * 3, dtype=np.float32)  # off the road
    frame = Frame(PointCloud(np.concatenate([points, outside])), roi=roi)
    for full_cloud in (True, False):
        network = FakeNetwork(centre=(17.1, 0.0), region=(14, 19, -2, 14))
        detector = CNNSegmentation(full_cloud, network=network)
        run = detector.run(frame)
        assert [b.label for b in run.boxes] == ["car"]  # the off-road returns are never objects
        flat, _ = point_cells(outside, GRID)
        row, col = divmod(int(flat[0]), GRID.size)
        assert bool(run.features[5, row, col]) is full_cloud


def test_detect_batch_gives_each_frame_its_own_boxes_in_one_network_call() -> None:
    network = FakeNetwork(centre=(17.1, 0.0), region=(14, 19, -2, 2))
    detector = CNNSegmentation(network=network)
    frames = [PointCloud(_street(_rear_face(15.0, 0.0))), PointCloud(_street(np.empty((0, 4))))]
    batch = detector.detect_batch(frames)
    assert network.batches == [2]
    assert batch == [detector(frames[0]), []] and detector.run_batch(frames) == batch
    assert detector.batch_size == 8 and detector.detect_batch([]) == []


def test_bad_arguments_are_named() -> None:
    with pytest.raises(InvalidArgument, match="full_cloud='yes' must be True or False"):
        CNNSegmentation("yes", network=FakeNetwork((0, 0), (0, 0, 0, 0)))  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match=r"model file '/nowhere\.onnx' does not exist"):
        CNNSegmentation(network="/nowhere.onnx")
    with pytest.raises(InvalidArgument, match=r"objectness_thresh=1\.5 must be in"):
        CNNSegParams(objectness_thresh=1.5)
    with pytest.raises(InvalidArgument, match="batch_size=0"):
        CNNSegmentation(network=FakeNetwork((0, 0), (0, 0, 0, 0)), batch_size=0)


def test_objects_the_grid_cuts_are_dropped() -> None:
    # A car whose returns reach x = 39.5 m: within 1 m of the grid's 40 m border.
    network = FakeNetwork(centre=(40.0, 0.0), region=(37, 40, -2, 2))
    points = PointCloud(_street(_rear_face(39.5, 0.0)))
    assert CNNSegmentation(network=network)(points) == []
    kept = CNNSegmentation(network=network, params=CNNSegParams(edge_margin=0.0))(points)
    assert [box.label for box in kept] == ["car"]
    with pytest.raises(InvalidArgument, match="edge_margin=-1 must be >= 0"):
        CNNSegParams(edge_margin=-1)


def test_max_lift_drops_what_floats_above_the_ground_and_keeps_road_users() -> None:
    # A wall's top seen over a hedge: returns 1.5-2.2 m above the road, none lower.
    network = FakeNetwork(centre=(17.1, 0.0), region=(14, 19, -2, 2))
    wall_top = _rear_face(15.0, 0.0)
    wall_top[:, 2] += 1.3
    floating = PointCloud(_street(wall_top))
    apollo = CNNSegmentation(network=network, params=CNNSegParams(max_lift=None))
    assert [box.label for box in apollo(floating)] == ["car"]
    lifted = CNNSegmentation(network=network)  # max_lift=1.0, the default
    assert CNNSegParams().max_lift == 1.0
    assert lifted(floating) == []
    # A car's rear face reaches down to 0.3 m above the road: kept.
    (box,) = lifted(PointCloud(_street(_rear_face(15.0, 0.0))))
    assert box.label == "car"
    # The limit is on the lowest return: 1.6 m lets the wall top (lowest 1.5 m) through.
    assert len(CNNSegmentation(network=network, params=CNNSegParams(max_lift=1.6))(floating)) == 1
    assert CNNSegParams(max_lift=np.float32(1.5)).max_lift == 1.5
    for bad in (0, -1.0, math.inf, math.nan, True, "1"):
        with pytest.raises(InvalidArgument, match=r"max_lift=.* must be None or a number > 0"):
            CNNSegParams(max_lift=bad)  # type: ignore[arg-type]
