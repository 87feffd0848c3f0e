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
    if points is None:
        count = len(columns["x"])
        points = np.zeros((count, 4), np.float32)
        # Values beyond float32's range become inf and then meet the non-finite policy.
        with np.errstate(over="ignore", invalid="ignore"):
            for index, column in enumerate(COLUMNS):
                if column in columns:
                    points[:, index] = columns[column]
    fields = {
        key: np.array(value, dtype=value.dtype.newbyteorder("="), order="C")
        for key, value in columns.items()
        if key not in COLUMNS
    }
    dropped_zero = 0
    if zeros == "drop" or (zeros == "auto" and organised):
        keep = (points[:, 0] != 0) | (points[:, 1] != 0) | (points[:, 2] != 0)
        dropped_zero = int(len(points) - np.count_nonzero(keep))
        if dropped_zero:
            points = points[keep]
            fields = {key: value[keep] for key, value in fields.items()}
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
    """:func:`cloud_from_columns` for a structured array (one record per point).

    The KITTI-like layout (x, y, z, intensity as float32 at offsets 0, 4, 8, 12 and nothing
    else) is viewed without copying.
    """
    columns = {key: records[key] for key in records.dtype.names or ()}
    points = None
    if records.dtype == _FAST_LAYOUT and records.flags.c_contiguous and records.flags.writeable:
        points = records.view("<f4").reshape(len(records), 4)
    return cloud_from_columns(columns, points=points, **options)  # type: ignore[arg-type]


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
