"""Writing clouds to ROS 1 bags and ROS 2 sqlite3 or MCAP bags."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.io._common import (
    replacing,
)
from pytest_metamorphic.lidar.io.rosbag.pointcloud2 import cloud_to_pointcloud2
from pytest_metamorphic.lidar.io.rosbag.typestore import POINTCLOUD2, BagStorage, _typestore
from pytest_metamorphic.lidar.model.cloud import PointCloud

__all__ = ["write_bag"]


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
    with replacing(target, overwrite=overwrite, what="ROS bag") as temporary:
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
        from rosbags.rosbag1 import Writer as Writer1

        return Writer1(path)
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    return Writer2(path, version=8, storage_plugin=plugin)
