"""Point-cloud files in and out: KITTI/nuScenes `.bin`, PCD, ROS bags, KITTI and Apollo side files.

:func:`read_cloud` and :func:`write_cloud` pick the format from the name (and, for
unknown names, the first bytes); the format modules hold the details and options:

* :mod:`~pytest_metamorphic.lidar.io.bin`: ``read_bin``, ``write_bin``
* :mod:`~pytest_metamorphic.lidar.io.pcd`: ``read_pcd``, ``write_pcd``, ``read_pcd_header``
* :mod:`~pytest_metamorphic.lidar.io.rosbag`: ``index_bag``, ``read_bag``, ``iter_bag``,
  ``write_bag``, ``bag_topics``, ``pointcloud2_to_cloud``, ``cloud_to_pointcloud2``
* :mod:`~pytest_metamorphic.lidar.io.kitti`: ``read_kitti_labels``, ``read_kitti_objects``,
  ``read_kitti_calibration``, ``read_kitti_dont_care``
* :mod:`~pytest_metamorphic.lidar.io.apollo`: ``read_apollo_poly``,
  ``read_apollo_roi_points``, ``read_apollo_clusters``, ``read_apollo_pose``

Every reader raises :class:`~pytest_metamorphic.core.errors.DataError` (naming the file
and what is wrong) for bad input, and nothing else.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import open_regular
from pytest_metamorphic.lidar.io._common import ZerosPolicy, check_policies
from pytest_metamorphic.lidar.io.apollo import (
    ApolloPose,
    read_apollo_clusters,
    read_apollo_poly,
    read_apollo_pose,
    read_apollo_roi_points,
)
from pytest_metamorphic.lidar.io.bin import read_bin, write_bin
from pytest_metamorphic.lidar.io.kitti import (
    KittiCalibration,
    KittiObject,
    read_kitti_calibration,
    read_kitti_dont_care,
    read_kitti_labels,
    read_kitti_objects,
)
from pytest_metamorphic.lidar.io.pcd import read_pcd, read_pcd_header, write_pcd
from pytest_metamorphic.lidar.io.rosbag import (
    BagIndex,
    bag_topics,
    index_bag,
    iter_bag,
    read_bag,
    write_bag,
)
from pytest_metamorphic.lidar.model.cloud import NonFinitePolicy, PointCloud

__all__ = [
    "ApolloPose",
    "BagIndex",
    "CloudFormat",
    "KittiCalibration",
    "KittiObject",
    "bag_topics",
    "detect_format",
    "index_bag",
    "iter_bag",
    "read_apollo_clusters",
    "read_apollo_poly",
    "read_apollo_pose",
    "read_apollo_roi_points",
    "read_bag",
    "read_bin",
    "read_cloud",
    "read_kitti_calibration",
    "read_kitti_dont_care",
    "read_kitti_labels",
    "read_kitti_objects",
    "read_pcd",
    "read_pcd_header",
    "write_bag",
    "write_bin",
    "write_cloud",
    "write_pcd",
]

CloudFormat = Literal["bin", "pcd", "bag"]
_BAG_SUFFIXES = (".bag", ".db3", ".mcap")


def detect_format(path: str | os.PathLike[str]) -> CloudFormat:
    """``"bin"``, ``"pcd"`` or ``"bag"`` for an existing file or ROS 2 bag folder.

    The suffix decides (``.bin``, ``.pcd``, ``.bag``, ``.db3``, ``.mcap``; a folder with
    ``metadata.yaml`` is a ROS 2 bag); for other names the first bytes do.
    """
    path = Path(path)
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return "bag"
        raise DataError("a folder, but not a ROS 2 bag (no metadata.yaml)", path=path)
    suffix = path.suffix.lower()
    if suffix in _BAG_SUFFIXES:
        return "bag"
    if suffix in (".bin", ".pcd"):
        return suffix[1:]  # type: ignore[return-value]
    with open_regular(path, what="recording") as handle:
        head = handle.read(1024)
    if head.startswith((b"#ROSBAG", b"\x89MCAP")) or head.startswith(b"SQLite format 3"):
        raise DataError(
            "looks like a ROS bag; rename it with its suffix (.bag, .mcap, .db3) so the "
            "bag reader can open it",
            path=path,
        )
    # A PCD header: comment lines, then VERSION or FIELDS.
    lines = (line.strip() for line in head.splitlines())
    first = next((line for line in lines if line and not line.startswith(b"#")), b"")
    if first.split(maxsplit=1)[:1] in ([b"VERSION"], [b"FIELDS"]):
        return "pcd"
    raise DataError(
        "unknown point-cloud format: expected .bin, .pcd, .bag, .db3, .mcap or a ROS 2 bag folder",
        path=path,
    )


def read_cloud(
    path: str | os.PathLike[str],
    *,
    format: CloudFormat | None = None,
    nonfinite: NonFinitePolicy = "reject",
    zeros: ZerosPolicy = "auto",
    topic: str | None = None,
    index: int = 0,
    columns: int | None = None,
) -> PointCloud:
    """Read one cloud from any supported file.

    Parameters
    ----------
    path : path-like
    format : {"bin", "pcd", "bag"}, optional
      Default: :func:`detect_format`.
    nonfinite : {"reject", "drop"}
      NaN/inf points raise DataError, or are dropped and counted.
    zeros : {"auto", "drop", "keep"}
      x = y = z = 0 padding of organised scans (PCD, PointCloud2); not for ``.bin``.
    topic, index
      Bags only: which PointCloud2 topic (default: the only one) and message.
    columns
      ``.bin`` only: float32 values per point (default: 5 for ``*.pcd.bin``, else 4).
    """
    check_policies(nonfinite, zeros)
    chosen = detect_format(path) if format is None else format
    if chosen not in ("bin", "pcd", "bag"):
        raise InvalidArgument(f"format={format!r} must be 'bin', 'pcd' or 'bag'")
    if chosen != "bag" and (topic is not None or index != 0):
        raise InvalidArgument(f"topic= and index= apply to bags, not to a {chosen} file")
    if chosen != "bin" and columns is not None:
        raise InvalidArgument(f"columns= applies to .bin files, not to a {chosen} file")
    if chosen == "bin":
        if zeros == "drop":
            raise InvalidArgument(".bin files are never organised; zeros='drop' is not supported")
        return read_bin(path, columns=columns, nonfinite=nonfinite)
    if chosen == "pcd":
        return read_pcd(path, nonfinite=nonfinite, zeros=zeros)
    return read_bag(path, topic=topic, index=index, nonfinite=nonfinite, zeros=zeros)


def write_cloud(
    cloud: PointCloud,
    path: str | os.PathLike[str],
    *,
    format: CloudFormat | None = None,
    overwrite: bool = False,
    topic: str = "/points",
) -> Path:
    """Write a cloud so that :func:`read_cloud` gives it back.

    The suffix picks the format: ``.pcd`` (binary PCD, every field), ``.bin`` (KITTI;
    ``*.pcd.bin``: nuScenes with the ``ring`` field), ``.bag`` (ROS 1 bag with one
    PointCloud2 on ``topic``); with ``format="bag"`` and no suffix, a ROS 2 sqlite3 bag
    folder. Use the format modules' writers for their other options.
    """
    target = Path(path)
    if format is None:
        suffix = target.suffix.lower()
        if suffix not in (".pcd", ".bin", ".bag"):
            raise InvalidArgument(
                f"cannot tell the format of {str(target)!r} from its suffix; use .pcd, .bin, "
                ".bag, or pass format='bag' for a ROS 2 bag folder"
            )
        format = "bag" if suffix == ".bag" else suffix[1:]  # type: ignore[assignment]
    if format == "pcd":
        return write_pcd(cloud, target, overwrite=overwrite)
    if format == "bin":
        return write_bin(cloud, target, overwrite=overwrite)
    if format == "bag":
        return write_bag(cloud, target, topic=topic, overwrite=overwrite)
    raise InvalidArgument(f"format={format!r} must be 'bin', 'pcd' or 'bag'")
