"""frames(): lazy index, on-demand loading with a bounded cache, shrinking to the first frame."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from pytest_metamorphic import metamorphic, relations
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.io import write_bag
from pytest_metamorphic.lidar.model.cloud import PointCloud
from tests.deterministic import find

KITTI = "kitti_openpcdet/training"


def test_kitti_folder_gives_frames_with_ground_truth(shared_data):
    frame = find(mst.frames(shared_data / KITTI), lambda f: len(f.boxes) == 3)
    assert frame.index == 1 and len(frame.cloud) == 120_268
    assert [b.label for b in frame.boxes] == ["car", "car", "cyclist"]
    assert frame.source.endswith("velodyne/000001.bin")
    assert repr(frame).endswith("000001.bin#1; 120268 points; 2 car, 1 cyclist)")


def test_failures_shrink_toward_the_first_frame(shared_data):
    # Frames 1, 2 and 5 have more than 120k points: the minimal example is frame 1.
    frame = find(mst.frames(shared_data / KITTI), lambda f: len(f.cloud) > 120_000)
    assert frame.index == 1
    assert find(mst.frames(shared_data / KITTI), lambda f: True).index == 0


def test_labels_option(shared_data):
    bare = find(mst.frames(shared_data / KITTI / "velodyne", labels=False), lambda f: True)
    assert bare.boxes == () and bare.index == 0
    required = find(mst.frames(shared_data / KITTI, labels=True), lambda f: True)
    assert len(required.boxes) == 1
    with pytest.raises(InvalidArgument, match=r"labels=True but 11 source\(s\) have no KITTI"):
        mst.frames(shared_data / "holdout", labels=True)
    with pytest.raises(InvalidArgument, match="labels='yes'"):
        mst.frames(shared_data / KITTI, labels="yes")


def test_glob_and_plain_folder(shared_data):
    strategy = mst.frames(str(shared_data / "holdout" / "cuda_*.bin"))
    last = find(strategy, lambda f: f.index == 9)
    assert last.source.endswith("cuda_pointpillars_000009.bin") and last.boxes == ()
    first = find(mst.frames(shared_data / "fast_gicp"), lambda f: True)
    assert first.source.endswith("251370668.pcd") and len(first.cloud) == 69_088
    recursive = find(mst.frames(str(shared_data / "**" / "velodyne" / "*.bin")), lambda f: True)
    assert recursive.boxes  # KITTI labels found beside a globbed velodyne file


def test_bag_frames(shared_data):
    strategy = mst.frames(shared_data / "pointcloudset_ouster/test_converted.bag")
    frame = find(strategy, lambda f: f.index == 1)
    assert frame.source.endswith("test_converted.bag [/os1_cloud_node/points #1]")
    assert frame.cloud.frame_id == "os1_lidar" and frame.cloud.dropped_zero > 80_000


def test_several_bags_in_one_glob(tmp_path):
    for name in ("a", "b"):
        clouds = [PointCloud(np.full((3, 4), k, np.float32), frame_id=name) for k in range(3)]
        write_bag(clouds, tmp_path / f"{name}.bag", topic="/lidar")
    strategy = mst.frames(str(tmp_path / "*.bag"), topic="/lidar")
    frame = find(strategy, lambda f: f.cloud.frame_id == "b")
    assert frame.index == 3 and frame.source.endswith("b.bag [/lidar #0]")


def test_construction_errors(shared_data, tmp_path):
    with pytest.raises(InvalidArgument, match="no such file or folder, and no glob match"):
        mst.frames(str(tmp_path / "*.bin"))
    with pytest.raises(DataError, match="no sensor_msgs/msg/PointCloud2 topic in this bag"):
        mst.frames(shared_data / "nebula_velodyne/vlp16/1673400471837873222")
    with pytest.raises(DataError, match="on topic '/velodyne_packets': it holds velodyne_msgs"):
        mst.frames(
            shared_data / "nebula_velodyne/vlp16/1673400471837873222", topic="/velodyne_packets"
        )
    with pytest.raises(InvalidArgument, match="is not a bag"):
        mst.frames(shared_data / "fast_gicp", topic="/points")
    with pytest.raises(InvalidArgument, match=r"holds no \.bin/\.pcd"):
        mst.frames(tmp_path)
    with pytest.raises(InvalidArgument, match="matches folder"):
        mst.frames(str(shared_data / "holdout*"))
    with pytest.raises(DataError, match="unknown point-cloud format"):
        mst.frames(shared_data / "SOURCES.md")
    for bad in ({"cache_size": 0}, {"cache_size": True}, {"nonfinite": "keep"}, {"topic": 5}):
        with pytest.raises(InvalidArgument):
            mst.frames(shared_data / KITTI, **bad)


def test_cached_frames_are_read_only(shared_data):
    frame = find(mst.frames(shared_data / "fast_gicp"), lambda f: True)
    with pytest.raises(ValueError, match="read-only"):
        frame.cloud.points[0, 0] = 1.0


def test_memory_is_bounded_by_the_cache(shared_data):
    seen: list[int] = []

    @settings(max_examples=40, database=None, phases=[Phase.generate], derandomize=True)
    @given(mst.frames(shared_data / KITTI, labels=False, cache_size=1))
    def draw(frame):
        seen.append(frame.index)

    tracemalloc.start()
    try:
        draw()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(set(seen)) >= 4
    # One cached frame plus the one being loaded, about 2 MB each; all six would be ~12 MB.
    assert peak < 7e6, peak


def test_frames_work_as_a_metamorphic_source(shared_data):
    far = np.array([[500.0, 500.0, 0.0, 0.5]], np.float32)

    def add_far_points(frame):
        return st.integers(1, 5).map(
            lambda n: frame.with_cloud(
                PointCloud(np.concatenate([frame.cloud.points, np.repeat(far, n, axis=0)]))
            )
        )

    @settings(max_examples=4, database=None, suppress_health_check=list(HealthCheck))
    @metamorphic(
        source=mst.frames(shared_data / KITTI),
        followup=add_far_points,
        relation=relations.equal(),
        followups=1,
    )
    def test_points_near_the_car(frame):
        return int(np.count_nonzero(np.hypot(*frame.cloud.xy.T) < 100))

    test_points_near_the_car()


RELATIVE = """
from hypothesis import given, settings
from pytest_metamorphic import strategies as mst

