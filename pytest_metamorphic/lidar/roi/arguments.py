"""Argument checks of the ROI's constructors and transforms (named errors, no numpy traces)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument


def _positive_float(value: Any, name: str) -> float:
    number = _finite_float(value, name)
    if number <= 0:
        raise InvalidArgument(f"{name}={value!r} must be > 0")
    return number


def _finite_float(value: Any, name: str) -> float:
    if isinstance(value, bool):
        raise InvalidArgument(f"{name}={value!r} must be a number")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidArgument(f"{name}={value!r} must be a number") from None
    if not math.isfinite(number):
        raise InvalidArgument(f"{name}={value!r} must be finite")
    return number


def _non_negative_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidArgument(f"{name}={value!r} must be a non-negative int")
    return int(value)


MAX_BITMAP_SIDE = 16384  # cells a side of the ROI bitmap: 268 million cells, 268 MB


def _grid_arguments(cell_size: Any, raster_range: Any) -> tuple[float, float]:
    """The bitmap's cell size and half-width, checked: positive, the range wider than a
    cell, and a bitmap of at most :data:`MAX_BITMAP_SIDE` cells a side (an artifact's
    1e-9 m cell over 1e9 m asked for 149 GiB at the first lookup)."""
    cell = _positive_float(cell_size, "cell_size")
    half = _positive_float(raster_range, "raster_range")
    if half <= cell:
        raise InvalidArgument(f"raster_range={half} must be larger than cell_size={cell}")
    side = 2.0 * half / cell
    if side > MAX_BITMAP_SIDE:
        raise InvalidArgument(
            f"cell_size={cell:g} over raster_range={half:g} makes a bitmap of {side:.3g} "
            f"cells a side; at most {MAX_BITMAP_SIDE} (Apollo: 0.25 m over 120 m, 960): "
            f"raise cell_size to at least {2.0 * half / MAX_BITMAP_SIDE:.3g}"
        )
    return cell, half
