"""Reading bags: a capped opener, topics and connections, the frame index, cached deserializers."""

from __future__ import annotations

import bisect
import contextlib
import functools
import heapq
import io
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import check_regular
from pytest_metamorphic.lidar.io._common import (
    ZerosPolicy,
    check_policies,
    wrap_errors,
)
from pytest_metamorphic.lidar.io.rosbag.pointcloud2 import pointcloud2_to_cloud
from pytest_metamorphic.lidar.io.rosbag.typestore import POINTCLOUD2, _typestore
from pytest_metamorphic.lidar.model.cloud import NonFinitePolicy, PointCloud

__all__ = ["BagIndex", "bag_topics", "index_bag", "iter_bag", "read_bag"]


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

    def open(self, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        if mode == "rb" and not args and not kwargs:
            return _CappedReader(io.FileIO(self, "rb"))
        return super().open(mode, *args, **kwargs)


@contextlib.contextmanager
def _open(path: Path) -> Iterator[Any]:
    """An open rosbags AnyReader; every parser failure becomes a DataError."""
    from rosbags.highlevel import AnyReader

    if not path.exists():
        raise DataError("no such bag (file or ROS 2 bag folder)", path=path)
    # rosbags opens the files itself: a FIFO among them would block it forever.
    if path.is_dir():
        for part in sorted(path.iterdir()):
            if part.name == "metadata.yaml" or part.suffix.lower() in (".db3", ".mcap"):
                check_regular(part, what="bag file")
    else:
        check_regular(path, what="bag")
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