SWEEPS = mst.frames("recordings/*.pcd")


@settings(max_examples=2, database=None)
@given(SWEEPS)
def test_draws(frame):
    assert len(frame.cloud) == 200
"""


def test_a_relative_path_is_found_beside_the_test_file(pytester: pytest.Pytester) -> None:
    # First contact: mst.frames("recordings/*.pcd"), as the first tutorial writes it,
    # stopped collection when pytest ran from the repository root, naming no folder.
    from pytest_metamorphic.lidar.io import write_pcd

    (pytester.path / "tests" / "recordings").mkdir(parents=True)
    cloud = PointCloud(np.random.default_rng(0).normal(size=(200, 3)).astype(np.float32))
    write_pcd(cloud, pytester.path / "tests" / "recordings" / "a.pcd")
    (pytester.path / "tests" / "test_mine.py").write_text(RELATIVE)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "tests")
    result.assert_outcomes(passed=1)
    # From the tests folder itself, as before.
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", str(pytester.path / "tests"))
    result.assert_outcomes(passed=1)
    # Nowhere: the error names both folders it looked in.
    (pytester.path / "tests" / "test_mine.py").write_text(RELATIVE.replace("recordings", "nope"))
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "tests")
    result.stdout.fnmatch_lines(
        [f"*no such file or folder, and no glob match (looked in {pytester.path / 'tests'} and "
         f"in the working directory {pytester.path})*"]
    )  # fmt: skip
