"""``frames()``: draw real LiDAR frames from recordings, lazily.

The strategy indexes its source when it is built (a sorted file list, or a bag's message
index: cheap, and every "nothing to draw" problem is reported right there), then loads
frames only when Hypothesis draws them, keeping the last few in a small LRU cache.
Frames are drawn by index with ``st.integers(0, n - 1)``, so failures shrink toward the
first frame of the recording.

A relative path is looked for beside the file that calls ``frames()`` first (a test
file's data lives next to it, as pytest's own ``request.path`` and data-folder plugins
have it), then in the working directory: ``frames("recordings/*.pcd")`` in
``tests/test_perception.py`` finds ``tests/recordings/`` whether pytest runs from the
repository root (as CI does) or from ``tests/``. The error names both folders.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Literal

from hypothesis import strategies as st

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.globbing import expand
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

      Relative to the folder of the file that calls ``frames()`` (your test file) when
      it matches there, else to the working directory.
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
    try:
        where = _beside_caller(path_or_glob, _calling_file())
    except TypeError:
        where = path_or_glob  # not a path: FrameCatalog names the argument
    try:
        catalog = FrameCatalog(
            where,
            topic=topic,
            roi=roi,
            labels=labels,
            nonfinite=nonfinite,
            zeros=zeros,
            cache_size=cache_size,
        )
    except InvalidArgument as error:
        raise _searched(error, path_or_glob) from None
    return st.integers(0, len(catalog) - 1).map(catalog.load)


_PACKAGE = Path(__file__).resolve().parent.parent


def _calling_file() -> Path | None:
    """The file of the first caller outside this package (the user's test module)."""
    frame = sys._getframe(1)
    while frame is not None:
        name = frame.f_globals.get("__file__")
        if name and not Path(name).resolve().is_relative_to(_PACKAGE):
            return Path(name).resolve()
        frame = frame.f_back  # type: ignore[assignment]
    return None


def _beside_caller(path_or_glob: Any, caller: Path | None) -> Any:
    """``path_or_glob`` beside ``caller`` when it is relative and matches there."""
    text = os.fspath(path_or_glob)
    if caller is None or os.path.isabs(text):
        return path_or_glob
    beside = caller.parent / text
    if beside.exists() or expand(str(beside)):
        return str(beside)
    return path_or_glob


def _searched(error: InvalidArgument, path_or_glob: Any) -> InvalidArgument:
    """``error`` naming the folders a relative path was looked for in, when nothing
    matched (the message says "no such file")."""
    try:
        text = os.fspath(path_or_glob)
    except TypeError:
        return error
    if "no such file" not in str(error) or os.path.isabs(text):
        return error
    caller = _calling_file()
    folders = [str(caller.parent)] if caller is not None else []
    folders.append(f"the working directory {Path.cwd()}")
    return InvalidArgument(f"{error} (looked in {' and in '.join(folders)})")
