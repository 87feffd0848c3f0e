"""Road corridors and junctions as ROI polygons: buffered centre lines with round joins."""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument

# Vertices of the polygon standing in for a round join between road segments.
_JOIN_SIDES = 16


def _road_pieces(road: Any, name: str) -> list[NDArray[np.float64]]:
    try:
        centerline = np.asarray(road.centerline, dtype=np.float64)
        width = float(road.width)
    except AttributeError:
        raise InvalidArgument(
            f"{name} needs .centerline ((k, 2) metres) and .width (metres), got "
            f"{type(road).__name__}"
        ) from None
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"{name}: bad centerline or width ({error})") from None
    if centerline.ndim != 2 or centerline.shape[1] != 2 or len(centerline) < 2:
        raise InvalidArgument(
            f"{name}.centerline must have shape (k >= 2, 2), got {centerline.shape}"
        )
    if not np.isfinite(centerline).all():
        raise InvalidArgument(f"{name}.centerline has non-finite values")
    if not (math.isfinite(width) and width > 0):
        raise InvalidArgument(f"{name}.width={width} must be a positive number of metres")
    half = width / 2.0
    keep = np.concatenate([[True], np.abs(np.diff(centerline, axis=0)).max(axis=1) > 1e-9])
    points = centerline[keep]
    if len(points) < 2:
        raise InvalidArgument(f"{name}.centerline has fewer than 2 distinct points")
    pieces = []
    for a, b in itertools.pairwise(points):
        direction = (b - a) / np.linalg.norm(b - a)
        normal = np.array([-direction[1], direction[0]]) * half
        pieces.append(np.stack([a - normal, b - normal, b + normal, a + normal]))
    angles = np.linspace(0.0, 2 * math.pi, _JOIN_SIDES, endpoint=False)
    circle = np.stack([np.cos(angles), np.sin(angles)], axis=1) * half
    pieces.extend(vertex + circle for vertex in points)
    return pieces
