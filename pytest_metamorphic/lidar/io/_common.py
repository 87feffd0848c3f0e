"""Pieces every reader and writer shares.

* :func:`cloud_from_columns` / :func:`cloud_from_records`: named per-point columns (PCD
  fields, PointCloud2 fields) to a :class:`PointCloud`, with the NaN and zero-padding
  policies applied in one place.
* :func:`records_from_cloud`: the inverse, a packed little-endian structured array.
* :func:`replacing`: write to a temporary name, then move into place, so a crash never
  leaves a half-written file where a user's tool would open it.
* :func:`wrap_errors`: third-party parsers (rosbags, sqlite, LZF) fail in many ways on
  corrupt files; this turns every such failure into a :class:`DataError` naming the file.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import uuid
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Literal

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument, MetamorphicError
from pytest_metamorphic.lidar.cloud import COLUMNS, NonFinitePolicy, PointCloud

__all__ = [
    "ZerosPolicy",
    "check_policies",
    "cloud_from_columns",
    "cloud_from_records",
    "records_from_cloud",
    "replacing",
    "require_xyz",
    "wrap_errors",
]

ZerosPolicy = Literal["auto", "drop", "keep"]

_FAST_LAYOUT = np.dtype(
    {"names": list(COLUMNS), "formats": ["<f4"] * 4, "offsets": [0, 4, 8, 12], "itemsize": 16}
)


def check_policies(nonfinite: object, zeros: object) -> None:
    """Raise InvalidArgument for an unknown ``nonfinite`` or ``zeros`` policy."""
    if nonfinite not in ("reject", "drop"):
        raise InvalidArgument(f"nonfinite={nonfinite!r} must be 'reject' or 'drop'")
    if zeros not in ("auto", "drop", "keep"):
        raise InvalidArgument(f"zeros={zeros!r} must be 'auto', 'drop' or 'keep'")


def require_xyz(names: Iterable[str], name: str) -> None:
    """Raise DataError unless the field names include x, y and z."""
    names = list(names)
    missing = [axis for axis in "xyz" if axis not in names]
    if missing:
        shown = sorted(set(names) - {"_"})
        raise DataError(f"no {'/'.join(missing)} field; the fields are {shown}", path=name)


def cloud_from_columns(
    columns: Mapping[str, np.ndarray],
    *,
    name: str,
    organised: bool,
    nonfinite: NonFinitePolicy,
    zeros: ZerosPolicy,
    frame_id: str = "",
    timestamp: float | None = None,
    points: np.ndarray | None = None,
) -> PointCloud:
    """Build a cloud from named columns of equal length.

    Parameters
    ----------
    columns : mapping of str to (n,) or (n, k) ndarray
      Must hold ``x``, ``y``, ``z``; ``intensity`` is optional (0 when absent). Every
      other column becomes an extra field, converted to native byte order, dtype kept.
    name : str
      The file (and message) named in errors.
    organised : bool
      Whether the source was an organised scan (height > 1); with ``zeros="auto"`` its
      points at x = y = z = 0 exactly are padding and are dropped (and counted).
    points : (n, 4) float32, optional
      x, y, z, intensity already assembled (a zero-copy view); the coordinate columns
      are then not read from ``columns``.
    """
    require_xyz(columns, name)
    for column in COLUMNS:
        if column in columns and columns[column].ndim != 1:
            raise DataError(
                f"field {column!r} has {columns[column].shape[1]} values per point, expected 1",
                path=name,
            )
    dropped_zero = 0
    if _drops_zeros(zeros, organised):
        # Compact first: every later copy then moves only the real points.
        keep = _not_padding(columns)
        dropped_zero = int(keep.size - np.count_nonzero(keep))
        if dropped_zero:
            columns = {key: value[keep] for key, value in columns.items()}
            points = None if points is None else points[keep]
    if points is None:
        count = len(columns["x"])
        points = np.zeros((count, 4), np.float32)
        # Values beyond float32's range become inf and then meet the non-finite policy.
        with np.errstate(over="ignore", invalid="ignore"):
            for index, column in enumerate(COLUMNS):
                if column in columns:
                    points[:, index] = columns[column]
    # Fields get their own native-order memory (not views of a file or message buffer),
    # unless compaction just made fresh copies.
    fields = {
        key: np.array(value, dtype=value.dtype.newbyteorder("="), order="C", copy=not dropped_zero)
        for key, value in columns.items()
        if key not in COLUMNS
    }
    cloud = PointCloud(
        points,
        fields=fields,
        frame_id=frame_id,
        timestamp=timestamp,
        nonfinite=nonfinite,
        name=name,
    )
    cloud.dropped_zero = dropped_zero
    return cloud


def cloud_from_records(records: np.ndarray, **options: object) -> PointCloud:
    """:func:`cloud_from_columns` for a 1-D structured array (one record per point).

    When x, y, z, intensity are consecutive little-endian float32 (KITTI, PCL's
    PointXYZI, this library's writers), they are taken in one block copy of 16 bytes per
    record, twice as fast as four strided column copies; a file holding nothing else is
    viewed without copying at all.
    """
    dropped_zero = 0
    if _drops_zeros(options.get("zeros"), bool(options.get("organised"))):
        require_xyz(records.dtype.names or (), str(options.get("name")))
        # One gather of whole records beats compacting each column separately; taking
        # them as opaque bytes is ~10x faster than numpy's structured boolean indexing.
        keep = _not_padding(records)
        dropped_zero = int(keep.size - np.count_nonzero(keep))
        if dropped_zero:
            opaque = np.dtype((np.void, records.dtype.itemsize))
            records = records.view(opaque).take(np.flatnonzero(keep)).view(records.dtype)
    columns = {key: records[key] for key in records.dtype.names or ()}
    options = {**options, "zeros": "keep"}
    cloud = cloud_from_columns(columns, points=_xyzi_block(records), **options)  # type: ignore[arg-type]
    cloud.dropped_zero = dropped_zero
    return cloud


def _drops_zeros(zeros: object, organised: bool) -> bool:
    return zeros == "drop" or (zeros == "auto" and organised)


def _not_padding(columns: Mapping[str, np.ndarray] | np.ndarray) -> np.ndarray:
    """(n,) bool: False where x = y = z = 0 exactly (NaN is not padding here)."""
    return (columns["x"] != 0) | (columns["y"] != 0) | (columns["z"] != 0)


def _xyzi_block(records: np.ndarray) -> np.ndarray | None:
    fields = records.dtype.fields or {}
    layout = [fields.get(column) for column in COLUMNS]
    if any(item is None or item[0] != np.dtype("<f4") for item in layout):
        return None
    start = layout[0][1]  # type: ignore[index]
    if [item[1] for item in layout] != [start, start + 4, start + 8, start + 12]:  # type: ignore[index]
        return None
    if not records.flags.c_contiguous or records.ndim != 1:
        return None
    if records.dtype == _FAST_LAYOUT and records.flags.writeable:
        return records.view("<f4").reshape(len(records), 4)
    rows = records.view(np.uint8).reshape(len(records), records.dtype.itemsize)
    return np.ascontiguousarray(rows[:, start : start + 16]).view("<f4")


def records_from_cloud(
    cloud: PointCloud, *, allowed: str, fmt: str, name: str = "cloud"
) -> np.ndarray:
    """Pack a cloud into a little-endian structured array: x, y, z, intensity, fields.

    Parameters
    ----------
    allowed : str
      numpy dtype characters (``dtype.str[1:]``, e.g. ``"f4 u1"``) the format can store.
    fmt : str
      The format's name, for the error message.
    """
    if not isinstance(cloud, PointCloud):
        raise InvalidArgument(f"{name} must be a PointCloud, got {type(cloud).__name__}")
    formats: list[object] = ["<f4"] * 4
    for key, value in cloud.fields.items():
        code = value.dtype.newbyteorder("<").str
        if code[1:] not in allowed.split():
            raise InvalidArgument(
                f"{name} field {key!r} has dtype {value.dtype}, which {fmt} cannot store; "
                f"convert it to one of {allowed.split()}"
            )
        formats.append(code if value.ndim == 1 else (code, value.shape[1:]))
    dtype = np.dtype({"names": [*COLUMNS, *cloud.fields], "formats": formats})
    records = np.empty(len(cloud), dtype)
    for index, column in enumerate(COLUMNS):
        records[column] = cloud.points[:, index]
    for key, value in cloud.fields.items():
        records[key] = value
    return records


@contextlib.contextmanager
def replacing(path: str | os.PathLike[str], *, overwrite: bool) -> Iterator[Path]:
    """Yield a fresh path to write; move it onto ``path`` when the block succeeds.

    The yielded path has the same name as ``path`` inside a hidden sibling folder (ROS 2
    bag writers name their storage file after the folder). ``path`` may end up a file or
    a directory; an existing directory is only replaced when it is a ROS 2 bag.
    """
    target = Path(path)
    if target.exists() or target.is_symlink():
        if not overwrite:
            raise InvalidArgument(f"{target} exists; pass overwrite=True to replace it")
        if target.is_dir() and not (target / "metadata.yaml").is_file():
            raise InvalidArgument(
                f"{target} is a directory but not a ROS 2 bag; refusing to replace it"
            )
    if not target.parent.is_dir():
        raise InvalidArgument(f"cannot write {target}: folder {target.parent} does not exist")
    staging = target.parent / f".{target.name}.{uuid.uuid4().hex[:8]}.tmp"
    staging.mkdir()
    try:
        yield staging / target.name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        os.replace(staging / target.name, target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


@contextlib.contextmanager
def wrap_errors(path: object, what: str) -> Iterator[None]:
    """Turn any failure inside the block into a DataError naming ``path``.

    Our own errors pass through. A missing file stays a DataError too (the user named a
    path that is not there), with the OS's reason.
    """
    try:
        yield
    except MetamorphicError:
        raise
    except (KeyboardInterrupt, SystemExit, GeneratorExit):
        raise
    except Exception as error:
        detail = str(error) or type(error).__name__
        raise DataError(f"cannot read {what}: {detail}", path=path) from error
