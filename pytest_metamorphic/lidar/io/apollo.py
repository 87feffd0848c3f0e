"""Baidu Apollo's text test-data formats (perception module).

* ``*.poly`` (HD-map ROI filter unit test): the polygon count, then per polygon its
  vertex count and one ``x y z`` (or ``x y``) row per vertex.
* The ROI filter's labelled points (``poly_mask_ut.pcd``, not a PCD despite the name):
  the point count, then ``x y label`` rows, label +1 inside the ROI and -1 outside.
* Object-builder clusters (``min_box_object_builder/*.pcd``, not PCD either): one
  cluster per line, ``n x1 y1 z1 i1 ... xn yn zn in``.
* ``*.pose``: ``frame_id timestamp x y z qx qy qz qw`` (UTM metres; Hamilton
  quaternion, scalar last).

Files are read a line at a time and rows parsed into blocks of numbers, so memory follows
what is parsed (a few bytes per value), never the file's size, and a declared count the
file does not hold allocates nothing.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.core.files import open_regular
from pytest_metamorphic.lidar.model.cloud import PointCloud

__all__ = [
    "ApolloPose",
    "read_apollo_clusters",
    "read_apollo_poly",
    "read_apollo_pose",
    "read_apollo_roi_points",
]

MAX_LINE_BYTES = 8 << 20
"""The longest line read (a cluster of about 200,000 points); files are read a line at a
time, so memory follows what is parsed, not the file's size."""
_CHUNK = 4096  # rows parsed into one block before it is kept


def _rows(path: Path, what: str) -> Iterator[tuple[int, list[str]]]:
    """Non-empty lines as (line number, tokens), read one at a time."""
    with open_regular(path, what=what) as handle:
        number = 0
        while True:
            raw = handle.readline(MAX_LINE_BYTES + 1)
            if not raw:
                return
            number += 1
            if len(raw) > MAX_LINE_BYTES:
                raise DataError(
                    f"line {number} is longer than {MAX_LINE_BYTES} bytes; not an Apollo {what}",
                    path=path,
                )
            try:
                tokens = raw.decode("utf-8").split()
            except UnicodeDecodeError as error:
                raise DataError(
                    f"{what} is not text (line {number}, byte {error.start})", path=path
                ) from None
            if tokens:
                yield number, tokens


def _block_rows(
    rows: Iterator[tuple[int, list[str]]],
    count: int,
    width: int,
    path: Path,
    *,
    row: str = "",
    expected: str = "",
) -> tuple[NDArray[np.float64], list[int]]:
    """Up to ``count`` rows of ``width`` numbers as a (k, width) array (k < count only when
    the file ends), with their line numbers; parsed in blocks, so a declared count that
    the file does not hold allocates nothing."""
    blocks: list[NDArray[np.float64]] = []
    numbers: list[int] = []
    if count <= 0:
        return np.empty((0, width), np.float64), numbers
    block = np.empty((min(count, _CHUNK), width), np.float64)
    filled = 0
    for number, tokens in rows:
        if len(tokens) != width:
            name = f"{row} has " if row else ""
            raise DataError(
                f"line {number}: {name}{len(tokens)} values, expected {expected or width}",
                path=path,
            )
        block[filled] = _floats(tokens, number, path)
        numbers.append(number)
        filled += 1
        if filled == len(block):
            blocks.append(block)
            filled = 0
            if len(numbers) == count:
                break
            block = np.empty((min(count - len(numbers), _CHUNK), width), np.float64)
    if filled:
        blocks.append(block[:filled])
    values = np.concatenate(blocks) if blocks else np.empty((0, width), np.float64)
    return values, numbers


def _count(tokens: list[str], number: int, what: str, path: Path) -> int:
    if len(tokens) != 1 or not tokens[0].isdigit():
        raise DataError(
            f"line {number}: expected the {what} (one non-negative integer), got "
            f"{' '.join(tokens)[:60]!r}",
            path=path,
        )
    return int(tokens[0])


def _floats(tokens: list[str], number: int, path: Path) -> NDArray[np.float64]:
    try:
        values = np.array([float(token) for token in tokens], np.float64)
    except ValueError:
        raise DataError(
            f"line {number}: non-numeric value in {' '.join(tokens)[:60]!r}", path=path
        ) from None
    if not np.isfinite(values).all():
        raise DataError(f"line {number}: non-finite value", path=path)
    return values


