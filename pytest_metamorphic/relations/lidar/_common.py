"""Helpers shared by the LiDAR relation modules."""

from __future__ import annotations

from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame

# An empty frame: strategies built on it validate a relation's arguments when it is made.
_PROBE = Frame(PointCloud.empty(), source="argument check")


def _frame(value: Any) -> Frame:
    if not isinstance(value, Frame):
        raise InvalidArgument(
            f"LiDAR relations need Frame source inputs (with .roi), got {type(value).__name__}"
        )
    return value


def _check_size(value: Any, name: str, *, allow_none: bool = False) -> None:
    if value is None and allow_none:
        return
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InvalidArgument(f"{name}={value!r} must be a positive int")
