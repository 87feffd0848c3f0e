"""The learned model's training data: degraded as real sweeps are, targets that match
what the network sees, windows on the grid's own cell lattice."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.synthetic import render
from pytest_metamorphic.lidar.synthetic.description import GROUND_INSTANCE
from pytest_metamorphic.lidar.synthetic.streetscape import street_scene
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import (
    CROP,
    degrade,
    example,
    training_frame,
    training_render,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import SHIPPED_GRID, point_cells
from pytest_metamorphic.lidar.systems.perception.cnnseg.targets import cell_targets


@pytest.fixture(scope="module")
def street() -> Frame:
    return render(street_scene(np.random.default_rng(11)), seed=11)


def test_degrading_is_reproducible_and_keeps_box_counts_true(street: Frame) -> None:
    first = degrade(street, np.random.default_rng(5))
    again = degrade(street, np.random.default_rng(5))
    assert np.array_equal(first.cloud.points, again.cloud.points)
    assert len(first.cloud) < len(street.cloud)
    instance = np.asarray(first.cloud.fields["instance"])
    for index, box in enumerate(first.boxes):
        assert box.points == int((instance == index).sum())
    assert first.cloud.points[:, 3].min() >= 0.0 and first.cloud.points[:, 3].max() <= 1.0


def test_a_training_scene_comes_as_rendered_and_as_training_sees_it() -> None:
    # bench/learned_gap.py measures both halves against real sweeps: the second must be
    # exactly what training reads, the first the same scene before degrading.
    raw, seen = training_render(7)
    assert np.array_equal(seen.cloud.points, training_frame(7).cloud.points)
    assert raw.sensor is seen.sensor and len(raw.boxes) == len(seen.boxes)
    assert len(seen.cloud) < len(raw.cloud)


def test_dead_lasers_take_whole_rings_away(street: Frame) -> None:
    rings = np.asarray(street.cloud.fields["ring"])
    seen = set()
    for seed in range(40):
        degraded = degrade(street, np.random.default_rng(seed))
        left = np.unique(np.asarray(degraded.cloud.fields["ring"]))
        missing = set(np.unique(rings)) - set(left)
        seen.update(missing)
        if missing:  # a ring is gone entirely or not at all
            assert not np.isin(np.asarray(degraded.cloud.fields["ring"]), list(missing)).any()
    assert seen, "40 seeds never killed a laser (a quarter of sweeps should have one)"


def test_targets_leave_out_obstacles_with_too_few_returns(street: Frame) -> None:
    all_targets = cell_targets(street, SHIPPED_GRID)
    strict = cell_targets(street, SHIPPED_GRID, min_points=10_000)
    assert all_targets.objectness.sum() > 0 and strict.objectness.sum() == 0


def test_heading_targets_are_the_doubled_yaw_of_cars_and_cyclists(street: Frame) -> None:
    targets = cell_targets(street, SHIPPED_GRID)
    instance = np.asarray(street.cloud.fields["instance"])
    flat, inside = point_cells(street.cloud.points, SHIPPED_GRID)
    checked = set()
    for index, box in enumerate(street.boxes):
        cells = np.unique(flat[inside & (instance == index)])
        # The cells this obstacle owns (it may lose some to a neighbour): they point at it.
        cx, cy = (c.ravel()[cells] for c in SHIPPED_GRID.cell_centers())
        offset = targets.offset.reshape(2, -1)[:, cells]
        pointing = np.hypot(cx + offset[0] - box.center[0], cy + offset[1] - box.center[1])
        owned = cells[pointing < 1e-3]
        if box.label not in ("car", "pedestrian", "cyclist") or len(owned) == 0:
            continue
        heading = targets.heading.reshape(2, -1)[:, owned]
        if box.label == "pedestrian":
            assert np.all(heading == 0)
        else:
            # A box is the same turned by 180 degrees: (cos 2θ, sin 2θ) says so.
            expected = [np.cos(2 * box.yaw), np.sin(2 * box.yaw)]
            assert heading == pytest.approx(np.repeat([expected], len(owned), 0).T, abs=1e-6)
        checked.add(box.label)
    assert {"car", "pedestrian"} <= checked
    assert np.all(targets.heading[:, targets.objectness == 0] == 0)


def test_an_example_is_a_window_of_the_grid_with_targets_per_view() -> None:
    seed = 7
    data = example(seed, SHIPPED_GRID)
    for view in ("full", "roi"):
        assert data[view].shape == (6, CROP, CROP)
        assert data[f"{view}_offset"].shape == (2, CROP, CROP)
        assert data[f"{view}_heading"].shape == (2, CROP, CROP)
        # Object cells hold returns of the view (ROI-only features have no object
        # outside the ROI to find: its targets must not ask for one).
        nonempty = data[view][5] > 0
        assert np.all(nonempty[data[f"{view}_objectness"] > 0])
    assert data["roi"][5].sum() <= data["full"][5].sum()
    frame = training_frame(seed)
    assert frame.roi is not None and len(frame.cloud) > 10_000


def test_reflectances_are_drawn_as_a_real_sensor_reports_them(street: Frame) -> None:
    # The renderer's reflectivity x cos gives the road almost nothing and no zero above
    # it; real KITTI sweeps read the road at about 0.25 and many object returns at 0.
    instance = np.asarray(street.cloud.fields["instance"])
    rendered_road = float(np.median(street.cloud.points[instance == -1, 3]))
    roads, zero_shares = [], []
    for seed in range(40):
        degraded = degrade(street, np.random.default_rng(seed))
        kept = np.asarray(degraded.cloud.fields["instance"])
        near = np.hypot(*degraded.cloud.points[:, :2].T) < 20.0
        roads.append(float(np.median(degraded.cloud.points[(kept == -1) & near, 3])))
        zero_shares.append(float(np.mean(degraded.cloud.points[kept >= 0, 3] == 0.0)))
    assert rendered_road < 0.1
    assert np.median(roads) > 2 * rendered_road  # most sweeps read the road bright
    assert min(roads) < max(roads) / 2  # and how bright varies per sweep
    assert np.median(zero_shares) > 0.05 and min(zero_shares) == 0.0  # some sweeps keep cos


def _ground_per_square_metre(frame: Frame, near: float, far: float) -> float:
    instance = np.asarray(frame.cloud.fields["instance"])
    distance = np.hypot(*frame.cloud.points[:, :2].T)
    ground = (instance == GROUND_INSTANCE) & (distance >= near) & (distance < far)
    return float(ground.sum()) / (np.pi * (far**2 - near**2))


def test_far_road_returns_thin_out_as_on_a_real_sensor(street: Frame) -> None:
    # Real KITTI sweeps keep 0.2-0.4 road returns per m² at 30-45 m where the renderer
    # gives 0.6-1.5; the road near the car keeps (almost) all of its returns.
    rendered_far = _ground_per_square_metre(street, 30.0, 45.0)
    rendered_near = _ground_per_square_metre(street, 5.0, 10.0)
    far, near = [], []
    for seed in range(20):
        degraded = degrade(street, np.random.default_rng(seed))
        far.append(_ground_per_square_metre(degraded, 30.0, 45.0) / rendered_far)
        near.append(_ground_per_square_metre(degraded, 5.0, 10.0) / rendered_near)
    assert np.median(far) < 0.5  # most sweeps lose most far road returns
    assert max(far) > 0.75  # some sweeps keep them, as the renderer draws them
    assert np.median(near) > 0.8


def test_a_camera_crop_cuts_the_near_road_as_kittis_published_crops_do(
    street: Frame,
) -> None:
    degraded = [degrade(street, np.random.default_rng(seed)) for seed in range(40)]
    cropped = [frame for frame in degraded if np.all(frame.cloud.points[:, 0] > 0)]
    assert cropped, "one sweep in four is cut to the camera's view"
    for frame in cropped:
        x, y, z = frame.cloud.points[:, :3].T
        assert np.degrees(np.abs(np.arctan2(y, x))).max() < 40.0 + 1.0  # and the tilt
        # Nothing under -14 degrees from the camera, give or take the tilt (up to a few
        # degrees): the road nearer than some 6 m is gone.
        assert np.degrees(np.arctan2(z + 0.08, np.hypot(x, y))).min() > -14.0 - 5.0
        instance = np.asarray(frame.cloud.fields["instance"])
        assert np.hypot(x, y)[instance == GROUND_INSTANCE].min() > 4.0


def test_degrading_a_recorded_frame_names_the_missing_field(street: Frame) -> None:
    recorded = Frame(PointCloud(street.cloud.points), roi=street.roi)  # as a .bin holds
    with pytest.raises(InvalidArgument, match="no 'instance' field"):
        degrade(recorded, np.random.default_rng(0))


def test_targets_of_a_recorded_frame_name_the_missing_field(street: Frame) -> None:
    recorded = Frame(PointCloud(street.cloud.points), roi=street.roi)
    with pytest.raises(InvalidArgument, match=r"training targets: .* no 'instance' field"):
        cell_targets(recorded, SHIPPED_GRID)
