"""Mirror symmetry of a scene: reflect the sweep, the ROI and the boxes in the car's x axis.

Left and right traffic scenes are mirror images of each other; nothing in the physics of a
LiDAR or of obstacle detection prefers one side, so a detector's obstacles should mirror
with the scene. The reflection maps a sensor-anchored bird's-eye grid onto itself (cell
borders at multiples of the cell size stay borders), so a grid-based detector sees the same
points in mirrored cells.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.frame import Frame

__all__ = ["MirrorAcrossX"]


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
