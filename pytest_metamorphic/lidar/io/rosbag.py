"""``sensor_msgs/PointCloud2`` in ROS 1 ``.bag`` and ROS 2 (sqlite3 ``.db3`` / ``.mcap``) bags.

Everything goes through `rosbags <https://gitlab.com/ternaris/rosbags>`_ (pure Python, no
ROS install). Reading:

* :func:`index_bag` lists the PointCloud2 messages of one topic without decoding them
  (for ROS 1 from the bag's own index, without reading message data; for ROS 2 by one
  pass over that topic's rows). :meth:`BagIndex.read` then loads message ``i`` alone by
  seeking to its timestamp, so memory stays at one message whatever the bag size.
* :func:`pointcloud2_to_cloud` decodes any field layout (any offsets and point_step,
  padding, either endianness, ``count`` > 1, row padding) through one structured-dtype
  view of the data buffer. Organised scans (height > 1) lose their padding: NaN points by
  the ``nonfinite`` policy, points at x = y = z = 0 exactly by the ``zeros`` policy, both
  counted on the cloud.

Writing (:func:`write_bag`) produces a ROS 1 bag (``*.bag``) or a ROS 2 bag folder in
sqlite3 or MCAP storage, one PointCloud2 per cloud, which RViz (after ``rosbag play`` /
``ros2 bag play``) and Foxglove open. Reading it back gives equal clouds: points, fields
and their dtypes, frame id and timestamp (to the nanosecond; a cloud without a timestamp
is written with stamp 0, which reads back as None, ROS's "unset").

Every failure of the underlying parsers on a corrupt bag becomes a
:class:`~pytest_metamorphic.core.errors.DataError` naming the bag.
"""

from __future__ import annotations

import bisect
import contextlib
import functools
import heapq
import io
import math
import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.cloud import NonFinitePolicy, PointCloud
from pytest_metamorphic.lidar.io._common import (
    ZerosPolicy,
    check_policies,
    cloud_from_records,
    records_from_cloud,
    replacing,
    wrap_errors,
)

__all__ = [
    "POINTCLOUD2",
    "BagIndex",
    "bag_topics",
    "cloud_to_pointcloud2",
    "index_bag",
    "iter_bag",
    "pointcloud2_to_cloud",
    "read_bag",
    "write_bag",
]

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
BagStorage = Literal["rosbag1", "sqlite3", "mcap"]

# sensor_msgs/PointField datatype codes.
_DATATYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_CODES = {code: datatype for datatype, code in _DATATYPES.items()}

# Packet types of the Velodyne driver, so bags recorded before drivers embedded their
# message definitions (ROS 2 before Iron) can at least be opened and listed.
_VELODYNE_MSGS = {
    "velodyne_msgs/msg/VelodynePacket": "builtin_interfaces/Time stamp\nuint8[1206] data",
    "velodyne_msgs/msg/VelodyneScan": "std_msgs/Header header\nVelodynePacket[] packets",
}


@functools.cache
def _typestore(ros1: bool) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types: dict = {}
    for name, text in _VELODYNE_MSGS.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


# -- reading ----------------------------------------------------------------------------


class _CappedReader(io.BufferedReader):
    """A binary file whose ``read(n)`` never asks for more bytes than are left.

    rosbags trusts the length fields it reads (``src.read(size)``), and Python allocates
    ``size`` bytes before reading; a corrupt 4-byte length would cost gigabytes before
    the short read is noticed. Capping the request changes no result: the read comes
    back short either way and rosbags reports the truncation.
    """

    def __init__(self, raw: io.FileIO) -> None:
        super().__init__(raw)
        self._end = os.fstat(raw.fileno()).st_size

    def read(self, size: int | None = -1) -> bytes:
        if size is not None and size > 0:
            size = min(size, max(self._end - self.tell(), 0))
        return super().read(size)


