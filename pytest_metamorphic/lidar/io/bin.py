"""KITTI and nuScenes ``.bin`` point files: headerless little-endian float32 rows.

* KITTI ``velodyne/*.bin``: 4 columns x, y, z, intensity (0-1).
* nuScenes ``*.pcd.bin`` (LIDAR_TOP sweeps): 5 columns x, y, z, intensity (0-255), ring.

A file holds no column count, and a nuScenes sweep's byte size is often divisible by
both 16 and 20, so the layout is taken from the name: ``*.pcd.bin`` means 5 columns,
anything else 4, unless ``columns=`` says otherwise. Columns after intensity become
float32 fields (``ring`` for nuScenes). A nuScenes name's trailing microsecond stamp
(``..._1532402927647951.pcd.bin``) becomes the cloud's timestamp.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import open_regular_fd
from pytest_metamorphic.lidar.io._common import check_nonfinite, read_into, replacing
from pytest_metamorphic.lidar.model.cloud import NonFinitePolicy, PointCloud

__all__ = ["read_bin", "write_bin"]

_NUSCENES_STAMP = re.compile(r"__(\d{16})\.pcd\.bin$")


def _is_nuscenes(path: Path) -> bool:
    return path.name.lower().endswith(".pcd.bin")


def read_bin(
    path: str | os.PathLike[str],
    *,
    columns: int | None = None,
    field_names: Sequence[str] = ("ring",),
    nonfinite: NonFinitePolicy = "reject",
) -> PointCloud:
    """Read a KITTI (4-column) or nuScenes (5-column) ``.bin`` file.

    Parameters
    ----------
    path : path-like
    columns : int, optional
      float32 values per point, at least 3. Default: 5 for ``*.pcd.bin``, else 4.
    field_names : sequence of str
      Names of the columns after intensity (nuScenes: ``ring``); one per extra column.
    nonfinite : {"reject", "drop"}
      Policy for points with NaN or infinite values.

    Returns
    -------
    PointCloud
      ``points`` (n, 4) float32 (intensity 0 for 3 columns); extra columns as (n,)
      float32 fields.

    Raises
    ------
    DataError
      The file is missing or its size is not a whole number of rows.
    """
    path = Path(path)
    if columns is None:
        columns = 5 if _is_nuscenes(path) else 4
    if isinstance(columns, bool) or not isinstance(columns, int) or columns < 3:
        raise InvalidArgument(f"columns={columns!r} must be an integer >= 3")
    names = tuple(field_names)[: max(columns - 4, 0)]
    if len(names) != max(columns - 4, 0):
        raise InvalidArgument(
            f"field_names={tuple(field_names)!r} must name the {columns - 4} column(s) after "
            "intensity"
        )
    check_nonfinite(nonfinite)
    name = str(path)
    fd = open_regular_fd(path, what=".bin file")
    try:
        size = os.fstat(fd).st_size
        row = 4 * columns
        if size % row:
            hint = ""
            for other in (4, 5):
                if other != columns and size % (4 * other) == 0:
                    hint = f" (it would fit {other} columns: pass columns={other})"
            raise DataError(
                f"size {size} bytes is not a multiple of {row} ({columns} float32 columns){hint}",
                path=path,
            )
        # Straight into the array from the descriptor (np.fromfile of a file object costs
        # a fifth more), as little-endian float32 rows.
        values = np.empty((size // row, columns), "<f4")
        if read_into(fd, values.view(np.uint8).reshape(-1)) != size:
            raise DataError(f"the file shrank while it was read (from {size} bytes)", path=path)
    except OSError as error:
        raise DataError(f"cannot read .bin file: {error.strerror or error}", path=path) from None
    finally:
        os.close(fd)
    if columns == 4 and values.dtype == np.float32:
        points = values
    else:
        points = np.zeros((len(values), 4), np.float32)
        points[:, : min(columns, 4)] = values[:, :4]
    fields = {field: values[:, 4 + k].copy() for k, field in enumerate(names)}
    stamp = _NUSCENES_STAMP.search(path.name)
    # The arrays are the reader's own, well formed; only the values need checking.
    return PointCloud._from_reader(
        points,
        fields,
        frame_id="",
        timestamp=int(stamp.group(1)) / 1e6 if stamp else None,
        nonfinite=nonfinite,
        name=name,
    )


def write_bin(
    cloud: PointCloud,
    path: str | os.PathLike[str],
    *,
    fields: Sequence[str] | None = None,
    overwrite: bool = False,
) -> Path:
    """Write x, y, z, intensity (and the named fields) as float32 rows.

    Parameters
    ----------
    cloud : PointCloud
    path : path-like
    fields : sequence of str, optional
      Fields to append as extra columns, in order. Default: ``("ring",)`` for a
      ``*.pcd.bin`` name (nuScenes), else none (KITTI). Each must be 1-D and exactly
      representable as float32. Other fields, the frame id and timestamp are not stored.
    overwrite : bool
      Replace an existing file.

    Returns
    -------
    Path
    """
    if not isinstance(cloud, PointCloud):
        raise InvalidArgument(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    target = Path(path)
    names = tuple(fields) if fields is not None else (("ring",) if _is_nuscenes(target) else ())
    columns = [cloud.points]
    for name in names:
        if name not in cloud.fields:
            raise InvalidArgument(
                f"cloud has no field {name!r} to write (fields: {sorted(cloud.fields)})"
            )
        value = cloud.fields[name]
        if value.ndim != 1:
            raise InvalidArgument(f"field {name!r} has shape {value.shape}; .bin columns are 1-D")
        as_float = value.astype(np.float32)
        if not np.array_equal(
            as_float.astype(value.dtype), value, equal_nan=value.dtype.kind == "f"
        ):
            raise InvalidArgument(
                f"field {name!r} ({value.dtype}) is not exactly representable as float32"
            )
        columns.append(as_float[:, None])
    rows = np.ascontiguousarray(np.hstack(columns), dtype="<f4")
    with replacing(target, overwrite=overwrite, what="KITTI .bin file") as temporary:
        rows.tofile(temporary)
    return target
