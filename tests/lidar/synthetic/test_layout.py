"""Street layouts: road ROIs and scenes from a chooser, independent random scenes."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import SIZE_PRIORS, bev_iou
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic import Scene
from pytest_metamorphic.lidar.synthetic.layout import (
    EGO_CLEARANCE,
    MAX_DISTANCE,
    ObstacleSpec,
    TooFewSlots,
    corridor_roi,
    junction_roi,
    layout_scene,
    obstacle_slots,
    random_scene,
    rng_chooser,
    road_roi,
    star_roi,
)


def check_placement(scene: Scene, *, max_distance: float) -> None:
    """Obstacles stand deep in the ROI, apart, clear of the ego car; clutter stays out."""
    assert 1.63 <= scene.sensor_height <= 1.90
    roi = scene.roi
    boxes = scene.boxes
    for box in boxes:
        assert SIZE_PRIORS[box.label].contains(box.size)
        assert box.bottom_z == pytest.approx(-scene.sensor_height)  # standing on the ground
        assert roi.contains(np.array([box.center[:2]]))[0]
        assert roi.contains(np.array([box.center[:2]]), method="exact")[0]
        assert math.hypot(*box.center[:2]) <= max_distance
        distance = math.hypot(*box.center[:2]) - math.hypot(*box.size[:2]) / 2
        assert distance >= EGO_CLEARANCE
    if len(boxes) > 1:
        iou = bev_iou(boxes, boxes)
        assert np.allclose(iou[~np.eye(len(boxes), dtype=bool)], 0.0)
    for item in scene.background:
        # The whole footprint stays outside the ROI, by both methods.
        angles = np.linspace(0, 2 * math.pi, 16, endpoint=False)
        ring = (
            np.array(item.center) + item.footprint_radius() * np.c_[np.cos(angles), np.sin(angles)]
        )
        probe = np.vstack([ring, [item.center]])
        assert not roi.contains(probe).any()
        assert not roi.contains(probe, method="exact").any()


def test_rng_chooser_covers_both_ends_and_is_seeded() -> None:
    first = rng_chooser(np.random.default_rng(1))(-2, 2)
    choose = rng_chooser(np.random.default_rng(1))
    values = [choose(-2, 2) for _ in range(400)]
    assert set(values) == {-2, -1, 0, 1, 2}
    assert values[0] == first
    assert choose(7, 7) == 7
    with pytest.raises(InvalidArgument, match="rng must be a numpy Generator"):
        rng_chooser(np.random.RandomState(0))  # type: ignore[arg-type]


def test_zero_choices_give_the_simplest_layouts() -> None:
    zero = lambda low, high: max(low, min(0, high))  # noqa: E731
    road = corridor_roi(zero)
    assert road.contains(np.array([[0.0, 0.0], [100.0, 3.0]])).all()
    assert not road.contains(np.array([[0.0, 3.8]])).any()  # 7 m wide along x
    assert junction_roi(zero).contains(np.array([[0.0, 0.0], [0.0, 40.0]])).all()  # a T at 0 m
    assert star_roi(zero).contains(np.array([[0.0, 0.0]]))[0]
    kinds = {road_roi(zero, kinds=(kind,)).polygons[0].shape for kind in ("curved", "polygon")}
    assert len(kinds) == 2


def test_layout_passes_taken_slots_on_and_refuses_too_many_obstacles() -> None:
    road = ROI.from_polygons([[[-120, -6], [120, -6], [120, 6], [-120, 6]]])
    slots = obstacle_slots(road, MAX_DISTANCE)  # layout_scene's default
    same_slot = [ObstacleSpec("car", 0, 0), ObstacleSpec("pedestrian", 0, 0)]
    scene = layout_scene(road, height_steps=0, obstacles=same_slot, clutter=[])
    centres = [box.center[:2] for box in scene.boxes]
    assert np.allclose(centres, slots[:2])
    with pytest.raises(TooFewSlots, match="obstacle slots"):
        layout_scene(road, height_steps=0, obstacles=[], clutter=[], min_obstacles=len(slots) + 1)


@pytest.mark.parametrize("seed", range(12))
def test_random_scenes_are_realistic(seed: int) -> None:
    scene = random_scene(np.random.default_rng(seed))
    check_placement(scene, max_distance=50.0)  # random_scene's default
    assert 1 <= len(scene.obstacles) <= 6
    assert len(scene.background) <= 6


def test_random_scenes_are_reproducible_and_independent() -> None:
    first = random_scene(np.random.default_rng([3, 1]))
    again = random_scene(np.random.default_rng([3, 1]))
    other = random_scene(np.random.default_rng([3, 2]))
    assert first.describe() == again.describe()
    assert first.roi == again.roi
    assert first.describe() != other.describe()


def test_random_scenes_sample_every_road_kind_and_class() -> None:
    scenes = [random_scene(np.random.default_rng([7, i]), max_background=0) for i in range(40)]
    labels = Counter(o.label for scene in scenes for o in scene.obstacles)
    assert set(labels) == {"car", "pedestrian", "cyclist"}
    polygon_counts = Counter(len(scene.roi.polygons) for scene in scenes)
    assert polygon_counts[1] >= 5  # corridors, straight or curved
    assert polygon_counts[4] + polygon_counts[5] >= 5  # junctions: 3 or 4 arms + the square
    counts = Counter(len(scene.obstacles) for scene in scenes)
    assert min(counts) == 1 and max(counts) == 6


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"kinds": ("motorway",)}, "kinds="),
        ({"labels": ("truck",)}, "labels="),
        ({"min_obstacles": -1}, "min_obstacles="),
        ({"min_obstacles": 3, "max_obstacles": 2}, "max_obstacles=2"),
        ({"max_background": 1.5}, "max_background="),
    ],
)
def test_random_scene_names_bad_arguments(options: dict, message: str) -> None:
    with pytest.raises(InvalidArgument, match=message):
        random_scene(np.random.default_rng(0), **options)