class _CappedPath(type(Path())):  # type: ignore[misc]
    """The path handed to rosbags: opened for binary reading, it gives a _CappedReader."""

    def open(self, mode: str = "r", *args: Any, **kwargs: Any) -> Any:  # type: ignore[override]
        if mode == "rb" and not args and not kwargs:
            return _CappedReader(io.FileIO(self, "rb"))
        return super().open(mode, *args, **kwargs)


@contextlib.contextmanager
def _open(path: Path) -> Iterator[Any]:
    """An open rosbags AnyReader; every parser failure becomes a DataError."""
    from rosbags.highlevel import AnyReader

    if not path.exists():
        raise DataError("no such bag (file or ROS 2 bag folder)", path=path)
    with wrap_errors(path, "bag"):
        try:
            reader = AnyReader([_CappedPath(path)], default_typestore=_typestore(ros1=False))
            reader.open()
        except Exception as error:
            if "Profile is not ros2" in str(error):
                raise DataError(
                    "this MCAP file uses the ros1 profile, which rosbags cannot read; "
                    "convert it to a ROS 1 .bag or a ROS 2 MCAP first",
                    path=path,
                ) from error
            raise
    try:
        with wrap_errors(path, "bag"):
            yield reader
    finally:
        with contextlib.suppress(Exception):
            reader.close()


def _describe_topics(reader: Any) -> str:
    topics = sorted(reader.topics.items())
    if not topics:
        return "the bag has no topics"
    return "topics: " + ", ".join(
        f"{name} ({info.msgtype}, {info.msgcount} messages)" for name, info in topics
    )


def _connections(reader: Any, topic: str | None, path: Path) -> tuple[str, list[Any]]:
    clouds = sorted({c.topic for c in reader.connections if c.msgtype == POINTCLOUD2})
    if topic is None:
        if not clouds:
            raise DataError(
                f"no {POINTCLOUD2} topic in this bag; {_describe_topics(reader)}", path=path
            )
        if len(clouds) > 1:
            raise InvalidArgument(
                f"{path} has several {POINTCLOUD2} topics ({', '.join(clouds)}); pass topic="
            )
        topic = clouds[0]
    if not isinstance(topic, str):
        raise InvalidArgument(f"topic={topic!r} must be a string")
    chosen = [c for c in reader.connections if c.topic == topic]
    listed = ", ".join(clouds) if clouds else "none"
    if not chosen:
        raise DataError(
            f"no topic {topic!r} in this bag; {POINTCLOUD2} topics: {listed}; "
            f"{_describe_topics(reader)}",
            path=path,
        )
    other = sorted({c.msgtype for c in chosen if c.msgtype != POINTCLOUD2})
    if other:
        raise DataError(
            f"no {POINTCLOUD2} on topic {topic!r}: it holds {', '.join(other)}; "
            f"{POINTCLOUD2} topics in this bag: {listed}",
            path=path,
        )
    return topic, chosen


def _timestamps(reader: Any, connections: list[Any]) -> list[int]:
    if not reader.is2:
        # ROS 1 bags carry a per-connection index: times without touching message data.
        (bag,) = reader.readers
        merged = heapq.merge(*(bag.indexes[c.id] for c in connections))
        return [entry.time for entry in merged]
    return [timestamp for _, timestamp, _ in reader.messages(connections=connections)]


