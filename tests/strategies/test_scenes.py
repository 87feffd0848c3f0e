"""Scene strategies: realistic placement, rendering, shrinking toward fewer simpler obstacles."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, Phase, given, settings

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import SIZE_PRIORS
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic import MeshShape, Scene
from pytest_metamorphic.lidar.synthetic.layout import MAX_DISTANCE
from pytest_metamorphic.strategies import road_corridors, scene_frames, scenes
from tests.deterministic import find
from tests.lidar.synthetic.test_layout import check_placement

NO_DB = settings(database=None, deadline=None, suppress_health_check=[HealthCheck.too_slow])
# Shrink-quality checks replay the same search every run.
SHRINK = settings(NO_DB, derandomize=True, phases=[Phase.generate, Phase.shrink])
ROAD = ROI.from_polygons([[[-120, -6], [120, -6], [120, 6], [-120, 6]]])


@settings(max_examples=25)
@given(scene=scenes(max_obstacles=5, max_background=5))
def test_scenes_place_objects_realistically(scene):
    check_placement(scene, max_distance=MAX_DISTANCE)


def test_scenes_shrink_to_fewer_and_simpler_obstacles():
    two = find(scenes(roi=ROAD, max_background=2), lambda s: len(s.obstacles) >= 2, settings=SHRINK)
    assert len(two.obstacles) == 2
    assert not two.background
    assert two.sensor_height == pytest.approx(1.73)
    for obstacle in two.obstacles:
        assert obstacle.label == "car"
        assert obstacle.box.size == pytest.approx(SIZE_PRIORS["car"].mean)
        assert obstacle.box.yaw == 0.0
        assert obstacle.shape == "auto"
    # A failure that needs a pedestrian shrinks to one average pedestrian 10 m ahead.
    walker = find(
        scenes(roi=ROAD, max_background=0),
        lambda scene: any(o.label == "pedestrian" for o in scene.obstacles),
        settings=SHRINK,
    )
    assert [o.label for o in walker.obstacles] == ["pedestrian"]
    box = walker.obstacles[0].box
    assert box.size == pytest.approx(SIZE_PRIORS["pedestrian"].mean)
    assert math.hypot(box.center[0] - 10, box.center[1]) < 0.5


def test_scene_roads_shrink_to_the_simplest_road():
    one = find(
        scenes(max_obstacles=1, max_background=0), lambda s: len(s.obstacles) == 1, settings=SHRINK
    )
    # The simplest road: straight along x, 7 m wide, the car 10 m ahead.
    assert len(one.roi.polygons) == 1 and one.roi.area() == pytest.approx(240 * 7)
    assert one.obstacles[0].box.center[:2] == pytest.approx((10, 0), abs=0.3)


@settings(max_examples=4, suppress_health_check=[HealthCheck.too_slow])
@given(frame=scene_frames(scenes(roi=road_corridors(), min_obstacles=1, max_obstacles=3)))
def test_rendered_scene_frames_know_their_ground_truth(frame):
    cloud = frame.cloud
    assert 60_000 < len(cloud) < 140_000
    instance = cloud.fields["instance"]
    assert len(frame.boxes) >= 1
    for index, box in enumerate(frame.boxes):
        assert box.points == np.count_nonzero(instance == index)
        grown = type(box)(box.center, tuple(s + 0.2 for s in box.size), box.yaw)
        assert grown.contains(cloud.points[instance == index]).all()
    assert frame.roi is not None


def test_user_shapes_are_drawn(tmp_path):
    path = tmp_path / "van.obj"
    trimesh.creation.box(extents=(5.0, 2.0, 2.2)).export(path)
    van = MeshShape.from_file(path)
    scene = find(
        scenes(roi=ROAD, labels=("car",), shapes={"car": [van]}),
        lambda scene: any(o.shape == van for o in scene.obstacles),
        settings=settings(SHRINK, max_examples=500),
    )
    assert [o.shape_name for o in scene.obstacles] == ["van"]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"min_obstacles": 3, "max_obstacles": 2}, "max_obstacles"),
        ({"min_obstacles": -1}, "min_obstacles"),
        ({"labels": ("truck",)}, "labels"),
        ({"labels": ()}, "labels"),
        ({"roi": "a road"}, "roi"),
        ({"max_distance": 2}, "max_distance"),
        ({"shapes": {"car": ["car.obj"]}}, "MeshShape.from_file"),
        ({"shapes": {"bus": []}}, "label 'bus'"),
    ],
)
def test_bad_scene_arguments_fail_early(options, message):
    with pytest.raises(InvalidArgument, match=message):
        scenes(**options)


def test_bad_frame_arguments_fail_early():
    with pytest.raises(InvalidArgument, match="seed"):
        scene_frames(seed=-1)
    with pytest.raises(InvalidArgument, match="engine"):
        scene_frames(engine="optix")
    with pytest.raises(InvalidArgument, match="scene_strategy"):
        scene_frames(Scene())


def test_package_lookup_gives_working_strategies():
    from pytest_metamorphic import strategies as mst

    # Whatever was looked up first, mst.scenes(...) builds the strategy.
    assert mst.rois is not None
    scene = find(mst.scenes(roi=ROAD, max_background=0), lambda s: True, settings=SHRINK)
    assert scene.obstacles == ()
    assert "noise_outside_roi" in dir(mst) and "scene_frames" in dir(mst)
