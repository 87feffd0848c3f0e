"""A LiDAR frame: one cloud plus what is known about it (ROI, ground truth, pose, origin)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors.identify import as_sensor
from pytest_metamorphic.lidar.model.sensors.layout import ScanPattern

__all__ = ["Frame"]


@dataclass(frozen=True, eq=False)
class Frame:
    """One LiDAR sweep with its context.

    Parameters
    ----------
    cloud : PointCloud
    roi : object or None
      The region of interest (usually a :class:`pytest_metamorphic.lidar.roi.ROI`); any
      object is kept as is.
    boxes : iterable of Box
      Ground-truth obstacles in the cloud's frame (KITTI labels), empty when unknown.
    pose : (4, 4) array_like or None
      Sensor-to-world transform, when known. Stored as a read-only float64 array.
    source : str
      Where the frame came from: a file path, or ``bag [topic #i]``.
    index : int
      Position of the frame in its source sequence (0 for a single file).
    sensor : ScanPattern or None
      The sensor that recorded it (from :mod:`pytest_metamorphic.lidar.model.sensors`,
      e.g. ``VLP16``; a catalogue key such as ``"vlp16"`` is accepted too); None:
      identified from the cloud when a relation needs it
      (:func:`~pytest_metamorphic.lidar.model.sensors.frame_sensor`).

    Notes
    -----
    Frames compare by identity (a cloud has no cheap equality); use
    ``a.cloud.equals(b.cloud)`` to compare contents.
    """

    cloud: PointCloud
    roi: Any = None
    boxes: tuple[Box, ...] = field(default=())
    pose: NDArray[np.float64] | None = None
    source: str = ""
    index: int = 0
    sensor: ScanPattern | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.cloud, PointCloud):
            raise InvalidArgument(f"cloud must be a PointCloud, got {type(self.cloud).__name__}")
        boxes = tuple(self.boxes) if isinstance(self.boxes, Iterable) else None
        if boxes is None or not all(isinstance(box, Box) for box in boxes):
            raise InvalidArgument(f"boxes must be an iterable of Box, got {self.boxes!r}")
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "pose", _as_pose(self.pose))
        if isinstance(self.index, bool) or not isinstance(self.index, (int, np.integer)):
            raise InvalidArgument(f"index={self.index!r} must be an integer")
        if self.index < 0:
            raise InvalidArgument(f"index={self.index} must be >= 0")
        object.__setattr__(self, "index", int(self.index))
        object.__setattr__(self, "source", str(self.source))
        object.__setattr__(self, "sensor", as_sensor(self.sensor))

    def with_cloud(self, cloud: PointCloud) -> Frame:
        """The same frame (ROI, boxes, pose, origin) around another cloud: a follow-up."""
        return Frame(cloud, self.roi, self.boxes, self.pose, self.source, self.index, self.sensor)

    def __repr__(self) -> str:
        # Compact: Hypothesis prints it in every falsifying example.
        parts = [f"{self.source or '<memory>'}#{self.index}", f"{len(self.cloud)} points"]
        if self.boxes:
            labels: dict[str, int] = {}
            for box in self.boxes:
                labels[box.label] = labels.get(box.label, 0) + 1
            parts.append(", ".join(f"{count} {label}" for label, count in labels.items()))
        if self.roi is not None:
            parts.append(f"roi={type(self.roi).__name__}")
        if self.pose is not None:
            parts.append("pose")
        if self.sensor is not None:
            parts.append(self.sensor.short_name)
        return f"Frame({'; '.join(parts)})"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        # Hypothesis would print a dataclass field by field (the whole cloud's fields).
        printer.text(repr(self))


def _as_pose(pose: ArrayLike | None) -> NDArray[np.float64] | None:
    if pose is None:
        return None
    try:
        matrix = np.array(pose, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"pose cannot be converted to a (4, 4) array: {error}") from None
    if matrix.shape != (4, 4):
        raise InvalidArgument(f"pose must have shape (4, 4), got {matrix.shape}")
    if not np.isfinite(matrix).all():
        raise InvalidArgument("pose has NaN or infinite entries")
    if not np.allclose(matrix[3], (0.0, 0.0, 0.0, 1.0)):
        raise InvalidArgument(f"pose's last row must be (0, 0, 0, 1), got {matrix[3].tolist()}")
    matrix.flags.writeable = False
    return matrix