@dataclass(frozen=True)
class BagIndex:
    """The PointCloud2 messages of one topic in one bag, loadable one at a time.

    Attributes
    ----------
    path : Path
      The ``.bag`` file, ROS 2 bag folder, or ``.db3`` / ``.mcap`` storage file.
    topic : str
    timestamps : tuple of int
      Log times in nanoseconds, in reading order (messages are read by seeking here).
    """

    path: Path
    topic: str
    timestamps: tuple[int, ...]

    def __len__(self) -> int:
        return len(self.timestamps)

    def read(
        self, index: int, *, nonfinite: NonFinitePolicy = "reject", zeros: ZerosPolicy = "auto"
    ) -> PointCloud:
        """Load and decode message ``index`` (0-based; negative counts from the end)."""
        check_policies(nonfinite, zeros)
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
            raise InvalidArgument(f"index={index!r} must be an integer")
        count = len(self.timestamps)
        if not -count <= index < count:
            raise InvalidArgument(
                f"index={index} is out of range: {self.path} has {count} messages on {self.topic}"
            )
        index = int(index) % count
        stamp = self.timestamps[index]
        # Messages sharing a log time come back in the same order as when indexing.
        rank = index - bisect.bisect_left(self.timestamps, stamp)
        with _open(self.path) as reader:
            _, connections = _connections(reader, self.topic, self.path)
            found = reader.messages(connections=connections, start=stamp, stop=stamp + 1)
            for position, (_, _, raw) in enumerate(found):
                if position == rank:
                    name = f"{self.path} [{self.topic} #{index}]"
                    return _decode(_deserializer(reader), raw, name, nonfinite, zeros)
        raise DataError(f"message {index} on {self.topic} vanished since indexing", path=self.path)

    def __iter__(self) -> Iterator[PointCloud]:
        """Every message in order, in one pass (policies: reject NaN, auto zeros)."""
        return self.iterate()

    def iterate(
        self, *, nonfinite: NonFinitePolicy = "reject", zeros: ZerosPolicy = "auto"
    ) -> Iterator[PointCloud]:
        """Every message in order, in one pass over the bag."""
        check_policies(nonfinite, zeros)
        return _iterate(self.path, self.topic, nonfinite, zeros)


def _iterate(
    path: Path, topic: str | None, nonfinite: NonFinitePolicy, zeros: ZerosPolicy
) -> Iterator[PointCloud]:
    with _open(path) as reader:
        topic, connections = _connections(reader, topic, path)
        deserialize = _deserializer(reader)
        for index, (_, _, raw) in enumerate(reader.messages(connections=connections)):
            name = f"{path} [{topic} #{index}]"
            yield _decode(deserialize, raw, name, nonfinite, zeros)


def _decode(
    deserialize: Callable[[bytes], Any], raw: bytes, name: str, nonfinite: str, zeros: str
) -> PointCloud:
    with wrap_errors(name, "PointCloud2 message"):
        message = deserialize(raw)
    return pointcloud2_to_cloud(message, name=name, nonfinite=nonfinite, zeros=zeros)  # type: ignore[arg-type]


def _deserializer(reader: Any) -> Callable[[bytes], Any]:
    """How to deserialize this bag's PointCloud2 messages.

    rosbags builds a new typestore for every bag it opens, and the first message of a
    type costs ~8 ms of code generation in each (more than decoding a 131 072-point
    message). When the bag defines PointCloud2 exactly as our cached typestore does (the
    same type hash, which covers the nested types), that store's deserializer, generated
    once per process, does the same work.
    """
    ros1 = not reader.is2
    try:
        same = reader.typestore.hash_rihs01(POINTCLOUD2) == _type_hash(ros1, POINTCLOUD2)
    except Exception:  # a definition rosbags cannot hash: let it deserialize (or fail) itself
        same = False
    if same:
        store = _typestore(ros1)
        method = store.deserialize_ros1 if ros1 else store.deserialize_cdr
        return functools.partial(method, typename=POINTCLOUD2)
    return functools.partial(reader.deserialize, typ=POINTCLOUD2)


@functools.cache
def _type_hash(ros1: bool, msgtype: str) -> str:
    return _typestore(ros1).hash_rihs01(msgtype)


def index_bag(path: str | os.PathLike[str], *, topic: str | None = None) -> BagIndex:
    """Index the PointCloud2 messages of ``topic`` (default: the bag's only such topic).

    Raises
    ------
    DataError
      Unreadable or corrupt bag; no such topic; the topic is not PointCloud2 (the message
      names its type and lists the PointCloud2 topics there are); no PointCloud2 at all.
    InvalidArgument
      ``topic=None`` but the bag has several PointCloud2 topics.
    """
    path = Path(path)
    with _open(path) as reader:
        topic, connections = _connections(reader, topic, path)
        stamps = tuple(_timestamps(reader, connections))
    return BagIndex(path, topic, stamps)


