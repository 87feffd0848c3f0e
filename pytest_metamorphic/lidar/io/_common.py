"""Pieces every reader and writer shares.

* :func:`cloud_from_columns` / :func:`cloud_from_records`: named per-point columns (PCD
  fields, PointCloud2 fields) to a :class:`PointCloud`, with the NaN and zero-padding
  policies applied in one place.
* :func:`records_from_cloud`: the inverse, a packed little-endian structured array.
* :func:`read_into`: a payload read straight into the array that will hold it.
* :func:`replacing`: write to a temporary name, then move into place, so a crash never
  leaves a half-written file where a user's tool would open it.
* :func:`wrap_errors`: third-party parsers (rosbags, sqlite, LZF) fail in many ways on
  corrupt files; this turns every such failure into a :class:`DataError` naming the file.
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import shutil
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument, MetamorphicError
from pytest_metamorphic.core.files import staging_sibling, write_error
from pytest_metamorphic.lidar.model.cloud import COLUMNS, NonFinitePolicy, PointCloud

__all__ = [
    "ZerosPolicy",
    "check_nonfinite",
    "check_policies",
    "cloud_from_columns",
    "cloud_from_records",
    "read_into",
    "records_from_cloud",
    "replacing",
    "require_xyz",
    "wrap_errors",
]

ZerosPolicy = Literal["auto", "drop", "keep"]

_F4 = np.dtype("<f4")
_FAST_LAYOUT = np.dtype(
    {"names": list(COLUMNS), "formats": [_F4] * 4, "offsets": [0, 4, 8, 12], "itemsize": 16}
)
_QUAD = np.dtype((np.void, 16))
#: The block copies of little-endian floats need the machine's float32 to be little-endian.
_NATIVE_LITTLE = np.dtype(np.float32) == _F4


def check_nonfinite(nonfinite: object) -> None:
    """Raise InvalidArgument for an unknown ``nonfinite`` policy."""
    if nonfinite not in ("reject", "drop"):
        raise InvalidArgument(f"nonfinite={nonfinite!r} must be 'reject' or 'drop'")


def check_policies(nonfinite: object, zeros: object) -> None:
    """Raise InvalidArgument for an unknown ``nonfinite`` or ``zeros`` policy."""
    check_nonfinite(nonfinite)
    if zeros not in ("auto", "drop", "keep"):
        raise InvalidArgument(f"zeros={zeros!r} must be 'auto', 'drop' or 'keep'")


def require_xyz(names: Iterable[str], name: str) -> None:
    """Raise DataError unless the field names include x, y and z."""
    problem = _missing_xyz(tuple(names))
    if problem:
        raise DataError(problem, path=name)


def _missing_xyz(names: tuple[str, ...]) -> str | None:
    missing = [axis for axis in "xyz" if axis not in names]
    if not missing:
        return None
    shown = sorted(set(names) - {"_"})
    return f"no {'/'.join(missing)} field; the fields are {shown}"


def cloud_from_columns(
    columns: Mapping[str, np.ndarray],
    *,
    name: str,
    organised: bool,
    nonfinite: NonFinitePolicy,
    zeros: ZerosPolicy,
    frame_id: str = "",
    timestamp: float | None = None,
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
    nonfinite, zeros, frame_id, timestamp
      As for :class:`PointCloud` and the readers.
    """
    require_xyz(columns, name)
    problem = _coordinates_problem({k: columns[k].shape[1:] for k in COLUMNS if k in columns})
    if problem:
        raise DataError(problem, path=name)
    dropped_zero = 0
    if _drops_zeros(zeros, organised):
        # Compact first: every later copy then moves only the real points.
        keep = _not_padding(columns)
        dropped_zero = int(keep.size - np.count_nonzero(keep))
        if dropped_zero:
            columns = {key: value[keep] for key, value in columns.items()}
    return _finish(
        _points_of_columns(columns), columns, name, nonfinite, frame_id, timestamp, dropped_zero
    )


