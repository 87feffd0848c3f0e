"""Deterministic perturbations: MR1 noise outside and inside the ROI, point edits, rotation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chisquare

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.followups.perturb import (
    NOISE_INSTANCE,
    DropPoints,
    DuplicatePoints,
    NoiseInsideROI,
    NoiseOutsideROI,
    PermutePoints,
    Perturbation,
    PreparedNoise,
    RotateAboutSensor,
    seeded_uniforms,
)
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.roi import ROI

# A crossroads: an east-west road and a north-south road (Apollo: road + junction polygons).
CROSS = ROI.from_polygons(
    [
        [[-120, -6], [120, -6], [120, 6], [-120, 6]],
        [[-5, -120], [5, -120], [5, 120], [-5, 120]],
    ]
)


def _frame(n: int = 5000, *, roi=CROSS, boxes=(), seed: int = 0) -> Frame:
    rng = np.random.default_rng(seed)
    points = np.c_[rng.uniform(-50, 50, (n, 2)), rng.uniform(-2, 1, n), rng.uniform(0.1, 0.7, n)]
    cloud = PointCloud(
        points.astype(np.float32),
        fields={"ring": rng.integers(0, 64, n).astype(np.uint8), "instance": np.zeros(n, np.int32)},
    )
    return Frame(cloud, roi=roi, boxes=boxes, source="test")


FRAME = _frame()
SEEDS = np.random.default_rng(42).integers(0, 2**32, 20_000)


def test_seeded_uniforms_are_per_seed_and_in_range():
    u = seeded_uniforms([0, 1, 2, 2**32 - 1], np.arange(5))
    assert u.shape == (4, 5)
    assert (u >= 0).all() and (u < 1).all()
    # Each row depends only on its own seed: deleting a seed deletes exactly its values.
    assert np.array_equal(seeded_uniforms([2], np.arange(5))[0], u[2])
    assert len(np.unique(u)) == u.size


@pytest.mark.parametrize("margin", [1, 4])
def test_noise_outside_roi_follows_the_paper_recipe(margin):
    noise = NoiseOutsideROI.from_seeds(FRAME, SEEDS[:3000], margin_cells=margin)
    points = noise.points.astype(np.float64)
    assert points.shape == (3000, 4)
    assert not CROSS.contains(points).any()
    assert not CROSS.contains(points, method="exact").any()
    assert CROSS.boundary_distance(points).min() >= margin * CROSS.cell_size
    assert np.hypot(points[:, 0], points[:, 1]).max() <= 120.0
    low, high = FRAME.cloud.points.min(axis=0), FRAME.cloud.points.max(axis=0)
    assert (points[:, 2] >= low[2]).all() and (points[:, 2] <= high[2]).all()
    assert (points[:, 3] >= low[3]).all() and (points[:, 3] <= high[3]).all()
    # z and intensity spread over the frame's whole range.
    assert points[:, 2].min() < low[2] + 0.05 and points[:, 2].max() > high[2] - 0.05


def test_noise_is_deterministic_and_pointwise():
    a = NoiseOutsideROI.from_seeds(FRAME, SEEDS[:100])
    b = NoiseOutsideROI.from_seeds(FRAME, SEEDS[:100])
    assert a.equals(b)
    # Removing seeds removes exactly their points (what Hypothesis' shrinking relies on).
    c = NoiseOutsideROI.from_seeds(FRAME, SEEDS[[3, 50, 99]])
    assert np.array_equal(c.points, a.points[[3, 50, 99]])
    assert NoiseOutsideROI.from_seeds(FRAME, []).points.shape == (0, 4)


def test_noise_outside_roi_is_uniform_over_the_free_disk():
    # Reference: uniform points in the disk, kept where ROI.free_cells says free. The
    # seeded sampler must give the same distribution (chi-square over a 6 x 6 grid).
    noise = NoiseOutsideROI.from_seeds(FRAME, SEEDS)
    rng = np.random.default_rng(7)
    candidates = rng.uniform(-120, 120, (200_000, 2))
    candidates = candidates[np.hypot(*candidates.T) <= 120]
    ix, iy = CROSS.cell_index(candidates)
    reference = candidates[CROSS.free_cells(margin_cells=1)[ix, iy]]
    edges = np.linspace(-120, 120, 7)
    observed = np.histogram2d(*noise.points[:, :2].T, bins=[edges, edges])[0].ravel()
    expected = np.histogram2d(*reference.T, bins=[edges, edges])[0].ravel()
    used = expected > 0
    expected = expected[used] / expected.sum() * observed.sum()
    assert chisquare(observed[used], expected).pvalue > 1e-3
    # Radial check: the fraction beyond 60 m matches the area fraction.
    far = np.mean(np.hypot(*noise.points[:, :2].T) > 60)
    assert far == pytest.approx(np.mean(np.hypot(*reference.T) > 60), abs=0.015)


def test_apply_appends_points_and_keeps_the_frame_context():
    box = Box((20, 0, -1), (4, 2, 1.5), label="car")
    frame = _frame(boxes=(box,))
    noise = NoiseOutsideROI.from_seeds(frame, SEEDS[:10])
    followup = noise.apply(frame)
    assert len(followup.cloud) == len(frame.cloud) + 10
    assert np.array_equal(followup.cloud.points[: len(frame.cloud)], frame.cloud.points)
    assert np.array_equal(followup.cloud.points[-10:], noise.points)
    assert followup.cloud.fields["instance"][-10:].tolist() == [NOISE_INSTANCE] * 10
    assert followup.cloud.fields["ring"][-10:].tolist() == [0] * 10
    assert followup.roi is frame.roi and followup.boxes == frame.boxes
    assert noise.params()["n"] == 10
    assert noise.params()["noise_outside_roi"] is noise
    assert repr(noise).startswith("NoiseOutsideROI(n=10: [(")
    assert "... 2 more" in repr(noise)
    assert len(noise.describe()) <= 115
    assert noise.describe().startswith("NoiseOutsideROI n=10: (")
    assert noise.describe().endswith(" more")
    assert isinstance(noise, Perturbation)


def test_sample_with_a_numpy_generator_is_reproducible():
    a = NoiseOutsideROI.sample(FRAME, 50, rng=np.random.default_rng(1))
    b = NoiseOutsideROI.sample(FRAME, 50, rng=np.random.default_rng(1))
    assert a.equals(b) and len(a) == 50
    with pytest.raises(InvalidArgument, match="rng"):
        NoiseOutsideROI.sample(FRAME, 5, rng=np.random.RandomState(1))
    with pytest.raises(InvalidArgument, match="n="):
        NoiseOutsideROI.sample(FRAME, -1, rng=np.random.default_rng(1))


def test_a_prepared_frame_gives_the_points_from_seeds_gives():
    """prepare() is from_seeds() split at the frame: the same points, follow-up after
    follow-up, for both kinds of noise and for numpy-drawn seeds."""
    boxes = (Box((20, 0, -1), (4, 2, 1.5), yaw=0.3, label="car"),)
    frame = _frame(boxes=boxes)
    outside = NoiseOutsideROI.prepare(frame, margin_cells=2, max_range=80.0)
    inside = NoiseInsideROI.prepare(frame, clearance=0.5)
    assert isinstance(outside, PreparedNoise) and outside.noise_type is NoiseOutsideROI
    for size in (0, 1, 10, 1000):
        seeds = SEEDS[size : 2 * size]
        expected = NoiseOutsideROI.from_seeds(frame, seeds, margin_cells=2, max_range=80.0)
        assert outside.from_seeds(seeds).equals(expected)
        assert inside.from_seeds(seeds).equals(
            NoiseInsideROI.from_seeds(frame, seeds, clearance=0.5)
        )
    drawn = outside.sample(50, rng=np.random.default_rng(3))
    assert drawn.equals(
        NoiseOutsideROI.sample(
            frame, 50, rng=np.random.default_rng(3), margin_cells=2, max_range=80.0
        )
    )
    # What from_seeds() would raise for any seeds, prepare() raises at once.
    with pytest.raises(InvalidArgument, match="has no ROI"):
        NoiseOutsideROI.prepare(Frame(FRAME.cloud))
    with pytest.raises(DataError, match="empty"):
        NoiseInsideROI.prepare(Frame(PointCloud.empty(), roi=CROSS))
    with pytest.raises(InvalidArgument, match="clearance"):
        NoiseInsideROI.prepare(frame, clearance=-1.0)
    with pytest.raises(InvalidArgument, match="seeds"):
        outside.from_seeds([-1])


def test_a_noise_strategy_prepares_its_frame_once(monkeypatch):
    """Every follow-up of a source shares the frame's z and intensity ranges: one pass
    over the sweep per strategy, not one per drawn follow-up."""
    from hypothesis import given, settings

    from pytest_metamorphic.lidar.followups.perturb import noise as noise_module
    from pytest_metamorphic.strategies import noise_outside_roi

    passes = []
    real = noise_module.column_bounds
    monkeypatch.setattr(noise_module, "column_bounds", lambda a: passes.append(1) or real(a))
    strategy = noise_outside_roi(FRAME, n=5)
    assert len(passes) == 1

    @settings(max_examples=10, database=None)
    @given(strategy)
    def draw(followup):
        assert len(followup.input.cloud) == len(FRAME.cloud) + 5

    draw()
    assert len(passes) == 1


def test_noise_errors_name_the_problem():
    bare = Frame(FRAME.cloud)
    with pytest.raises(InvalidArgument, match="has no ROI; pass roi="):
        NoiseOutsideROI.from_seeds(bare, [1])
    # An explicit ROI works for frames without one (real KITTI frames).
    assert len(NoiseOutsideROI.from_seeds(bare, [1, 2], roi=CROSS)) == 2
    small = ROI.from_polygons([[[-5, -5], [5, -5], [5, 5], [-5, 5]]], raster_range=70.0)
    with pytest.raises(InvalidArgument, match="raster_range=70"):
        NoiseOutsideROI.from_seeds(bare, [1], roi=small)
    assert len(NoiseOutsideROI.from_seeds(bare, [1], roi=small, max_range=70.0)) == 1
    with pytest.raises(InvalidArgument, match="margin_cells=0"):
        NoiseOutsideROI.from_seeds(FRAME, [1], margin_cells=0)
    with pytest.raises(InvalidArgument, match="seeds"):
        NoiseOutsideROI.from_seeds(FRAME, [2**32])
    with pytest.raises(InvalidArgument, match="seeds"):
        NoiseOutsideROI.from_seeds(FRAME, [0.5])
    empty = Frame(PointCloud.empty(), roi=CROSS)
    with pytest.raises(DataError, match="empty"):
        NoiseOutsideROI.from_seeds(empty, [1])
    with pytest.raises(InvalidArgument, match="shape"):
        NoiseOutsideROI(np.zeros((3, 3)))
    with pytest.raises(InvalidArgument, match="finite"):
        NoiseOutsideROI(np.full((1, 4), np.nan))


def test_noise_where_the_roi_fills_the_range():
    everything = ROI.from_polygons([[[-130, -130], [130, -130], [130, 130], [-130, 130]]])
    with pytest.raises(DataError, match="no room outside the ROI"):
        NoiseOutsideROI.from_seeds(Frame(FRAME.cloud, roi=everything), [1])


def test_noise_inside_roi_avoids_obstacles():
    boxes = (Box((20, 0, -1), (4, 2, 1.5), yaw=0.3, label="car"), Box((0, 30, -1), (1, 1, 1.7)))
    frame = _frame(boxes=boxes)
    noise = NoiseInsideROI.from_seeds(frame, SEEDS[:4000], clearance=2.0)
    xy = noise.points[:, :2].astype(np.float64)
    assert CROSS.contains(xy).all()
    assert CROSS.contains(xy, method="exact").all()
    assert CROSS.boundary_distance(xy).min() >= CROSS.cell_size
    for box in boxes:
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        offset = xy - box.center[:2]
        along = np.abs(offset @ [c, s]) - box.size[0] / 2
        across = np.abs(offset @ [-s, c]) - box.size[1] / 2
        assert np.hypot(np.maximum(along, 0), np.maximum(across, 0)).min() > 2.0
    # Points come near the obstacles' clearance zones, not only far away.
    assert np.hypot(*(xy - [20, 0]).T).min() < 5.0
    # Without boxes (or with obstacles=()), points may land anywhere in the ROI.
    free = NoiseInsideROI.from_seeds(frame, SEEDS[:4000], obstacles=())
    assert np.hypot(*(free.points[:, :2] - np.array([20, 0])).T).min() < 1.0
    with pytest.raises(InvalidArgument, match="clearance"):
        NoiseInsideROI.from_seeds(frame, [1], clearance=-1)


def test_drop_duplicate_permute():
    frame = FRAME
    dropped = DropPoints([0, 5, 5, 17]).apply(frame)
    assert len(dropped.cloud) == len(frame.cloud) - 3
    assert np.array_equal(dropped.cloud.points[:4], frame.cloud.points[[1, 2, 3, 4]])
    assert DropPoints([0, 5, 5]).params()["dropped"] == 2
    duplicated = DuplicatePoints([7, 7, 9]).apply(frame)
    assert np.array_equal(duplicated.cloud.points[-3:], frame.cloud.points[[7, 7, 9]])
    assert duplicated.cloud.fields["ring"][-1] == frame.cloud.fields["ring"][9]
    permuted = PermutePoints(11).apply(frame)
    order = PermutePoints(11).order(len(frame.cloud))
    assert np.array_equal(permuted.cloud.points, frame.cloud.points[order])
    assert not np.array_equal(order, np.arange(len(order)))
    assert sorted(map(tuple, permuted.cloud.points)) == sorted(map(tuple, frame.cloud.points))
    with pytest.raises(InvalidArgument, match="holds index 5000"):
        DropPoints([5000]).apply(frame)
    with pytest.raises(InvalidArgument, match="non-negative ints"):
        DuplicatePoints([-1])
    with pytest.raises(InvalidArgument, match="seed"):
        PermutePoints(-2)
    assert repr(DropPoints(list(range(20)))).endswith("... 12 more])")


def test_rotation_turns_cloud_roi_and_boxes_together():
    box = Box((20, 5, -1), (4, 2, 1.5), yaw=0.1, label="car")
    frame = _frame(boxes=(box,))
    rotation = RotateAboutSensor(math.radians(30))
    turned = rotation.apply(frame)
    assert turned.roi.equals(CROSS.rotated(math.radians(30)))
    assert turned.boxes[0].center == pytest.approx(box.rotated(math.radians(30)).center)
    # Containment and box membership are preserved point by point.
    assert np.array_equal(
        CROSS.contains(frame.cloud, method="exact"),
        turned.roi.contains(turned.cloud, method="exact"),
    )
    assert np.array_equal(box.contains(frame.cloud), turned.boxes[0].contains(turned.cloud))
    assert np.allclose(
        np.linalg.norm(turned.cloud.xyz, axis=1), np.linalg.norm(frame.cloud.xyz, axis=1), atol=1e-4
    )
    back = RotateAboutSensor(-math.radians(30)).apply(turned)
    assert np.allclose(back.cloud.points, frame.cloud.points, atol=1e-4)
    assert rotation.params() == {"theta_deg": 30.0}
    with pytest.raises(InvalidArgument, match="theta"):
        RotateAboutSensor(float("inf"))
    with pytest.raises(InvalidArgument, match="rotated"):
        RotateAboutSensor(0.1).apply(Frame(frame.cloud, roi="a map"))


def test_noise_on_a_real_kitti_frame(shared_data):
    from pytest_metamorphic.lidar.io import read_cloud

    cloud = read_cloud(shared_data / "kitti_openpcdet/training/velodyne/000000.bin")
    road = ROI.from_polygons([[[-80, -4], [80, -4], [80, 6], [-80, 6]]])
    frame = Frame(cloud, roi=road, source="kitti 000000")
    noise = NoiseOutsideROI.from_seeds(frame, SEEDS[:1000])
    followup = noise.apply(frame)
    assert len(followup.cloud) == len(cloud) + 1000
    assert not road.contains(noise.points).any()
    assert not road.contains(noise.points, method="exact").any()
    z = cloud.points[:, 2]
    assert noise.points[:, 2].min() >= z.min() and noise.points[:, 2].max() <= z.max()