def read_bag(
    path: str | os.PathLike[str],
    *,
    topic: str | None = None,
    index: int = 0,
    nonfinite: NonFinitePolicy = "reject",
    zeros: ZerosPolicy = "auto",
) -> PointCloud:
    """Read PointCloud2 message ``index`` of ``topic`` as a cloud."""
    return index_bag(path, topic=topic).read(index, nonfinite=nonfinite, zeros=zeros)


def iter_bag(
    path: str | os.PathLike[str],
    *,
    topic: str | None = None,
    nonfinite: NonFinitePolicy = "reject",
    zeros: ZerosPolicy = "auto",
) -> Iterator[PointCloud]:
    """Yield every PointCloud2 of ``topic`` in order, one message in memory at a time.

    The bag is opened once, when iteration starts; errors about the bag or topic are
    raised then; bad arguments are raised at once.
    """
    check_policies(nonfinite, zeros)
    return _iterate(Path(path), topic, nonfinite, zeros)


def bag_topics(path: str | os.PathLike[str]) -> dict[str, tuple[str | None, int]]:
    """``{topic: (message type, message count)}`` of a bag."""
    path = Path(path)
    with _open(path) as reader:
        return {name: (info.msgtype, info.msgcount) for name, info in reader.topics.items()}


def pointcloud2_to_cloud(
    message: Any,
    *,
    name: str = "PointCloud2",
    nonfinite: NonFinitePolicy = "reject",
    zeros: ZerosPolicy = "auto",
) -> PointCloud:
    """Decode a ``sensor_msgs/PointCloud2`` (a rosbags message object or look-alike).

    Parameters
    ----------
    message
      Has ``header`` (``stamp.sec``, ``stamp.nanosec``, ``frame_id``), ``height``,
      ``width``, ``fields`` (``name``, ``offset``, ``datatype``, ``count``),
      ``is_bigendian``, ``point_step``, ``row_step`` and ``data`` (uint8 buffer).
    name : str
      Named in errors (the bag, topic and message number).
    nonfinite, zeros
      As for :func:`~pytest_metamorphic.lidar.io.pcd.read_pcd`; ``zeros="auto"`` drops
      the x = y = z = 0 padding of organised clouds (height > 1).

    Returns
    -------
    PointCloud
      x, y, z, intensity (0 when there is no intensity field) and every other field with
      its own dtype in native byte order; frame id; timestamp in seconds (None for 0).
    """
    check_policies(nonfinite, zeros)
    with wrap_errors(name, "PointCloud2 message"):
        height, width = int(message.height), int(message.width)
        point_step, row_step = int(message.point_step), int(message.row_step)
        data = message.data
        if isinstance(data, (bytes, bytearray, memoryview)):
            data = np.frombuffer(data, np.uint8)
        data = np.asarray(data, np.uint8).reshape(-1)
        order = ">" if message.is_bigendian else "<"
        layout = [
            (str(f.name), int(f.offset), int(f.datatype), int(f.count)) for f in message.fields
        ]
        frame_id = str(message.header.frame_id)
        stamp = (int(message.header.stamp.sec), int(message.header.stamp.nanosec))
    dtype = _record_dtype(layout, order, point_step, name)
    count = height * width
    if count and (row_step < width * point_step):
        raise DataError(
            f"row_step {row_step} is less than width {width} x point_step {point_step}", path=name
        )
    needed = (height - 1) * row_step + width * point_step if count else 0
    if len(data) < needed:
        raise DataError(
            f"data holds {len(data)} bytes; {height} rows of {width} points "
            f"(row_step {row_step}, point_step {point_step}) need {needed}",
            path=name,
        )
    owned = True  # the records below are a fresh array, not a view of the message
    if not count:
        records = np.empty(0, dtype)
    elif height == 1 or row_step == width * point_step:
        records, owned = np.frombuffer(data, dtype, count), False
    else:  # rows padded beyond width * point_step: gather the rows, then view them
        rows = np.lib.stride_tricks.as_strided(
            data, (height, width * point_step), (row_step, 1), writeable=False
        )
        records = np.ascontiguousarray(rows).view(dtype).reshape(-1)
    seconds = stamp[0] + stamp[1] / 1e9 if stamp != (0, 0) else None
    return cloud_from_records(
        records,
        name=name,
        organised=height > 1,
        nonfinite=nonfinite,
        zeros=zeros,
        frame_id=frame_id,
        timestamp=seconds,
        owned=owned,
    )


