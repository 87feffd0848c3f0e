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

Modules: :mod:`.typestore` (rosbags type stores, with the Velodyne packet types),
:mod:`.reader` (indexing and reading bags, capped), :mod:`.pointcloud2` (PointCloud2
messages to and from clouds) and :mod:`.writer` (:func:`write_bag`).
"""

from pytest_metamorphic.lidar.io.rosbag.pointcloud2 import (
    cloud_to_pointcloud2,
    pointcloud2_to_cloud,
)
from pytest_metamorphic.lidar.io.rosbag.reader import (
    BagIndex,
    bag_topics,
    index_bag,
    iter_bag,
    read_bag,
)
from pytest_metamorphic.lidar.io.rosbag.typestore import POINTCLOUD2, BagStorage
from pytest_metamorphic.lidar.io.rosbag.writer import write_bag

__all__ = [
    "POINTCLOUD2",
    "BagIndex",
    "BagStorage",
    "bag_topics",
    "cloud_to_pointcloud2",
    "index_bag",
    "iter_bag",
    "pointcloud2_to_cloud",
    "read_bag",
    "write_bag",
]
