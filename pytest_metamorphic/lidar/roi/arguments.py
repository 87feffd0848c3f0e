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