def _record_dtype(
    layout: list[tuple[str, int, int, int]], order: str, point_step: int, name: str
) -> np.dtype:
    names, formats, offsets = [], [], []
    for field, offset, datatype, count in layout:
        if datatype not in _DATATYPES:
            raise DataError(
                f"field {field!r} has unknown PointField datatype {datatype}", path=name
            )
        if count < 1:
            raise DataError(f"field {field!r} has count {count}", path=name)
        code = order + _DATATYPES[datatype]
        size = np.dtype(code).itemsize * count
        if offset < 0 or offset + size > point_step:
            raise DataError(
                f"field {field!r} (offset {offset}, {size} bytes) does not fit in "
                f"point_step {point_step}",
                path=name,
            )
        if field in names:
            raise DataError(f"field {field!r} appears twice", path=name)
        names.append(field)
        formats.append(code if count == 1 else (code, (count,)))
        offsets.append(offset)
    with wrap_errors(name, "PointCloud2 field layout"):
        return np.dtype(
            {"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step}
        )


# -- writing ----------------------------------------------------------------------------


def cloud_to_pointcloud2(cloud: PointCloud, *, ros1: bool = False) -> Any:
    """A rosbags ``sensor_msgs/msg/PointCloud2`` (ROS 1 Noetic or ROS 2 Humble types).

    Unorganised (height 1), little-endian, dense; fields x, y, z, intensity (FLOAT32)
    then the cloud's extra fields (int8..uint32, float32, float64; a 2-D field becomes
    one PointField with ``count`` k).
    """
    records = records_from_cloud(cloud, allowed="i1 u1 i2 u2 i4 u4 f4 f8", fmt="PointCloud2")
    store = _typestore(ros1)
    types = store.types
    fields = []
    for key in records.dtype.names:
        base, offset = records.dtype.fields[key][0], records.dtype.fields[key][1]
        shape = base.shape
        fields.append(
            types["sensor_msgs/msg/PointField"](
                name=key,
                offset=offset,
                datatype=_CODES[base.base.str[1:]],
                count=shape[0] if shape else 1,
            )
        )
    sec, nanosec = _split_stamp(cloud.timestamp)
    header_args: dict[str, Any] = {
        "stamp": types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
        "frame_id": cloud.frame_id,
    }
    if ros1:
        header_args["seq"] = 0
    step = records.dtype.itemsize
    return types[POINTCLOUD2](
        header=types["std_msgs/msg/Header"](**header_args),
        height=1,
        width=len(records),
        fields=fields,
        is_bigendian=False,
        point_step=step,
        row_step=step * len(records),
        data=records.view(np.uint8).reshape(-1) if len(records) else np.empty(0, np.uint8),
        is_dense=True,
    )


def _split_stamp(timestamp: float | None) -> tuple[int, int]:
    if timestamp is None:
        return 0, 0
    # ROS 2 stores seconds as int32 (ROS 1 as uint32): the common range.
    if not (0 <= timestamp < 2**31):
        raise InvalidArgument(f"timestamp {timestamp} cannot be a ROS time (0 .. 2**31 s)")
    sec = math.floor(timestamp)
    nanosec = round((timestamp - sec) * 1e9)
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return sec, nanosec


def write_bag(
    clouds: PointCloud | Iterable[PointCloud],
    path: str | os.PathLike[str],
    *,
    topic: str = "/points",
    storage: BagStorage | None = None,
    overwrite: bool = False,
) -> Path:
    """Write clouds as PointCloud2 messages, in order, to a new bag.

    Parameters
    ----------
    clouds : PointCloud or iterable of PointCloud
      Consumed one at a time (a generator keeps memory at one cloud).
    path : path-like
      ``*.bag``: a ROS 1 bag file. Anything else: a ROS 2 bag folder (name it without a
      suffix, e.g. ``failure_0001``; the storage file inside is named after it).
    topic : str
      Absolute topic name.
    storage : {"rosbag1", "sqlite3", "mcap"}, optional
      Default: ``rosbag1`` for ``*.bag``, else ``sqlite3`` (the storage every ROS 2
      distribution ships). Choose ``mcap`` for Foxglove, which opens the ``.mcap`` file
      inside. rosbags writes bag metadata version 8: distributions older than that
      format (Humble) may refuse ``metadata.yaml``; delete it and run
      ``ros2 bag reindex`` there, or use a ROS 1 bag.
    overwrite : bool
      Replace an existing bag.

    Notes
    -----
    Header stamps count nanoseconds: a timestamp is rounded to the nearest nanosecond
    (so any timestamp read from a bag comes back exactly). The log time of each message
    is its stamp, bumped by 1 ns where needed so log times strictly increase (readers
    return messages in log-time order, so the written order is the read order). Clouds
    without a timestamp get stamp 0.
    """
    target = Path(path)
    if storage is None:
        storage = "rosbag1" if target.suffix == ".bag" else "sqlite3"
    if storage not in ("rosbag1", "sqlite3", "mcap"):
        raise InvalidArgument(f"storage={storage!r} must be 'rosbag1', 'sqlite3' or 'mcap'")
    if (storage == "rosbag1") != (target.suffix == ".bag"):
        raise InvalidArgument(
            f"path {str(target)!r} and storage={storage!r} disagree: ROS 1 bags are '*.bag' "
            "files, ROS 2 bags are folders named without a suffix"
        )
    if target.suffix in (".db3", ".mcap"):
        raise InvalidArgument(
            f"ROS 2 bags are folders: pass a folder name such as {target.stem!r} with "
            f"storage={storage!r}, not {target.name!r}"
        )
    if not isinstance(topic, str) or not topic.startswith("/") or len(topic) < 2:
        raise InvalidArgument(f"topic={topic!r} must be an absolute topic name like '/points'")
    items = [clouds] if isinstance(clouds, PointCloud) else clouds
    ros1 = storage == "rosbag1"
    store = _typestore(ros1)
    with replacing(target, overwrite=overwrite) as temporary:
        writer = _writer(temporary, storage)
        with writer:
            connection = writer.add_connection(topic, POINTCLOUD2, typestore=store)
            last = -1
            for position, cloud in enumerate(items):
                if not isinstance(cloud, PointCloud):
                    raise InvalidArgument(
                        f"clouds[{position}] is {type(cloud).__name__}, not PointCloud"
                    )
                message = cloud_to_pointcloud2(cloud, ros1=ros1)
                stamp = message.header.stamp
                last = max(stamp.sec * 1_000_000_000 + stamp.nanosec, last + 1)
                raw = (
                    store.serialize_ros1(message, POINTCLOUD2)
                    if ros1
                    else store.serialize_cdr(message, POINTCLOUD2)
                )
                writer.write(connection, last, raw)
    return target


def _writer(path: Path, storage: str) -> Any:
    if storage == "rosbag1":
        from rosbags.rosbag1 import Writer

        return Writer(path)
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    return Writer(path, version=8, storage_plugin=plugin)
