"""PCD bodies: binary records read straight into arrays, LZF-compressed columns, ascii."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.lidar.io import _lzf
from pytest_metamorphic.lidar.io._common import (
    cloud_from_columns,
    cloud_from_records,
    read_into,
)
from pytest_metamorphic.lidar.io.pcd.header import PcdHeader
from pytest_metamorphic.lidar.model.cloud import PointCloud


def _need(available: int, needed: int, what: str, path: Path) -> None:
    if needed > available:
        raise DataError(
            f"{what} needs {needed} bytes but only {available} follow the header "
            "(truncated file, or a header that overstates its size)",
            path=path,
        )


def _no_more(available: int, used: int, what: str, path: Path) -> None:
    """Refuse bytes after the payload the header declares: a header that understates
    POINTS or WIDTH would otherwise read silently short."""
    if available > used:
        raise DataError(
            f"{available - used} bytes follow {what} the header declares ({used} bytes): the "
            "header understates POINTS/WIDTH, or the file has trailing data",
            path=path,
        )


def _read_binary(
    fd: int, path: Path, header: PcdHeader, available: int, options: dict[str, Any]
) -> PointCloud:
    dtype = header.dtype()
    step = dtype.itemsize  # header.point_step, without summing it again
    size = header.points * step
    if size != available:  # (the messages are only built when they are needed)
        _need(available, size, f"{header.points} points of {step} bytes", path)
        _no_more(available, size, f"the {header.points} points", path)
    records = np.empty(header.points, dtype)
    read = read_into(fd, records.view(np.uint8))
    if read != size:  # the file shrank since fstat()
        raise DataError(f"expected {header.points} points, read {read // step}", path=path)
    return cloud_from_records(records, owned=True, **options)


def _read_bytes(fd: int, size: int) -> bytes:
    """Up to ``size`` bytes from ``fd`` (fewer only at the end of the file)."""
    chunks = []
    while size > 0:
        chunk = os.read(fd, size)
        if not chunk:
            break
        chunks.append(chunk)
        size -= len(chunk)
    return b"".join(chunks)


def _read_compressed(
    fd: int, path: Path, header: PcdHeader, available: int, options: dict[str, Any]
) -> PointCloud:
    _need(available, 8, "the compressed-size words", path)
    compressed, uncompressed = (int(v) for v in np.frombuffer(_read_bytes(fd, 8), "<u4"))
    expected = header.points * header.point_step
    if uncompressed != expected:
        raise DataError(
            f"binary_compressed payload declares {uncompressed} bytes but {header.points} "
            f"points of {header.point_step} bytes need {expected}",
            path=path,
        )
    _need(available - 8, compressed, "the compressed payload", path)
    _no_more(available - 8, compressed, "the compressed payload", path)
    if uncompressed > _lzf.MAX_RATIO * compressed + 64:
        raise DataError(
            f"{compressed} LZF bytes cannot expand to the declared {uncompressed}", path=path
        )
    packed = _read_bytes(fd, compressed)
    try:
        raw = _lzf.decompress(packed, uncompressed)
    except ValueError as error:
        raise DataError(f"corrupt binary_compressed payload: {error}", path=path) from None
    columns: dict[str, np.ndarray] = {}
    offset, n = 0, header.points
    for field, width, kind, count in zip(
        header.fields, header.sizes, header.types, header.counts, strict=True
    ):
        block = n * width * count
        if field != "_":
            values = np.frombuffer(raw, f"<{kind.lower()}{width}", n * count, offset)
            columns[field] = values if count == 1 else values.reshape(n, count)
        offset += block
    return cloud_from_columns(columns, **options)


def _read_ascii(
    fd: int, path: Path, header: PcdHeader, available: int, options: dict[str, Any]
) -> PointCloud:
    per_point = sum(header.counts)
    # Every value takes at least one character and one separator: bound before parsing.
    _need(available + 1, 2 * header.points * per_point, f"{header.points} ascii points", path)
    try:
        tokens = _read_bytes(fd, available).decode("ascii").split()
    except UnicodeDecodeError:
        raise DataError("ascii payload holds non-ASCII bytes", path=path) from None
    if len(tokens) != header.points * per_point:
        raise DataError(
            f"ascii payload has {len(tokens)} values; {header.points} points x {per_point} "
            f"values need {header.points * per_point}",
            path=path,
        )
    columns: dict[str, np.ndarray] = {}
    start = 0
    for field, width, kind, count in zip(
        header.fields, header.sizes, header.types, header.counts, strict=True
    ):
        if field != "_":
            parts = [tokens[start + k :: per_point] for k in range(count)]
            text = np.array(parts).T if count > 1 else np.array(parts[0])
            try:
                with np.errstate(over="ignore", invalid="ignore"):
                    if kind == "F":
                        values = text.astype(np.float64).astype(f"<f{width}")
                    else:
                        values = text.astype(f"<{kind.lower()}{width}")
            except (ValueError, OverflowError) as error:
                raise DataError(
                    f"field {field!r} has a value that is not a {kind}{width}: {error}", path=path
                ) from None
            columns[field] = values.reshape(header.points, count) if count > 1 else values
        start += count
    return cloud_from_columns(columns, **options)


def _ascii_body(records: np.ndarray) -> str:
    columns = []
    for key in records.dtype.names or ():
        values = records[key].reshape(len(records), int(np.prod(records.dtype[key].shape)))
        kind, size = values.dtype.kind, values.dtype.itemsize
        # 9 / 17 significant digits read back to the same float32 / float64.
        fmt = ("%.9g" if size == 4 else "%.17g") if kind == "f" else "%d"
        columns.append([[fmt % v for v in row] for row in values.tolist()])
    lines = (" ".join(v for column in row for v in column) for row in zip(*columns, strict=True))
    return "".join(line + "\n" for line in lines)
