"""An index of the frames in recordings (bags, KITTI folders, cloud files), loaded lazily.

:class:`FrameCatalog` is what :func:`pytest_metamorphic.strategies.frames` draws from and
what campaigns take their real sources from: frames are numbered over all matched
sources in order (a bag contributes one frame per PointCloud2 message), indexing is cheap,
and only the last few loaded frames stay in memory.
"""

from __future__ import annotations

import bisect
import functools
import os
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal, overload

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.globbing import expand
from pytest_metamorphic.lidar.io import detect_format, read_cloud, read_kitti_labels
from pytest_metamorphic.lidar.io._common import ZerosPolicy, check_policies
from pytest_metamorphic.lidar.io.rosbag import BagIndex, index_bag
from pytest_metamorphic.lidar.model.cloud import NonFinitePolicy, PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors import ScanPattern, as_sensor

__all__ = ["FrameCatalog"]

_CLOUD_SUFFIXES = (".bin", ".pcd")
_BAG_SUFFIXES = (".bag", ".db3", ".mcap")


class FrameCatalog:
    """An index of the frames in some recordings; frames load on demand.

    Parameters
    ----------
    path_or_glob : str or path-like
        A bag, a KITTI folder, any folder of clouds and bags, one cloud file, or a glob
        (see :func:`pytest_metamorphic.strategies.frames`).
    topic : str, optional
        PointCloud2 topic for bags (default: the bag's only PointCloud2 topic).
    roi : object, optional
        Attached as is to every frame.
    labels : bool or "auto"
        KITTI ground truth from ``label_2``/``calib`` beside ``velodyne``: where present,
        required for every frame, or never.
    nonfinite, zeros
        Reader policies (see :func:`~pytest_metamorphic.lidar.io.read_cloud`).
    cache_size : int
        Frames kept in memory, least recently loaded first out. Cached frames are shared,
        so their arrays are read-only.
    sensor : ScanPattern or str, optional
        The sensor that recorded them (a model of
        :mod:`pytest_metamorphic.lidar.model.sensors` or its key, e.g. ``"vlp16"``),
        attached to every frame; by default each frame's sensor is identified from its
        cloud when a relation needs it.

    Notes
    -----
    Indexing is cheap (a sorted file list, or a bag's message index) and reports every
    "nothing to load" problem at once; ``catalog[i]`` (or :meth:`load`) reads one frame,
    ``catalog[a:b]`` a list of them, and iterating reads them in order.
    """

    def __init__(
        self,
        path_or_glob: str | os.PathLike[str],
        *,
        topic: str | None = None,
        roi: Any = None,
        labels: bool | Literal["auto"] = "auto",
        nonfinite: NonFinitePolicy = "reject",
        zeros: ZerosPolicy = "auto",
        cache_size: int = 4,
        sensor: ScanPattern | str | None = None,
    ) -> None:
        check_policies(nonfinite, zeros)
        self.sensor = as_sensor(sensor)
        if labels not in (True, False, "auto"):
            raise InvalidArgument(f"labels={labels!r} must be True, False or 'auto'")
        if isinstance(cache_size, bool) or not isinstance(cache_size, int) or cache_size < 1:
            raise InvalidArgument(f"cache_size={cache_size!r} must be a positive integer")
        if topic is not None and not isinstance(topic, str):
            raise InvalidArgument(f"topic={topic!r} must be a string")
        spec = str(os.fspath(path_or_glob))
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
        self.cache_size = cache_size
        self._cached = functools.lru_cache(maxsize=cache_size)(self._load)

    def __getstate__(self) -> dict[str, Any]:
        # A catalog travels (to pytest-xdist or Dask workers) as its index: absolute paths,
        # bag message times and options, never loaded frames; each process loads its own.
        state = {key: value for key, value in self.__dict__.items() if key != "_cached"}
        state["sources"] = [
            replace(source, path=source.path.absolute())
            if isinstance(source, BagIndex)
            else source.absolute()
            for source in self.sources
        ]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._cached = functools.lru_cache(maxsize=self.cache_size)(self._load)

    def load(self, index: int) -> Frame:
        """Frame ``index`` (0-based, over all sources in order)."""
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
            raise InvalidArgument(f"index={index!r} must be an int")
        if not 0 <= index < self.total:
            raise InvalidArgument(f"index={index} out of range: {self!r}")
        return self._cached(int(index))

    @overload
    def __getitem__(self, index: int) -> Frame: ...

    @overload
    def __getitem__(self, index: slice) -> list[Frame]: ...

    def __getitem__(self, index: int | slice) -> Frame | list[Frame]:
        """``catalog[i]`` (negative counts from the end) or ``catalog[a:b:c]``."""
        if isinstance(index, slice):
            return [self.load(i) for i in range(*index.indices(self.total))]
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
            raise InvalidArgument(f"catalog[{index!r}]: the index must be an int or a slice")
        if -self.total <= index < 0:
            index = self.total + int(index)
        if not 0 <= index < self.total:
            raise IndexError(f"catalog[{index}] out of range: {self!r}")
        return self.load(index)

    def __iter__(self) -> Iterator[Frame]:
        return (self.load(i) for i in range(self.total))

    def __len__(self) -> int:
        return self.total

    def __repr__(self) -> str:
        return f"FrameCatalog({self.spec!r}: {self.total} frames)"

    def _load(self, index: int) -> Frame:
        position = bisect.bisect_right(self.starts, index) - 1
        source = self.sources[position]
        if isinstance(source, BagIndex):
            local = index - self.starts[position]
            cloud = source.read(local, **self.options)
            origin = f"{source.path} [{source.topic} #{local}]"
            boxes: tuple[Box, ...] = ()
        else:
            cloud = read_cloud(source, **self.options)
            origin = str(source)
            files = _label_files(source) if self.labels else None
            boxes = tuple(read_kitti_labels(*files)) if files else ()
        _freeze(cloud)
        return Frame(
            cloud, roi=self.roi, boxes=boxes, source=origin, index=index, sensor=self.sensor
        )


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
    # Each file once, however many symbolic links lead to it (a `self -> .` link made
    # glob list one file 41 times, and two such links never ended).
    matches = [Path(match) for match in expand(spec)]
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