def read_apollo_poly(path: str | os.PathLike[str]) -> list[NDArray[np.float64]]:
    """Read an Apollo ``.poly`` ROI file.

    Returns
    -------
    list of (k, 3) or (k, 2) float64
      One vertex array per polygon (columns as in the file), k >= 3.
    """
    path = Path(path)
    rows = _rows(path, "polygon file")
    first = next(rows, None)
    if first is None:
        raise DataError("empty polygon file", path=path)
    declared = _count(first[1], first[0], "polygon count", path)
    polygons: list[NDArray[np.float64]] = []
    for polygon in range(declared):
        head = next(rows, None)
        if head is None:
            raise DataError(f"declares {declared} polygons but ends after {polygon}", path=path)
        number, tokens = head
        vertices = _count(tokens, number, f"vertex count of polygon {polygon}", path)
        if vertices < 3:
            raise DataError(f"line {number}: polygon {polygon} has {vertices} vertices", path=path)
        start = next(rows, None)
        width = 0 if start is None else len(start[1])
        if start is not None and width not in (2, 3):
            raise DataError(
                f"line {start[0]}: vertex of polygon {polygon} has {width} values, expected 2 or 3",
                path=path,
            )
        values, numbers = _block_rows(
            itertools.chain([start] if start else [], rows),
            vertices,
            width or 3,
            path,
            row=f"vertex of polygon {polygon}",
        )
        if len(numbers) < vertices:
            raise DataError(
                f"polygon {polygon} declares {vertices} vertices but the file ends after "
                f"{len(numbers)}",
                path=path,
            )
        polygons.append(values)
    extra = sum(1 for _ in rows)
    if extra:
        raise DataError(
            f"{extra} unexpected line(s) after the {declared} declared polygons", path=path
        )
    return polygons


def read_apollo_roi_points(
    path: str | os.PathLike[str], *, allow_truncated: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.int8]]:
    """Read Apollo's labelled ROI test points.

    Parameters
    ----------
    allow_truncated : bool
      Accept fewer rows than the first line declares (a prefix of the file, like the
      676-point excerpt of ``poly_mask_ut.pcd``). More rows than declared is always an
      error.

    Returns
    -------
    xy : (n, 2) float64
    labels : (n,) int8
      +1 inside the ROI, -1 outside.
    """
    path = Path(path)
    rows = _rows(path, "ROI point file")
    first = next(rows, None)
    if first is None:
        raise DataError("empty ROI point file", path=path)
    declared = _count(first[1], first[0], "point count", path)
    values, numbers = _block_rows(rows, declared, 3, path, expected="x y label")
    held = len(numbers) + sum(1 for _ in rows)
    if held > declared or (held < declared and not allow_truncated):
        hint = "; pass allow_truncated=True for a prefix" if held < declared else ""
        raise DataError(f"declares {declared} points but holds {held}{hint}", path=path)
    labels = values[:, 2]
    valid = np.isin(labels, (-1.0, 1.0))
    if not valid.all():
        bad = int(np.flatnonzero(~valid)[0])
        raise DataError(
            f"line {numbers[bad]}: label {format(labels[bad], 'g')!r} is not +1 or -1",
            path=path,
        )
    return values[:, :2].copy(), labels.astype(np.int8)


def read_apollo_clusters(path: str | os.PathLike[str]) -> list[PointCloud]:
    """Read an object-builder cluster file: one cloud per line (intensity 0-255)."""
    path = Path(path)
    clouds = []
    for number, tokens in _rows(path, "cluster file"):
        declared = _count(tokens[:1], number, "point count", path)
        if len(tokens) != 1 + 4 * declared:
            raise DataError(
                f"line {number}: declares {declared} points ({4 * declared} values) but holds "
                f"{len(tokens) - 1} values",
                path=path,
            )
        values = _floats(tokens[1:], number, path).reshape(declared, 4)
        clouds.append(PointCloud(values, name=f"{path} line {number}"))
    return clouds


@dataclass(frozen=True)
class ApolloPose:
    """A LiDAR pose from an Apollo ``.pose`` file.

    Attributes
    ----------
    frame_id : int
    timestamp : float
      Seconds (GPS/Unix, as recorded).
    translation : (3,) float64
      UTM easting, northing, height in metres.
    quaternion : (4,) float64
      x, y, z, w; normalised.
    """

    frame_id: int
    timestamp: float
    translation: NDArray[np.float64]
    quaternion: NDArray[np.float64]

    def matrix(self) -> NDArray[np.float64]:
        """(4, 4) float64 homogeneous transform, sensor frame to world frame."""
        x, y, z, w = self.quaternion
        rotation = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        out = np.eye(4)
        out[:3, :3] = rotation
        out[:3, 3] = self.translation
        return out


def read_apollo_pose(path: str | os.PathLike[str]) -> ApolloPose:
    """Read an Apollo ``.pose`` file (one line of 9 values)."""
    path = Path(path)
    lines = list(itertools.islice(_rows(path, "pose file"), 2))
    if len(lines) != 1 or len(lines[0][1]) != 9:
        got = "more lines" if len(lines) > 1 else "no line"
        if len(lines) == 1:
            got = f"{len(lines[0][1])} values"
        raise DataError(
            f"expected one line 'frame_id timestamp x y z qx qy qz qw', got {got}", path=path
        )
    number, tokens = lines[0]
    frame_id = _count(tokens[:1], number, "frame id", path)
    values = _floats(tokens[1:], number, path)
    quaternion = values[4:8]
    norm = float(np.linalg.norm(quaternion))
    if not math.isclose(norm, 1.0, abs_tol=1e-3):
        raise DataError(f"quaternion {quaternion.tolist()} has norm {norm:.6f}, not 1", path=path)
    return ApolloPose(frame_id, float(values[0]), values[1:4].copy(), quaternion / norm)
