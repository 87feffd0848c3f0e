"""KITTI / nuScenes ``.bin``: real frames as SOURCES.md describes them, round trips, errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.io import read_bin, write_bin
from pytest_metamorphic.lidar.model.cloud import PointCloud

NUSCENES = (
    "mmdet3d_demo/nuscenes/n015-2018-07-24-11-22-45+0800__LIDAR_TOP__1532402927647951.pcd.bin"
)

# SOURCES.md section 2: points, then x, y, z ranges (rounded to 0.01 m there).
KITTI_FRAMES = {
    "000000": (115_384, (-71.04, 73.04), (-21.10, 53.80), (-5.16, 2.67)),
    "000001": (120_268, (-79.43, 77.00), (-55.32, 57.72), (-7.29, 2.90)),
    "000002": (126_891, (-79.45, 79.48), (-72.20, 7.32), (-6.81, 2.88)),
    "000003": (113_110, (-79.72, 79.72), (-30.15, 28.42), (-13.02, 2.91)),
    "000004": (115_976, (-79.30, 79.03), (-75.22, 53.15), (-5.67, 2.90)),
    "000005": (125_086, (-79.80, 79.28), (-40.11, 22.44), (-2.76, 2.89)),
}


@pytest.mark.parametrize("frame", sorted(KITTI_FRAMES))
def test_kitti_frames_match_sources(shared_data, frame):
    path = shared_data / "kitti_openpcdet/training/velodyne" / f"{frame}.bin"
    count, *ranges = KITTI_FRAMES[frame]
    cloud = read_bin(path)
    assert len(cloud) == count and cloud.fields == {} and cloud.timestamp is None
    low, high = cloud.bounds()
    for axis, (lo, hi) in enumerate(ranges):
        assert low[axis] == pytest.approx(lo, abs=0.006)
        assert high[axis] == pytest.approx(hi, abs=0.006)
    assert low[3] >= 0 and high[3] <= 1  # KITTI intensity is reflectance in 0..1
    # Exactly the file's bytes, as numpy reads them.
    assert np.array_equal(cloud.points, np.fromfile(path, "<f4").reshape(-1, 4))


@pytest.mark.parametrize(
    ("name", "count"),
    [
        ("kitti_pointpillars_demo/test/000002.bin", 17_694),
        ("kitti_pointpillars_demo/val/000134.bin", 19_097),
        ("mmdet3d_demo/kitti/000008.bin", 17_238),
        ("holdout/pointpillars_int8_000009.bin", 115_275),
    ],
)
def test_other_kitti_files(shared_data, name, count):
    cloud = read_bin(shared_data / name)
    assert len(cloud) == count


def test_cropped_demo_frame_is_in_front_of_the_car(shared_data):
    cloud = read_bin(shared_data / "kitti_pointpillars_demo/test/000002.bin")
    low, high = cloud.bounds()
    assert low[0] == pytest.approx(4.6, abs=0.01) and high[0] == pytest.approx(79.1, abs=0.02)


def test_nuscenes_sweep_has_five_columns_by_name(shared_data):
    path = shared_data / NUSCENES
    cloud = read_bin(path)
    raw = np.fromfile(path, "<f4").reshape(-1, 5)
    assert len(cloud) == 34_688 and sorted(cloud.fields) == ["ring"]
    assert np.array_equal(cloud.points, raw[:, :4])
    assert (
        np.array_equal(cloud.fields["ring"], raw[:, 4]) and cloud.fields["ring"].dtype == np.float32
    )
    ring = cloud.fields["ring"]
    assert ring.min() == 0 and ring.max() == 31 and np.all(ring == np.round(ring))
    low, high = cloud.bounds()
    assert (low[0], high[0]) == (pytest.approx(-58.0, abs=0.05), pytest.approx(96.9, abs=0.05))
    assert (low[1], high[1]) == (pytest.approx(-96.3, abs=0.05), pytest.approx(98.6, abs=0.05))
    assert (low[2], high[2]) == (pytest.approx(-3.4, abs=0.05), pytest.approx(19.0, abs=0.05))
    assert high[3] <= 255
    assert cloud.timestamp == pytest.approx(1532402927.647951, abs=1e-6)


def test_nuscenes_read_as_kitti_on_request_and_layout_hint(shared_data, tmp_path):
    # The sweep's size divides by 16 too: only the name tells the layouts apart.
    assert len(read_bin(shared_data / NUSCENES, columns=4)) == 693_760 // 16
    odd = tmp_path / "odd.bin"
    np.zeros(15, "<f4").tofile(odd)  # 60 bytes: 3 rows of 5, not rows of 4
    with pytest.raises(
        DataError, match=r"odd\.bin: size 60 bytes is not a multiple of 16.*columns=5"
    ):
        read_bin(odd)
    assert len(read_bin(odd, columns=5)) == 3


def test_bin_errors(tmp_path):
    with pytest.raises(DataError, match=r"missing\.bin: cannot read \.bin file"):
        read_bin(tmp_path / "missing.bin")
    for columns in (2, 4.0, True):
        with pytest.raises(InvalidArgument, match="columns="):
            read_bin(tmp_path / "x.bin", columns=columns)
    with pytest.raises(InvalidArgument, match="must name the 2 column"):
        read_bin(tmp_path / "x.bin", columns=6)
    nan = tmp_path / "nan.bin"
    np.array([[1, 2, 3, 4], [np.nan, 0, 0, 0]], "<f4").tofile(nan)
    with pytest.raises(DataError, match=r"nan\.bin: 1 point\(s\) have NaN"):
        read_bin(nan)
    assert read_bin(nan, nonfinite="drop").dropped_nonfinite == 1
    # The policy is checked before the file is opened: a typo is named, not a missing file.
    with pytest.raises(InvalidArgument, match="nonfinite='keep' must be 'reject' or 'drop'"):
        read_bin(tmp_path / "missing.bin", nonfinite="keep")
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    assert len(read_bin(empty)) == 0


def test_three_and_six_columns(tmp_path):
    path = tmp_path / "six.bin"
    values = np.arange(36, dtype="<f4").reshape(6, 6)
    values.tofile(path)
    cloud = read_bin(path, columns=6, field_names=("ring", "time"))
    assert cloud.fields["time"].tolist() == values[:, 5].tolist()
    xyz = read_bin(path, columns=3)
    assert len(xyz) == 12 and not xyz.intensity.any()


def test_kitti_round_trip_is_byte_exact(shared_data, tmp_path):
    source = shared_data / "kitti_openpcdet/training/velodyne/000001.bin"
    cloud = read_bin(source)
    copy = write_bin(cloud, tmp_path / "copy.bin")
    assert copy.read_bytes() == source.read_bytes()
    assert read_bin(copy).equals(cloud)


def test_nuscenes_round_trip_keeps_the_ring(shared_data, tmp_path):
    cloud = read_bin(shared_data / NUSCENES)
    copy = write_bin(cloud, tmp_path / "sweep__1532402927647951.pcd.bin")
    assert copy.read_bytes() == (shared_data / NUSCENES).read_bytes()
    assert read_bin(copy).equals(cloud)


def test_write_bin_refuses_what_it_cannot_store(tmp_path):
    cloud = PointCloud(np.zeros((2, 4)), fields={"t": np.array([1, 2**25 + 1], np.int64)})
    with pytest.raises(InvalidArgument, match=r"'t' .* not exactly representable as float32"):
        write_bin(cloud, tmp_path / "a.bin", fields=["t"])
    with pytest.raises(InvalidArgument, match="no field 'ring'"):
        write_bin(cloud, tmp_path / "a.pcd.bin")
    with pytest.raises(InvalidArgument, match="1-D"):
        write_bin(
            PointCloud(np.zeros((2, 4)), fields={"n": np.zeros((2, 3))}),
            tmp_path / "b.bin",
            fields=["n"],
        )
    with pytest.raises(InvalidArgument, match="must be a PointCloud"):
        write_bin(np.zeros((2, 4)), tmp_path / "c.bin")
    write_bin(cloud, tmp_path / "d.bin")
    with pytest.raises(InvalidArgument, match="exists; pass overwrite=True"):
        write_bin(cloud, tmp_path / "d.bin")
    write_bin(PointCloud(np.ones((3, 4))), tmp_path / "d.bin", overwrite=True)
    assert len(read_bin(tmp_path / "d.bin")) == 3
    with pytest.raises(InvalidArgument, match="does not exist"):
        write_bin(cloud, tmp_path / "no" / "e.bin")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.bin"]  # no temporary left


@given(
    points=hnp.arrays(
        np.float32,
        st.tuples(st.integers(0, 30), st.just(4)),
        elements=st.floats(width=32, allow_nan=False, allow_infinity=False),
    ),
    ring=st.integers(0, 127),
)
@settings(max_examples=30)
def test_round_trip_any_finite_cloud(tmp_path_factory, points, ring):
    folder = tmp_path_factory.mktemp("bin")
    rings = np.full(len(points), ring, np.float32)
    cloud = PointCloud(points, fields={"ring": rings})
    back = read_bin(write_bin(cloud, folder / "x.pcd.bin"))
    assert np.array_equal(back.points, cloud.points) and np.array_equal(back.fields["ring"], rings)