def cloud_from_records(
    records: np.ndarray,
    *,
    name: str,
    organised: bool,
    nonfinite: NonFinitePolicy,
    zeros: ZerosPolicy,
    frame_id: str = "",
    timestamp: float | None = None,
    owned: bool = False,
) -> PointCloud:
    """:func:`cloud_from_columns` for a 1-D structured array (one record per point).

    When x, y, z are consecutive little-endian float32 (PCL's PointXYZ(I), Velodyne and
    Ouster drivers, this library's writers), they are taken with one 16-byte copy per
    record. Records in memory of the cloud's own (``owned``, or compacted here) are not
    copied again: extra fields are views of them, and so are the points when the records
    are exactly x, y, z, intensity float32. Records in a buffer others hold (a message)
    are copied field by field, so the cloud never aliases it.

    Parameters
    ----------
    records : (n,) structured ndarray
    owned : bool
      ``records`` is memory the reader allocated for this cloud alone (a payload read
      into a fresh array).
    name, organised, nonfinite, zeros, frame_id, timestamp
      As for :func:`cloud_from_columns`.
    """
    problem = _records_problem(records.dtype)
    if problem:
        raise DataError(problem, path=name)
    dropped_zero = 0
    if _drops_zeros(zeros, organised):
        # One gather of whole records beats compacting each column separately; taking
        # them as opaque bytes is ~10x faster than numpy's structured boolean indexing.
        keep = _not_padding(records)
        dropped_zero = int(keep.size - np.count_nonzero(keep))
        if dropped_zero:
            opaque = np.dtype((np.void, records.dtype.itemsize))
            records = records.view(opaque).take(np.flatnonzero(keep)).view(records.dtype)
            owned = True
    points = _points_of_records(records, owned)
    names = records.dtype.names or ()
    if points is None:
        points = _points_of_columns({key: records[key] for key in COLUMNS if key in names})
    fields = {key: records[key] for key in names if key not in COLUMNS}
    return _finish(points, fields, name, nonfinite, frame_id, timestamp, dropped_zero, owned=owned)


@functools.lru_cache(maxsize=64)
def _records_problem(dtype: np.dtype) -> str | None:
    """Why records of this dtype cannot make a cloud, or None (cached: frames share one)."""
    names = dtype.names or ()
    shapes = {key: dtype.fields[key][0].shape for key in COLUMNS if key in names}  # type: ignore[index]
    return _missing_xyz(names) or _coordinates_problem(shapes)


def _coordinates_problem(shapes: Mapping[str, tuple[int, ...]]) -> str | None:
    """Unless x, y, z and intensity (those present: their shape per point) are scalars."""
    for column, shape in shapes.items():
        if shape != ():
            return f"field {column!r} has {shape[0]} values per point, expected 1"
    return None


def _finish(
    points: np.ndarray,
    columns: Mapping[str, np.ndarray],
    name: str,
    nonfinite: NonFinitePolicy,
    frame_id: str,
    timestamp: float | None,
    dropped_zero: int,
    *,
    owned: bool = False,
) -> PointCloud:
    fields = {key: _field(value, owned) for key, value in columns.items() if key not in COLUMNS}
    return PointCloud._from_reader(
        points,
        fields,
        frame_id=frame_id,
        timestamp=timestamp,
        nonfinite=nonfinite,
        name=name,
        dropped_zero=dropped_zero,
    )


def _field(value: np.ndarray, owned: bool) -> np.ndarray:
    """An extra field in native byte order.

    A view of records the reader ``owned`` is kept, as is an array owning contiguous
    memory (a fresh compaction); a view of anything else (a message, a decompressed
    payload) is copied: others may hold that buffer, and the view would keep it alive.
    """
    native = value.dtype.newbyteorder("=")
    if value.dtype == native and (owned or (value.base is None and value.flags.c_contiguous)):
        return value
    return np.array(value, dtype=native, order="C")


def _drops_zeros(zeros: object, organised: bool) -> bool:
    return zeros == "drop" or (zeros == "auto" and organised)


def _not_padding(columns: Mapping[str, np.ndarray] | np.ndarray) -> np.ndarray:
    """(n,) bool: False where x = y = z = 0 exactly (NaN is not padding here)."""
    return (columns["x"] != 0) | (columns["y"] != 0) | (columns["z"] != 0)


def _points_of_columns(columns: Mapping[str, np.ndarray]) -> np.ndarray:
    """(n, 4) float32 x, y, z, intensity (0 when absent) from named columns."""
    points = np.zeros((len(columns["x"]), 4), np.float32)
    # Values beyond float32's range become inf and then meet the non-finite policy.
    with np.errstate(over="ignore", invalid="ignore"):
        for index, column in enumerate(COLUMNS):
            if column in columns:
                points[:, index] = columns[column]
    return points


