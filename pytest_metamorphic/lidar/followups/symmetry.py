"""Symmetries of a scene: reflect the sweep, the ROI and the boxes in the car's x axis, or
shift them all along it.

Left and right traffic scenes are mirror images of each other; nothing in the physics of a
LiDAR or of obstacle detection prefers one side, so a detector's obstacles should mirror
with the scene. The reflection maps a sensor-anchored bird's-eye grid onto itself (cell
borders at multiples of the cell size stay borders), so a grid-based detector sees the same
points in mirrored cells.

A shift is not something a sensor could see (ranges and beam footprints change with it);
it tests the narrower claim some detectors make, that their bird's-eye processing is
translation invariant for shifts by whole grid cells.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame

__all__ = ["MirrorAcrossX", "ShiftAlongX", "ShiftScene"]


@dataclass(frozen=True)
class MirrorAcrossX:
    """Reflect a frame in the sensor's x axis (the car's forward axis): y -> -y for every
    point, the ROI (rasterised afresh) and the boxes (heading -> -heading)."""

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        points = frame.cloud.points.copy()
        points[:, 1] = -points[:, 1]
        roi = frame.roi
        if roi is not None:
            mirror = getattr(roi, "mirrored", None)
            if not callable(mirror):
                raise InvalidArgument(f"the frame's roi ({type(roi).__name__}) has no mirrored()")
            roi = mirror()
        return dataclasses.replace(
            frame,
            cloud=frame.cloud.with_points(points),
            roi=roi,
            boxes=tuple(box.mirrored() for box in frame.boxes),
        )

    def params(self) -> dict[str, Any]:
        return {"mirrored": "y -> -y"}


@dataclass(frozen=True)
class ShiftAlongX:
    """Shift a frame's points, ROI (rasterised afresh) and boxes by ``dx`` metres along x.

    Parameters
    ----------
    dx : float
        Metres; a multiple of the detector's grid cell for a translation-invariance test.
    """

    dx: float

    def __post_init__(self) -> None:
        value = self.dx
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"dx={value!r} must be a finite number of metres")
        if not math.isfinite(value):
            raise InvalidArgument(f"dx={value!r} must be a finite number of metres")
        object.__setattr__(self, "dx", float(value))

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        points = frame.cloud.points.copy()
        points[:, 0] += np.float32(self.dx)
        roi = frame.roi
        if roi is not None:
            move = getattr(roi, "translated", None)
            if not callable(move):
                raise InvalidArgument(f"the frame's roi ({type(roi).__name__}) has no translated()")
            roi = move(self.dx, 0.0)
        return dataclasses.replace(
            frame,
            cloud=frame.cloud.with_points(points),
            roi=roi,
            boxes=tuple(box.translated(self.dx, 0.0) for box in frame.boxes),
        )

    def params(self) -> dict[str, Any]:
        return {"shift_x_m": self.dx}


@dataclass(frozen=True)
class ShiftScene:
    """Shift a frame's points, ROI (rasterised afresh) and boxes by ``(dx, dy)`` metres.

    :class:`ShiftAlongX` for any shift: by amounts that are no multiple of a detector's
    grid cell, every cell border cuts the scene elsewhere.
    """

    dx: float
    dy: float

    def __post_init__(self) -> None:
        for name in ("dx", "dy"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidArgument(f"{name}={value!r} must be a finite number of metres")
            if not math.isfinite(value):
                raise InvalidArgument(f"{name}={value!r} must be a finite number of metres")
            object.__setattr__(self, name, float(value))

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        points = frame.cloud.points.copy()
        points[:, 0] += np.float32(self.dx)
        points[:, 1] += np.float32(self.dy)
        roi = frame.roi
        if roi is not None:
            move = getattr(roi, "translated", None)
            if not callable(move):
                raise InvalidArgument(f"the frame's roi ({type(roi).__name__}) has no translated()")
            roi = move(self.dx, self.dy)
        return dataclasses.replace(
            frame,
            cloud=frame.cloud.with_points(points),
            roi=roi,
            boxes=tuple(box.translated(self.dx, self.dy) for box in frame.boxes),
        )

    def params(self) -> dict[str, Any]:
        return {"shift_x_m": self.dx, "shift_y_m": self.dy}
