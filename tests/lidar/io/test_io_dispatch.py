"""read_cloud / write_cloud / detect_format: the format comes from the name or the first bytes."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.io import detect_format, read_cloud, write_cloud
from pytest_metamorphic.lidar.model.cloud import PointCloud

CLOUD = PointCloud(
    np.arange(20, dtype=np.float32).reshape(5, 4),
    fields={"ring": np.arange(5, dtype=np.float32)},
    frame_id="velo",
    timestamp=1.5,
)


def test_detects_real_files(shared_data):
    assert detect_format(shared_data / "fast_gicp/251370668.pcd") == "pcd"
    assert detect_format(shared_data / "kitti_openpcdet/training/velodyne/000000.bin") == "bin"
    assert detect_format(shared_data / "pointcloudset_ouster/test_converted.bag") == "bag"
    assert detect_format(shared_data / "nebula_velodyne/vlp16/1673400471837873222") == "bag"


def test_detects_by_content_when_the_name_says_nothing(tmp_path):
    pcd = write_cloud(CLOUD, tmp_path / "scan.pcd")
    renamed = pcd.rename(tmp_path / "scan.dat")
    assert detect_format(renamed) == "pcd"
    assert read_cloud(renamed).equals(CLOUD)
    bag = write_cloud(CLOUD, tmp_path / "a.bag").rename(tmp_path / "a.record")
    with pytest.raises(DataError, match="looks like a ROS bag; rename it"):
        detect_format(bag)
    (tmp_path / "junk.dat").write_bytes(b"\x01\x02")
    with pytest.raises(DataError, match=r"junk\.dat: unknown point-cloud format"):
        read_cloud(tmp_path / "junk.dat")
    (tmp_path / "folder").mkdir()
    with pytest.raises(DataError, match="not a ROS 2 bag"):
        read_cloud(tmp_path / "folder")
    with pytest.raises(DataError, match="cannot read"):
        detect_format(tmp_path / "none.dat")


def test_apollo_cluster_file_named_pcd_is_refused_clearly(shared_data):
    path = shared_data / "apollo/min_box_object_builder/QB9178_3_1461381834_1461382134_30651.pcd"
    with pytest.raises(DataError, match=r"not a PCD file: unknown header line '3 14\.1913"):
        read_cloud(path)


@pytest.mark.parametrize("name", ["c.pcd", "c.bag"])
def test_write_then_read_is_exact(tmp_path, name):
    assert read_cloud(write_cloud(CLOUD, tmp_path / name)).equals(CLOUD)


def test_bin_keeps_what_bin_can_hold(tmp_path):
    kitti = read_cloud(write_cloud(CLOUD, tmp_path / "c.bin"))
    assert np.array_equal(kitti.points, CLOUD.points) and kitti.fields == {}
    nuscenes = read_cloud(write_cloud(CLOUD, tmp_path / "c.pcd.bin"))
    assert np.array_equal(nuscenes.fields["ring"], CLOUD.fields["ring"])


def test_ros2_bag_folder(tmp_path):
    folder = write_cloud(CLOUD, tmp_path / "run", format="bag")
    assert (folder / "metadata.yaml").is_file()
    assert read_cloud(folder).equals(CLOUD)
    assert read_cloud(folder, topic="/points", index=0).equals(CLOUD)


def test_argument_checks(tmp_path, shared_data):
    pcd = write_cloud(CLOUD, tmp_path / "c.pcd")
    kitti = shared_data / "kitti_openpcdet/training/velodyne/000000.bin"
    cases = [
        (lambda: read_cloud(pcd, topic="/points"), "apply to bags"),
        (lambda: read_cloud(pcd, index=1), "apply to bags"),
        (lambda: read_cloud(pcd, columns=4), "applies to .bin"),
        (lambda: read_cloud(pcd, format="las"), "format='las'"),
        (lambda: read_cloud(pcd, nonfinite="keep"), "nonfinite='keep'"),
        (lambda: read_cloud(kitti, zeros="drop"), "never organised"),
        (lambda: write_cloud(CLOUD, tmp_path / "c.las"), "cannot tell the format"),
        (lambda: write_cloud(CLOUD, tmp_path / "c", format="las"), "format='las'"),
    ]
    for call, message in cases:
        with pytest.raises(InvalidArgument, match=message):
            call()
    assert len(read_cloud(kitti, columns=4, zeros="keep")) == 115_384
