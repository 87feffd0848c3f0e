"""``frames()``: draw real LiDAR frames from recordings, lazily.

The strategy indexes its source when it is built (a sorted file list, or a bag's message
index: cheap, and every "nothing to draw" problem is reported right there), then loads
frames only when Hypothesis draws them, keeping the last few in a small LRU cache.
Frames are drawn by index with ``st.integers(0, n - 1)``, so failures shrink toward the
first frame of the recording.
"""

from __future__ import annotations

import os
from typing import Any, Literal

from hypothesis import strategies as st

from pytest_metamorphic.lidar.io._common import ZerosPolicy
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.model.cloud import NonFinitePolicy
from pytest_metamorphic.lidar.model.frame import Frame

__all__ = ["frames"]

_CLOUD_SUFFIXES = (".bin", ".pcd")
_BAG_SUFFIXES = (".bag", ".db3", ".mcap")


def frames(
    path_or_glob: str | os.PathLike[str],
    *,
    topic: str | None = None,
    roi: Any = None,
    labels: bool | Literal["auto"] = "auto",
    nonfinite: NonFinitePolicy = "reject",
    zeros: ZerosPolicy = "auto",
    cache_size: int = 4,
) -> st.SearchStrategy[Frame]:
    """A strategy drawing :class:`~pytest_metamorphic.lidar.model.frame.Frame` objects from files.

    Parameters
    ----------
    path_or_glob : str or path-like
      One of:

      * a bag (``*.bag``, ``*.db3``, ``*.mcap``, or a ROS 2 bag folder): one frame per
        PointCloud2 message on ``topic``;
      * a KITTI folder (``training``/``testing``, or any folder holding ``velodyne/``):
        the sorted ``velodyne/*.bin``, with ground truth from ``label_2/`` + ``calib/``;
      * any other folder: its sorted ``*.bin``, ``*.pcd`` and bag files;
      * a single cloud file;
      * a glob pattern (``**`` allowed), e.g. ``"data/*/velodyne/*.bin"``.
    topic : str, optional
      PointCloud2 topic for bags (default: the bag's only PointCloud2 topic).
    roi : object, optional
      Attached as is to every frame (e.g. an ``ROI`` built from the map of the drive).
    labels : bool or "auto"
      Ground-truth boxes from KITTI ``label_2``/``calib`` files beside ``velodyne``:
      ``"auto"`` attaches them where both files exist, ``True`` requires them for every
      frame (checked now), ``False`` never loads them.
    nonfinite, zeros
      Reader policies for NaN points and the zero padding of organised scans (see
      :func:`~pytest_metamorphic.lidar.io.read_cloud`).
    cache_size : int
      Frames kept in memory (least recently drawn first out). Memory is bounded by
      ``cache_size`` times the largest frame: about 2 MB for a KITTI HDL-64E sweep, so
      ~8 MB at the default 4. Cached frames are shared between examples, so their arrays
      are made read-only: a system under test that edits its input in place gets an error
      instead of silently corrupting later examples.

    Raises
    ------
    InvalidArgument
      Nothing matches ``path_or_glob``; a bad option; ``labels=True`` without labels.
    DataError
      A bag cannot be read, has no such topic, or the topic holds no PointCloud2 (the
      message lists the topics there are).
    """
    catalog = FrameCatalog(
        path_or_glob,
        topic=topic,
        roi=roi,
        labels=labels,
        nonfinite=nonfinite,
        zeros=zeros,
        cache_size=cache_size,
    )
    return st.integers(0, len(catalog) - 1).map(catalog.load)
