"""ROS bags: the Ouster PointCloud2 bag, the Velodyne packet bags, PointCloud2 layouts, writers."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.io import bag_topics, index_bag, iter_bag, read_bag, write_bag
from pytest_metamorphic.lidar.io.rosbag import cloud_to_pointcloud2, pointcloud2_to_cloud
from pytest_metamorphic.lidar.io.rosbag import reader as rosbag
from pytest_metamorphic.lidar.model.cloud import PointCloud

OUSTER = "pointcloudset_ouster/test_converted.bag"
OUSTER_TOPIC = "/os1_cloud_node/points"
VLP16_BAG = "nebula_velodyne/vlp16/1673400471837873222"
VLP32_BAG = "nebula_velodyne/vlp32/1713492677464078412"
OUSTER_FIELDS = {"t": "u4", "reflectivity": "u2", "ring": "u1", "noise": "u2", "range": "u4"}


@pytest.fixture(scope="module")
def ouster(request):
    from conftest import shared_data_path

    path = shared_data_path(OUSTER)
    index = index_bag(path)
    return path, index, [index.read(i) for i in range(len(index))]


# -- the real bags ----------------------------------------------------------------------


def test_ouster_bag_index(ouster):
    path, index, _ = ouster
    assert index.topic == OUSTER_TOPIC and len(index) == 2
    assert index.timestamps == (1592833242657266645, 1592833242755911566)
    assert bag_topics(path)[OUSTER_TOPIC] == ("sensor_msgs/msg/PointCloud2", 2)
    assert len(bag_topics(path)) == 10


def test_ouster_frames_match_sources(ouster):
    _, _, clouds = ouster
    first = clouds[0]
    # 64 x 2048 organised scan: the all-zero padding is dropped and counted.
    assert len(first) + first.dropped_zero == 64 * 2048
    assert 45_600 < len(first) < 45_800 and first.dropped_nonfinite == 0
    assert first.frame_id == "os1_lidar"
    assert first.timestamp == pytest.approx(1588075038.629915872, abs=1e-6)
    assert {k: v.dtype.str[1:] for k, v in first.fields.items()} == OUSTER_FIELDS
    # SOURCES.md gives the ranges over both messages.
    low = np.minimum(first.bounds()[0], clouds[1].bounds()[0])
    high = np.maximum(first.bounds()[1], clouds[1].bounds()[1])
    assert low[:3] == pytest.approx([-10.7, -2.4, -1.8], abs=0.05)
    assert high[:3] == pytest.approx([13.7, 14.2, 2.7], abs=0.06)
    assert set(np.unique(first.fields["ring"])) <= set(range(64))
    assert 45_700 < len(clouds[1]) < 45_900


def test_ouster_decoding_agrees_with_an_independent_decoder(ouster):
    from rosbags.highlevel import AnyReader

    path, _, clouds = ouster
    with AnyReader([path]) as reader:
        connection = next(c for c in reader.connections if c.topic == OUSTER_TOPIC)
        _, _, raw = next(reader.messages(connections=[connection]))
        message = reader.deserialize(raw, connection.msgtype)
    data = np.asarray(message.data).reshape(64 * 2048, 48)
    column = {name: data[:, offset : offset + 4].copy().view("<f4")[:, 0] for name, offset in
              (("x", 0), ("y", 4), ("z", 8), ("intensity", 16))}  # fmt: skip
    keep = (column["x"] != 0) | (column["y"] != 0) | (column["z"] != 0)
    expected = np.stack([column[c][keep] for c in ("x", "y", "z", "intensity")], axis=1)
    assert np.array_equal(clouds[0].points, expected)
    ring = data[:, 26][keep]
    assert np.array_equal(clouds[0].fields["ring"], ring)


def test_ouster_zero_padding_can_be_kept(ouster):
    _, index, clouds = ouster
    full = index.read(0, zeros="keep")
    assert len(full) == 64 * 2048 and full.dropped_zero == 0
    assert index.read(-1).equals(clouds[1])


@pytest.mark.parametrize(
    ("bag", "topic"),
    [(VLP16_BAG, "/velodyne_packets"), (VLP32_BAG, "/sensing/lidar/front/velodyne_packets")],
)
def test_packet_bags_say_there_is_no_pointcloud2(shared_data, bag, topic):
    path = shared_data / bag
    assert list(bag_topics(path)) == [topic]
    assert bag_topics(path)[topic][0] == "velodyne_msgs/msg/VelodyneScan"
    with pytest.raises(DataError) as error:
        index_bag(path, topic=topic)
    assert str(error.value) == (
        f"{path}: no sensor_msgs/msg/PointCloud2 on topic {topic!r}: it holds "
        "velodyne_msgs/msg/VelodyneScan; sensor_msgs/msg/PointCloud2 topics in this bag: none"
    )
    with pytest.raises(
        DataError,
        match=rf"no sensor_msgs/msg/PointCloud2 topic in this bag; topics: {topic} "
        r"\(velodyne_msgs/msg/VelodyneScan, [45] messages\)",
    ):
        read_bag(path)


def test_packet_bag_counts(shared_data):
    assert bag_topics(shared_data / VLP16_BAG)["/velodyne_packets"][1] == 4
    assert bag_topics(shared_data / VLP32_BAG)["/sensing/lidar/front/velodyne_packets"][1] == 5


def test_ros1_profile_mcap_gets_a_clear_error(shared_data):
    with pytest.raises(DataError, match="ros1 profile, which rosbags cannot read"):
        index_bag(shared_data / "pointcloudset_ouster/test.mcap")


def test_topic_and_index_errors(ouster, shared_data, tmp_path):
    path, index, _ = ouster
    with pytest.raises(
        DataError,
        match=r"no topic '/points' in this bag; .*PointCloud2 topics: /os1_cloud_node/points",
    ):
        index_bag(path, topic="/points")
    with pytest.raises(
        DataError, match=r"on topic '/os1_cloud_node/imu': it holds sensor_msgs/msg/Imu"
    ):
        index_bag(path, topic="/os1_cloud_node/imu")
    with pytest.raises(InvalidArgument, match=r"index=2 is out of range: .* has 2 messages"):
        index.read(2)
    with pytest.raises(InvalidArgument, match="must be an integer"):
        index.read(1.0)
    with pytest.raises(DataError, match="no such bag"):
        index_bag(tmp_path / "missing.bag")
    two = write_bag(PointCloud(np.ones((1, 4))), tmp_path / "a.bag")
    with pytest.raises(InvalidArgument, match="topic=3"):
        index_bag(two, topic=3)


def test_bag_with_two_pointcloud2_topics_needs_a_topic(tmp_path):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    message = cloud_to_pointcloud2(PointCloud(np.ones((2, 4))), ros1=True)
    path = tmp_path / "two.bag"
    with Writer(path) as writer:
        for topic in ("/front", "/rear"):
            connection = writer.add_connection(
                topic, "sensor_msgs/msg/PointCloud2", typestore=store
            )
            writer.write(
                connection, 1, store.serialize_ros1(message, "sensor_msgs/msg/PointCloud2")
            )
    with pytest.raises(InvalidArgument, match=r"several .* topics \(/front, /rear\); pass topic="):
        index_bag(path)
    assert len(read_bag(path, topic="/rear")) == 2


# -- writers: every storage round-trips exactly -------------------------------------------


@pytest.mark.parametrize(("name", "storage"), [("out.bag", None), ("out", None), ("out", "mcap")])
def test_real_clouds_round_trip(ouster, tmp_path, name, storage):
    _, _, clouds = ouster
    target = write_bag(clouds, tmp_path / name, topic="/lidar", storage=storage)
    back = list(iter_bag(target))
    assert len(back) == 2 and all(b.equals(c) for b, c in zip(back, clouds, strict=True))
    index = index_bag(target, topic="/lidar")
    assert index.read(1).equals(clouds[1])
    # Log times are the header stamps (to float64 precision, ~0.25 us at 1.6e9 s).
    for log_time, cloud in zip(index.timestamps, clouds, strict=True):
        assert abs(log_time - cloud.timestamp * 1e9) < 1000
    if storage == "mcap":
        assert (target / "out.mcap").is_file() and (target / "metadata.yaml").is_file()


def test_timestamps_are_rounded_to_the_nanosecond(tmp_path):
    cloud = PointCloud(np.ones((1, 4)), timestamp=1.2472855841002684)
    (back,) = iter_bag(write_bag(cloud, tmp_path / "t.bag"))
    assert back.timestamp == 1 + 247285584 / 1e9


def test_written_bag_keeps_order_for_equal_or_missing_stamps(tmp_path):
    clouds = [
        PointCloud(np.full((1, 4), k, np.float32), frame_id=f"f{k}", timestamp=t)
        for k, t in enumerate([5.0, 5.0, None, 1.0])
    ]
    for name in ("o.bag", "o2"):
        back = list(iter_bag(write_bag(clouds, tmp_path / name)))
        assert [c.frame_id for c in back] == ["f0", "f1", "f2", "f3"]
        assert [c.timestamp for c in back] == [5.0, 5.0, None, 1.0]
        assert [c.points[0, 0] for c in back] == [0, 1, 2, 3]


@st.composite
def ros_clouds(draw):
    n = draw(st.integers(0, 15))
    finite = st.floats(width=32, allow_nan=False, allow_infinity=False)
    points = draw(hnp.arrays(np.float32, (n, 4), elements=finite))
    fields = {}
    for index in range(draw(st.integers(0, 3))):
        dtype = draw(st.sampled_from(["i1", "u1", "i2", "u2", "i4", "u4", "f4", "f8"]))
        shape = (n,) if draw(st.booleans()) else (n, 3)
        fields[f"f{index}"] = draw(hnp.arrays(np.dtype(dtype), shape))
    # ROS stamps count nanoseconds; seconds as the reader builds them from a stamp.
    stamp = draw(
        st.none()
        | st.tuples(st.integers(0, 2**31 - 1), st.integers(0, 10**9 - 1))
        .filter(lambda t: t != (0, 0))
        .map(lambda t: t[0] + t[1] / 1e9)
    )
    frame_id = draw(st.text(max_size=6))
    return PointCloud(points, fields=fields, frame_id=frame_id, timestamp=stamp)


@given(cloud=ros_clouds(), storage=st.sampled_from(["rosbag1", "sqlite3", "mcap"]))
@settings(max_examples=25)
def test_any_cloud_round_trips(tmp_path_factory, cloud, storage):
    name = "c.bag" if storage == "rosbag1" else "c"
    target = write_bag(cloud, tmp_path_factory.mktemp("bag") / name, storage=storage)
    (back,) = list(iter_bag(target, zeros="keep"))
    assert np.array_equal(back.points, cloud.points)
    assert (back.frame_id, back.timestamp) == (cloud.frame_id, cloud.timestamp)
    assert [(k, v.dtype, v.tobytes()) for k, v in back.fields.items()] == [
        (k, v.dtype, v.tobytes()) for k, v in cloud.fields.items()
    ]


def test_write_bag_refusals(tmp_path):
    cloud = PointCloud(np.ones((1, 4)))
    cases = [
        ({"path": tmp_path / "a.db3"}, "ROS 2 bags are folders"),
        ({"path": tmp_path / "a.bag", "storage": "mcap"}, "disagree"),
        ({"path": tmp_path / "a", "storage": "rosbag1"}, "disagree"),
        ({"path": tmp_path / "a", "storage": "zip"}, "storage='zip'"),
        ({"path": tmp_path / "a", "topic": "points"}, "absolute topic name"),
        ({"path": tmp_path / "a", "clouds": [cloud, "x"]}, r"clouds\[1\] is str"),
        (
            {"path": tmp_path / "a", "clouds": PointCloud(np.ones((1, 4)), fields={"b": [True]})},
            "PointCloud2 cannot store",
        ),
        (
            {
                "path": tmp_path / "a",
                "clouds": PointCloud(np.ones((1, 4)), fields={"b": np.array([1], np.int64)}),
            },
            "int64",
        ),
        (
            {"path": tmp_path / "a", "clouds": PointCloud(np.ones((1, 4)), timestamp=-1.0)},
            "cannot be a ROS time",
        ),
    ]
    for overrides, message in cases:
        arguments = {"clouds": cloud, **overrides}
        with pytest.raises(InvalidArgument, match=message):
            write_bag(**arguments)
    assert list(tmp_path.iterdir()) == []  # nothing half-written left behind
    write_bag(cloud, tmp_path / "a")
    with pytest.raises(InvalidArgument, match="overwrite=True"):
        write_bag(cloud, tmp_path / "a")
    write_bag([cloud, cloud], tmp_path / "a", overwrite=True)
    assert len(index_bag(tmp_path / "a")) == 2
    (tmp_path / "folder").mkdir()
    with pytest.raises(InvalidArgument, match="not a ROS 2 bag; refusing"):
        write_bag(cloud, tmp_path / "folder", overwrite=True)


@pytest.mark.parametrize("storage", ["rosbag1", "sqlite3", "mcap"])
def test_cached_deserializer_decodes_as_rosbags_own(tmp_path, monkeypatch, storage):
    rng = np.random.default_rng(3)
    clouds = [
        PointCloud(rng.normal(size=(50, 4)), fields={"ring": rng.integers(0, 64, 50, np.uint8)},
                   frame_id="velo", timestamp=10.5 + k)
        for k in range(3)
    ]  # fmt: skip
    bag = write_bag(clouds, tmp_path / ("b.bag" if storage == "rosbag1" else "b"), storage=storage)
    with rosbag._open(bag) as reader:
        # The bag defines PointCloud2 as our typestore does: its deserializer is reused.
        assert rosbag._deserializer(reader).func.__self__ is rosbag._typestore(not reader.is2)
    cached = list(iter_bag(bag))
    monkeypatch.setattr(rosbag, "_type_hash", lambda ros1, msgtype: "another definition")
    with rosbag._open(bag) as reader:
        assert rosbag._deserializer(reader).func.__self__ is reader
    own = list(iter_bag(bag))
    assert len(cached) == len(own) == 3
    for mine, theirs, cloud in zip(cached, own, clouds, strict=True):
        assert mine.equals(theirs) and mine.equals(cloud)


def test_misaligned_message_buffer_decodes_into_memory_of_its_own():
    layout = np.dtype(
        {"names": ["x", "y", "z", "intensity", "ring", "t"],
         "formats": ["<f4", "<f4", "<f4", "<f4", "u1", "<u4"],
         "offsets": [0, 4, 8, 16, 20, 24], "itemsize": 28}
    )  # fmt: skip
    rng = np.random.default_rng(5)
    records = np.zeros(300, layout)
    for name in ("x", "y", "z", "intensity"):
        records[name] = rng.normal(size=300)
    records["ring"] = rng.integers(0, 64, 300)
    records["t"] = rng.integers(0, 2**32, 300)
    message = _message(records)
    # A PointCloud2's data starts wherever the serialised header ends: 3 bytes in, here.
    message.data = np.frombuffer(b"\xee" * 3 + records.tobytes(), np.uint8)[3:]
    for zeros in ("keep", "auto"):
        cloud = pointcloud2_to_cloud(message, zeros=zeros)
        expected = np.stack([records[c] for c in ("x", "y", "z", "intensity")], axis=1)
        assert np.array_equal(cloud.points, expected)
        for name in ("ring", "t"):
            field = cloud.fields[name]
            assert np.array_equal(field, records[name]) and field.dtype.isnative
            assert field.flags.writeable and not np.shares_memory(field, message.data)
        assert not np.shares_memory(cloud.points, message.data)
        cloud.fields["ring"][:] = 0
        assert np.array_equal(cloud.fields["t"], records["t"])


# -- PointCloud2 layouts --------------------------------------------------------------------


def _message(records, *, height=1, big=False, row_padding=0, fields=None, stamp=(3, 500)):
    """A PointCloud2 look-alike holding a structured array."""
    dtype = records.dtype
    if fields is None:
        codes = {"i1": 1, "u1": 2, "i2": 3, "u2": 4, "i4": 5, "u4": 6, "f4": 7, "f8": 8}
        fields = []
        for name in dtype.names:
            base, offset = dtype.fields[name][:2]
            fields.append(SimpleNamespace(
                name=name, offset=offset, datatype=codes[base.base.str[1:]],
                count=base.shape[0] if base.shape else 1,
            ))  # fmt: skip
    width = len(records) // height
    rows = records.tobytes()
    step = dtype.itemsize
    data = b"".join(
        rows[r * width * step : (r + 1) * width * step] + b"\xee" * row_padding
        for r in range(height)
    )
    return SimpleNamespace(
        header=SimpleNamespace(
            stamp=SimpleNamespace(sec=stamp[0], nanosec=stamp[1]), frame_id="velo"
        ),
        height=height, width=width, fields=fields, is_bigendian=big, point_step=step,
        row_step=width * step + row_padding, data=np.frombuffer(data, np.uint8), is_dense=False,
    )  # fmt: skip


def test_layout_with_gaps_big_endian_counts_and_row_padding():
    layout = np.dtype(
        {"names": ["intensity", "z", "y", "x", "ring", "normal"],
         "formats": [">f4", ">f4", ">f4", ">f4", ">u2", (">f8", (3,))],
         "offsets": [0, 8, 12, 16, 22, 24], "itemsize": 56}
    )  # fmt: skip
    records = np.zeros(6, layout)
    records["x"] = np.arange(6) + 1
    records["y"] = -np.arange(6)
    records["z"] = 0.5
    records["intensity"] = 7
    records["ring"] = [0, 1, 2, 3, 4, 5]
    records["normal"] = np.arange(18).reshape(6, 3)
    message = _message(records, height=2, big=True, row_padding=5)
    cloud = pointcloud2_to_cloud(message)
    assert cloud.points.tolist() == [[k + 1, -k, 0.5, 7] for k in range(6)]
    assert cloud.fields["ring"].dtype == np.dtype("=u2") and cloud.fields["ring"].tolist() == list(
        range(6)
    )
    assert cloud.fields["normal"].dtype == np.float64 and cloud.fields["normal"][5].tolist() == [
        15,
        16,
        17,
    ]
    assert cloud.frame_id == "velo" and cloud.timestamp == 3.0000005
    assert cloud.dropped_zero == 0


def test_nan_and_zero_padding_of_organised_clouds():
    records = np.zeros(6, np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")]))
    records["x"] = [1, 0, np.nan, 4, 0, 0]
    records["y"][4] = 1e-30  # not padding: only exactly zero is
    message = _message(records, height=2)
    with pytest.raises(DataError, match=r"PointCloud2: 1 point\(s\) have NaN"):
        pointcloud2_to_cloud(message)
    cloud = pointcloud2_to_cloud(message, nonfinite="drop")
    assert cloud.points[:, 0].tolist() == [1, 4, 0]
    assert (cloud.dropped_nonfinite, cloud.dropped_zero) == (1, 2)
    flat = pointcloud2_to_cloud(_message(records[[0, 1, 3]]), nonfinite="drop")
    assert len(flat) == 3  # an unorganised cloud keeps exact zeros under "auto"
    assert len(pointcloud2_to_cloud(_message(records[[0, 1, 3]]), zeros="drop")) == 2


def test_zero_stamp_means_no_timestamp_and_empty_clouds():
    records = np.zeros(0, np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")]))
    cloud = pointcloud2_to_cloud(_message(records, stamp=(0, 0)))
    assert len(cloud) == 0 and cloud.timestamp is None


def _broken(**changes):
    records = np.zeros(4, np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")]))
    message = _message(records)
    for key, value in changes.items():
        setattr(message, key, value)
    return message


@pytest.mark.parametrize(
    ("changes", "error"),
    [
        ({"data": np.zeros(40, np.uint8)}, "data holds 40 bytes; 1 rows of 4 points .* need 48"),
        ({"row_step": 4}, "row_step 4 is less than width 4 x point_step 12"),
        ({"point_step": 8}, r"field 'z' \(offset 8, 4 bytes\) does not fit in point_step 8"),
        (
            {"fields": [SimpleNamespace(name="x", offset=0, datatype=9, count=1)]},
            "unknown PointField datatype 9",
        ),
        ({"fields": [SimpleNamespace(name="x", offset=0, datatype=7, count=0)]}, "count 0"),
        (
            {"fields": [SimpleNamespace(name="x", offset=0, datatype=7, count=1)] * 2},
            "appears twice",
        ),
        (
            {"fields": [SimpleNamespace(name="x", offset=0, datatype=7, count=1)]},
            r"no y/z field; the fields are \['x'\]",
        ),
        (
            {
                "fields": [
                    SimpleNamespace(name="x", offset=0, datatype=7, count=3),
                    SimpleNamespace(name="y", offset=0, datatype=7, count=1),
                    SimpleNamespace(name="z", offset=0, datatype=7, count=1),
                ]
            },
            "'x' has 3 values per point",
        ),
        ({"header": None}, "cannot read PointCloud2 message"),
    ],
)
def test_malformed_messages(changes, error):
    with pytest.raises(DataError, match=error):
        pointcloud2_to_cloud(_broken(**changes), name="bag [/t #3]")


def test_messages_built_for_both_ros_versions_decode_back():
    cloud = PointCloud(
        np.arange(12, dtype=np.float32).reshape(3, 4),
        fields={"ring": np.array([1, 2, 3], np.uint8)},
        frame_id="x",
        timestamp=12.25,
    )
    for ros1 in (True, False):
        message = cloud_to_pointcloud2(cloud, ros1=ros1)
        assert [f.name for f in message.fields] == ["x", "y", "z", "intensity", "ring"]
        assert message.point_step == 17 and message.row_step == 51
        assert pointcloud2_to_cloud(message).equals(cloud)
