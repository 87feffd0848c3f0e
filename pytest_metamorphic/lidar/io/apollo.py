"""Baidu Apollo's text test-data formats (perception module).

* ``*.poly`` (HD-map ROI filter unit test): the polygon count, then per polygon its
  vertex count and one ``x y z`` (or ``x y``) row per vertex.
* The ROI filter's labelled points (``poly_mask_ut.pcd``, not a PCD despite the name):
  the point count, then ``x y label`` rows, label +1 inside the ROI and -1 outside.
* Object-builder clusters (``min_box_object_builder/*.pcd``, not PCD either): one
  cluster per line, ``n x1 y1 z1 i1 ... xn yn zn in``.
* ``*.pose``: ``frame_id timestamp x y z qx qy qz qw`` (UTM metres; Hamilton
  quaternion, scalar last).

Declared counts are checked against what the file holds before anything is allocated.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.lidar.model.cloud import PointCloud

__all__ = [
    "ApolloPose",
    "read_apollo_clusters",
    "read_apollo_poly",
    "read_apollo_pose",
    "read_apollo_roi_points",
]

MAX_TEXT_BYTES = 64 << 20


def _lines(path: str | os.PathLike[str], what: str) -> tuple[Path, list[tuple[int, list[str]]]]:
    """Non-empty lines as (line number, tokens)."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_TEXT_BYTES:
            raise DataError(
                f"{what} is {size} bytes, over the {MAX_TEXT_BYTES}-byte limit", path=path
            )
        text = path.read_bytes().decode("utf-8")
    except OSError as error:
        raise DataError(f"cannot read {what}: {error.strerror or error}", path=path) from None
    except UnicodeDecodeError as error:
        raise DataError(f"{what} is not text (byte {error.start})", path=path) from None
    lines = [(number, line.split()) for number, line in enumerate(text.splitlines(), 1)]
    return path, [(number, tokens) for number, tokens in lines if tokens]


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
    path, lines = _lines(path, "polygon file")
    if not lines:
        raise DataError("empty polygon file", path=path)
    number, tokens = lines[0]
    polygons_declared = _count(tokens, number, "polygon count", path)
    polygons: list[NDArray[np.float64]] = []
    cursor = 1
    for polygon in range(polygons_declared):
        if cursor >= len(lines):
            raise DataError(
                f"declares {polygons_declared} polygons but ends after {polygon}", path=path
            )
        number, tokens = lines[cursor]
        vertices = _count(tokens, number, f"vertex count of polygon {polygon}", path)
        if vertices < 3:
            raise DataError(f"line {number}: polygon {polygon} has {vertices} vertices", path=path)
        rows = lines[cursor + 1 : cursor + 1 + vertices]
        if len(rows) < vertices:
            raise DataError(
                f"polygon {polygon} declares {vertices} vertices but the file ends after "
                f"{len(rows)}",
                path=path,
            )
        width = len(rows[0][1])
        for row_number, row in rows:
            if len(row) not in (2, 3) or len(row) != width:
                raise DataError(
                    f"line {row_number}: vertex of polygon {polygon} has {len(row)} values, "
                    f"expected {width if width in (2, 3) else '2 or 3'}",
                    path=path,
                )
        polygons.append(np.stack([_floats(row, row_number, path) for row_number, row in rows]))
        cursor += 1 + vertices
    if cursor != len(lines):
        raise DataError(
            f"{len(lines) - cursor} unexpected line(s) after the {polygons_declared} declared "
            f"polygons (line {lines[cursor][0]})",
            path=path,
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
    path, lines = _lines(path, "ROI point file")
    if not lines:
        raise DataError("empty ROI point file", path=path)
    number, tokens = lines[0]
    declared = _count(tokens, number, "point count", path)
    rows = lines[1:]
    if len(rows) > declared or (len(rows) < declared and not allow_truncated):
        hint = "; pass allow_truncated=True for a prefix" if len(rows) < declared else ""
        raise DataError(f"declares {declared} points but holds {len(rows)}{hint}", path=path)
    values = np.empty((len(rows), 3), np.float64)
    for index, (row_number, row) in enumerate(rows):
        if len(row) != 3:
            raise DataError(f"line {row_number}: {len(row)} values, expected x y label", path=path)
        values[index] = _floats(row, row_number, path)
    labels = values[:, 2]
    if not np.isin(labels, (-1.0, 1.0)).all():
        bad = int(np.flatnonzero(~np.isin(labels, (-1.0, 1.0)))[0])
        raise DataError(
            f"line {rows[bad][0]}: label {rows[bad][1][2]!r} is not +1 or -1", path=path
        )
    return values[:, :2].copy(), labels.astype(np.int8)


def read_apollo_clusters(path: str | os.PathLike[str]) -> list[PointCloud]:
    """Read an object-builder cluster file: one cloud per line (intensity 0-255)."""
    path, lines = _lines(path, "cluster file")
    clouds = []
    for number, tokens in lines:
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
    path, lines = _lines(path, "pose file")
    if len(lines) != 1 or len(lines[0][1]) != 9:
        got = f"{len(lines)} lines" if len(lines) != 1 else f"{len(lines[0][1])} values"
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