def _points_of_records(records: np.ndarray, owned: bool) -> np.ndarray | None:
    """(n, 4) float32 points of records whose x, y, z are consecutive ``<f4``, else None.

    ``owned`` records that are exactly x, y, z, intensity float32 are viewed, not copied.
    """
    if not (_NATIVE_LITTLE and records.flags.c_contiguous and len(records)):
        return None
    if owned and records.dtype == _FAST_LAYOUT:
        return records.view(np.float32).reshape(len(records), 4)
    start = _xyz_offset(records.dtype)
    if start is None:
        return None
    count, step = len(records), records.dtype.itemsize
    points = np.empty((count, 4), np.float32)
    # One 16-byte copy per record is ~6x faster than numpy's 2-D copy of 3 or 4 floats a
    # row and ~2x faster than a strided copy per column. Column 3 receives whatever
    # follows z: the intensity when it is the next <f4, else overwritten below. A last
    # record that ends with z has no 4 bytes after it and is copied column by column.
    whole = count if start + 16 <= step else count - 1
    source = np.ndarray((whole,), _QUAD, records.view(np.uint8), start, (step,))
    points.view(_QUAD)[:whole, 0] = source
    if whole < count:
        for k, axis in enumerate("xyz"):
            points[whole:, k] = records[axis][whole:]
    fields: Mapping[str, tuple[Any, ...]] = records.dtype.fields or {}
    intensity = fields.get("intensity")
    if intensity is None:
        points[:, 3] = 0
    elif intensity != (_F4, start + 12):
        # Values beyond float32's range become inf and then meet the non-finite policy.
        with np.errstate(over="ignore", invalid="ignore"):
            points[:, 3] = records["intensity"]
    return points


@functools.lru_cache(maxsize=64)
def _xyz_offset(dtype: np.dtype) -> int | None:
    """Byte offset of x when x, y, z are consecutive ``<f4`` in ``dtype``, else None."""
    fields: Mapping[str, tuple[Any, ...]] = dtype.fields or {}
    start = fields["x"][1]
    consecutive = all(fields[axis] == (_F4, start + 4 * k) for k, axis in enumerate("xyz"))
    return start if consecutive else None


def read_into(fd: int, buffer: np.ndarray) -> int:
    """Fill a uint8 array from ``fd``; the bytes read (fewer only at the end of the file).

    Straight into the array: ``np.fromfile`` goes through C stdio and is ~20% slower on
    a 1 MB payload.
    """
    view = buffer.data  # a memoryview of the array's bytes
    total = 0
    while total < len(view):
        count = _read_some(fd, view[total:])
        if not count:
            break
        total += count
    return total


def _read_some(fd: int, view: memoryview) -> int:
    if hasattr(os, "readv"):  # POSIX
        return os.readv(fd, [view])
    with io.FileIO(fd, "rb", closefd=False) as raw:  # Windows
        return raw.readinto(view)


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
def replacing(
    path: str | os.PathLike[str], *, overwrite: bool, what: str = "file"
) -> Iterator[Path]:
    """Yield a fresh path to write; move it onto ``path`` when the block succeeds.

    The yielded path has the same name as ``path`` inside a hidden sibling folder (ROS 2
    bag writers name their storage file after the folder). ``path`` may end up a file or
    a directory; an existing directory is only replaced when it is a ROS 2 bag.

    Raises
    ------
    WriteError
        The operating system refused a write (named: ``path``, with the cause's advice).
    """
    target = Path(path)
    try:
        present = target.exists() or target.is_symlink()
    except OSError as error:  # a name too long for the file system
        raise write_error(error, target, what=what) from None
    if present:
        if not overwrite:
            raise InvalidArgument(f"{target} exists; pass overwrite=True to replace it")
        if target.is_dir() and not (target / "metadata.yaml").is_file():
            raise InvalidArgument(
                f"{target} is a directory but not a ROS 2 bag; refusing to replace it"
            )
    if not target.parent.is_dir():
        raise InvalidArgument(f"cannot write {target}: folder {target.parent} does not exist")
    staging = staging_sibling(target)
    try:
        staging.mkdir()
        yield staging / target.name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        os.replace(staging / target.name, target)
    except OSError as error:
        if isinstance(error, MetamorphicError):
            raise
        raise write_error(error, target, what=what) from None
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
