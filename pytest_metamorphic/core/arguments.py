"""Checking numeric arguments early, with an error that names the argument."""

from __future__ import annotations

import math
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["check_number"]


def check_number(value: Any, name: str, *, positive: bool = False) -> float:
    """``value`` as a float when it is a finite number >= 0 (> 0 with ``positive``).

    Raises
    ------
    InvalidArgument
        Naming ``name`` (e.g. ``"VehicleSpec brake_delay"``) and the value.
    """
    ok = (
        not isinstance(value, bool)
        and isinstance(value, (int, float))
        and math.isfinite(value)
        and (value > 0 if positive else value >= 0)
    )
    if not ok:
        bound = "> 0" if positive else ">= 0"
        raise InvalidArgument(f"{name}={value!r} must be a finite number {bound}")
    return float(value)
