"""Reading and writing PCD files: :func:`read_pcd`, :func:`read_pcd_header`, :func:`write_pcd`."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import open_regular_fd
from pytest_metamorphic.lidar.io import _lzf
from pytest_metamorphic.lidar.io._common import (
    ZerosPolicy,
    check_policies,
    records_from_cloud,
    replacing,
    require_xyz,
)
from pytest_metamorphic.lidar.io.pcd.header import (
    _FIRST_READ,
    _WRITABLE,
    MAX_HEADER_BYTES,
    PcdData,
    PcdHeader,
    _header_text,
    _parse,
)
from pytest_metamorphic.lidar.io.pcd.payload import (
    _ascii_body,
    _read_ascii,
    _read_binary,
    _read_bytes,
    _read_compressed,
)
from pytest_metamorphic.lidar.model.cloud import NonFinitePolicy, PointCloud

__all__ = ["read_pcd", "read_pcd_header", "write_pcd"]


def read_pcd_header(path: str | os.PathLike[str]) -> PcdHeader:
    """Parse and check the header of a PCD file (nothing after it is read)."""
    path = Path(path)
    fd = open_regular_fd(path, what="PCD file")
    try:
        return _read_header(fd, path)
    except OSError as error:
        raise DataError(f"cannot read PCD file: {error.strerror or error}", path=path) from None
    finally:
        os.close(fd)


def _read_header(fd: int, path: Path) -> PcdHeader:
    head = os.read(fd, _FIRST_READ)
    header = _parse(head, path, complete=len(head) < _FIRST_READ)
    if header is None:  # the DATA line is further on than the first read
        head += _read_bytes(fd, MAX_HEADER_BYTES - len(head))
        header = _parse(head, path, complete=True)
    return header  # type: ignore[return-value]


def read_pcd(
    path: str | os.PathLike[str],
    *,
    nonfinite: NonFinitePolicy = "reject",
    zeros: ZerosPolicy = "auto",
) -> PointCloud:
    """Read a PCD file.

    Parameters
    ----------
    path : path-like
    nonfinite : {"reject", "drop"}
      Points with NaN/inf x, y, z or intensity (the padding of organised PCL clouds) raise
      a DataError, or are dropped and counted in ``cloud.dropped_nonfinite``.
    zeros : {"auto", "drop", "keep"}
      Points at x = y = z = 0 exactly: dropped (and counted in ``cloud.dropped_zero``) for
      ``"drop"``, or for ``"auto"`` when the cloud is organised (HEIGHT > 1).

    Returns
    -------
    PointCloud
      Extra fields keep their PCD dtype; ``COUNT`` k > 1 gives an ``(n, k)`` field.

    Raises
    ------
    DataError
      Naming the file and what is wrong: bad header, unsupported type, truncated or
      oversized payload, corrupt compressed data, missing x/y/z, non-finite points.
    """
    check_policies(nonfinite, zeros)
    path = path if isinstance(path, Path) else Path(path)  # Path(a Path) costs 3 us
    # A raw descriptor, not a file object: for a small file the ~5 us saved matter (the
    # header is one read, the payload one read straight into its array).
    fd = open_regular_fd(path, what="PCD file")
    try:
        return _read_open(fd, path, nonfinite, zeros)
    except OSError as error:
        raise DataError(f"cannot read PCD file: {error.strerror or error}", path=path) from None
    finally:
        os.close(fd)


def _read_open(fd: int, path: Path, nonfinite: str, zeros: str) -> PointCloud:
    header = _read_header(fd, path)
    name = str(path)
    require_xyz(header.fields, name)  # before reading a payload that cannot be used
    available = os.fstat(fd).st_size - header.data_offset
    os.lseek(fd, header.data_offset, os.SEEK_SET)
    options = {
        "name": name,
        "organised": header.height > 1,
        "nonfinite": nonfinite,
        "zeros": zeros,
        "frame_id": header.frame_id,
        "timestamp": header.timestamp,
    }
    if header.data == "binary":
        return _read_binary(fd, path, header, available, options)
    if header.data == "binary_compressed":
        return _read_compressed(fd, path, header, available, options)
    return _read_ascii(fd, path, header, available, options)


def write_pcd(
    cloud: PointCloud,
    path: str | os.PathLike[str],
    *,
    data: PcdData = "binary",
    overwrite: bool = False,
) -> Path:
    """Write a cloud as an unorganised PCD file that reads back to an equal cloud.

    Parameters
    ----------
    cloud : PointCloud
      Written as fields x, y, z, intensity (F4), then its extra fields in order, each
      with its own dtype (bool and float16 fields are refused: PCD has no such type).
    path : path-like
    data : {"binary", "binary_compressed", "ascii"}
      ``binary_compressed`` is PCL's LZF format (compact, slower); ``ascii`` prints
      every value with enough digits to read back exactly (NaN payload bits excepted).
    overwrite : bool
      Replace an existing file; otherwise an existing ``path`` is an InvalidArgument.

    Returns
    -------
    Path
      Where the file was written (atomically: the file appears complete or not at all).
    """
    if data not in ("ascii", "binary", "binary_compressed"):
        raise InvalidArgument(f"data={data!r} must be 'ascii', 'binary' or 'binary_compressed'")
    records = records_from_cloud(cloud, allowed=_WRITABLE, fmt="PCD")
    if any(not re.fullmatch(r"[^\s#]+", key) or key == "_" for key in cloud.fields):
        bad = next(k for k in cloud.fields if not re.fullmatch(r"[^\s#]+", k) or k == "_")
        raise InvalidArgument(f"field name {bad!r} cannot be written to a PCD header")
    if "\n" in cloud.frame_id or "\r" in cloud.frame_id:
        raise InvalidArgument(f"frame_id {cloud.frame_id!r} has a line break; PCD cannot keep it")
    header = _header_text(cloud, records.dtype, data).encode("utf-8")
    with (
        replacing(path, overwrite=overwrite, what="PCD file") as temporary,
        temporary.open("wb") as handle,
    ):
        handle.write(header)
        if data == "binary":
            handle.write(records.tobytes())
        elif data == "binary_compressed":
            raw = b"".join(
                np.ascontiguousarray(records[key]).tobytes() for key in records.dtype.names or ()
            )
            packed = _lzf.compress(raw)
            handle.write(np.array([len(packed), len(raw)], "<u4").tobytes())
            handle.write(packed)
        else:
            handle.write(_ascii_body(records).encode("ascii"))
    return Path(path)
