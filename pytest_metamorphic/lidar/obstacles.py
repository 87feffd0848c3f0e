"""Detected or ground-truth obstacles as 3-D boxes in the sensor frame."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["LABELS", "Box", "Label"]

Label = Literal["car", "pedestrian", "cyclist", "unknown"]
LABELS: tuple[Label, ...] = ("car", "pedestrian", "cyclist", "unknown")


@dataclass(frozen=True)
class Box:
    """An oriented 3-D box.

    Parameters
    ----------
    center : (3,) float
      x, y, z of the box centre in metres.
    size : (3,) float
      length (along the heading), width, height in metres; all > 0.
    yaw : float
      Heading about +z in radians, counter-clockwise from +x.
    label : {"car", "pedestrian", "cyclist", "unknown"}
    score : float or None
      Detection confidence, when the detector gives one.
    points : int or None
      How many LiDAR points support the box (detectors fill this in).
    """

    center: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0
    label: Label = "unknown"
    score: float | None = None
    points: int | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        center = tuple(float(v) for v in self.center)
        size = tuple(float(v) for v in self.size)
        if len(center) != 3 or len(size) != 3:
            raise InvalidArgument(f"Box center and size need 3 values, got {center}, {size}")
        if not all(math.isfinite(v) for v in (*center, *size, float(self.yaw))):
            raise InvalidArgument(f"Box has non-finite values: center={center} size={size}")
        if min(size) <= 0:
            raise InvalidArgument(f"Box size must be positive, got {size}")
        if self.label not in LABELS:
            raise InvalidArgument(f"Box label {self.label!r} must be one of {LABELS}")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "yaw", float(self.yaw))

    def corners_bev(self) -> NDArray[np.float64]:
        """(4, 2) float64: bird's-eye corners, counter-clockwise."""
        length, width, _ = self.size
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = np.array(
            [[length, width], [-length, width], [-length, -width], [length, -width]]
        ) / 2.0
        rotation = np.array([[c, -s], [s, c]])
        return local @ rotation.T + np.array(self.center[:2])

    def describe(self) -> str:
        """Short human description, e.g. ``car at (12.1, -3.4)``."""
        x, y, _ = self.center
        return f"{self.label} at ({x:.1f}, {y:.1f})"

    def __str__(self) -> str:
        return self.describe()
