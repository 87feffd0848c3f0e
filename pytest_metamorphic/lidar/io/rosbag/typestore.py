"""rosbags type stores for ROS 1 and ROS 2, with the Velodyne driver's packet types registered."""

from __future__ import annotations

import functools
from typing import Any, Literal

__all__ = ["POINTCLOUD2", "BagStorage"]

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
BagStorage = Literal["rosbag1", "sqlite3", "mcap"]


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
    types: dict[str, Any] = {}
    for name, text in _VELODYNE_MSGS.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store
