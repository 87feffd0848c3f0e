"""``frames()``: draw real LiDAR frames from recordings, lazily.

The strategy indexes its source when it is built (a sorted file list, or a bag's message
index: cheap, and every "nothing to draw" problem is reported right there), then loads
frames only when Hypothesis draws them, keeping the last few in a small LRU cache.
Frames are drawn by index with ``st.integers(0, n - 1)``, so failures shrink toward the
first frame of the recording.
"""

from __future__ import annotations

import bisect
import functools
import glob
import os
import sys
import types
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

from hypothesis import strategies as st

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.cloud import NonFinitePolicy, PointCloud
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.io import detect_format, read_cloud, read_kitti_labels
from pytest_metamorphic.lidar.io._common import ZerosPolicy, check_policies
from pytest_metamorphic.lidar.io.rosbag import BagIndex, index_bag

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
    """A strategy drawing :class:`~pytest_metamorphic.lidar.frame.Frame` objects from files.

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
    check_policies(nonfinite, zeros)
    if labels not in (True, False, "auto"):
        raise InvalidArgument(f"labels={labels!r} must be True, False or 'auto'")
    if isinstance(cache_size, bool) or not isinstance(cache_size, int) or cache_size < 1:
        raise InvalidArgument(f"cache_size={cache_size!r} must be a positive integer")
    if topic is not None and not isinstance(topic, str):
        raise InvalidArgument(f"topic={topic!r} must be a string")
    catalog = _Catalog(
        str(os.fspath(path_or_glob)),
        topic=topic,
        roi=roi,
        labels=labels,
        nonfinite=nonfinite,
        zeros=zeros,
        cache_size=cache_size,
    )
    return st.integers(0, len(catalog) - 1).map(catalog.load)


class _Catalog:
    """The frames of one ``frames()`` call: sources, their sizes, and a bounded cache."""

    def __init__(
        self,
        spec: str,
        *,
        topic: str | None,
        roi: Any,
        labels: bool | str,
        nonfinite: NonFinitePolicy,
        zeros: ZerosPolicy,
        cache_size: int,
    ) -> None:
        self.spec = spec
        self.roi = roi
        self.labels = labels
        self.options: dict[str, Any] = {"nonfinite": nonfinite, "zeros": zeros}
        self.sources: list[Path | BagIndex] = []
        for path in _expand(spec):
            if _is_bag(path):
                self.sources.append(index_bag(path, topic=topic))
            elif topic is not None:
                raise InvalidArgument(f"topic={topic!r} given, but {path} is not a bag")
            else:
                self.sources.append(path)
        self.starts: list[int] = []
        total = 0
        for source in self.sources:
            self.starts.append(total)
            total += len(source) if isinstance(source, BagIndex) else 1
        if total == 0:
            raise DataError(f"no PointCloud2 messages on {topic or 'the topic'}", path=spec)
        self.total = total
        if labels is True:
            missing = [s for s in self.sources if isinstance(s, BagIndex) or not _label_files(s)]
            if missing:
                raise InvalidArgument(
                    f"labels=True but {len(missing)} source(s) have no KITTI label_2 + calib "
                    f"files, e.g. {_name(missing[0])}"
                )
        self.load = functools.lru_cache(maxsize=cache_size)(self._load)

    def __len__(self) -> int:
        return self.total

    def __repr__(self) -> str:
        return f"frames({self.spec!r}: {self.total} frames)"

    def _load(self, index: int) -> Frame:
        position = bisect.bisect_right(self.starts, index) - 1
        source = self.sources[position]
        if isinstance(source, BagIndex):
            local = index - self.starts[position]
            cloud = source.read(local, **self.options)
            origin = f"{source.path} [{source.topic} #{local}]"
            boxes: tuple = ()
        else:
            cloud = read_cloud(source, **self.options)
            origin = str(source)
            files = _label_files(source) if self.labels else None
            boxes = tuple(read_kitti_labels(*files)) if files else ()
        _freeze(cloud)
        return Frame(cloud, roi=self.roi, boxes=boxes, source=origin, index=index)


def _freeze(cloud: PointCloud) -> None:
    cloud.points.flags.writeable = False
    for value in cloud.fields.values():
        value.flags.writeable = False


def _name(source: Path | BagIndex) -> str:
    return str(source.path if isinstance(source, BagIndex) else source)


def _is_bag(path: Path) -> bool:
    return path.suffix.lower() in _BAG_SUFFIXES or (path / "metadata.yaml").is_file()


def _label_files(cloud_path: Path) -> tuple[Path, Path] | None:
    """KITTI ``label_2/NNNNNN.txt`` and ``calib/NNNNNN.txt`` beside ``velodyne/``."""
    if cloud_path.parent.name != "velodyne":
        return None
    root = cloud_path.parent.parent
    label = root / "label_2" / f"{cloud_path.stem}.txt"
    calib = root / "calib" / f"{cloud_path.stem}.txt"
    return (label, calib) if label.is_file() and calib.is_file() else None


def _expand(spec: str) -> Sequence[Path]:
    path = Path(spec)
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return [path]
        for velodyne in (path / "velodyne", path / "training" / "velodyne"):
            if velodyne.is_dir():
                return _listed(velodyne, (".bin",), spec)
        return _listed(path, _CLOUD_SUFFIXES + _BAG_SUFFIXES, spec)
    if path.is_file():
        detect_format(path)  # fail now, not at the first draw, for an unknown format
        return [path]
    matches = sorted(Path(match) for match in glob.glob(spec, recursive=True))
    if not matches:
        raise InvalidArgument(f"path_or_glob={spec!r}: no such file or folder, and no glob match")
    for match in matches:
        if match.is_dir() and not (match / "metadata.yaml").is_file():
            raise InvalidArgument(f"path_or_glob={spec!r} matches folder {match}, not a cloud file")
        if match.is_file():
            detect_format(match)
    return matches


def _listed(folder: Path, suffixes: tuple[str, ...], spec: str) -> list[Path]:
    found = sorted(
        child
        for child in folder.iterdir()
        if child.is_file() and child.suffix.lower() in suffixes and not child.name.startswith(".")
    )
    if not found:
        raise InvalidArgument(
            f"path_or_glob={spec!r}: folder {folder} holds no {'/'.join(suffixes)} files"
        )
    return found


class _CallableModule(types.ModuleType):
    """This module, callable as :func:`frames`.

    The package looks strategies up lazily by name, but importing this submodule binds
    ``pytest_metamorphic.strategies.frames`` to the *module* (same name as the function),
    which would hide the lazy lookup. Calling the module forwards to the function, so
    ``mst.frames(...)`` works whatever was imported first.
    """

    def __call__(self, *args: Any, **kwargs: Any) -> st.SearchStrategy[Frame]:
        return frames(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
