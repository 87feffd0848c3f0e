"""The sweep as a sensor in another pose receives it: pitched, rolled or at another height.

A car pitches when it brakes, rolls in a bend and sits lower when loaded, and a mount is
a degree off its calibration; a detector receives its returns in the sensor's frame (or
in a vehicle frame through a fixed extrinsic), so the road, the objects and everything
else tilt or shift in what it receives. :class:`SensorPose` makes that follow-up from a
recorded sweep by a rigid transform of every return about the sensor.

What the transform is, exactly:

* **pitch and roll** turn every return about the sensor's origin. The follow-up holds the
  same returns of the same world, in a frame turned by the pose: what a detector receives
  when the extrinsic it applies is off by that pose (the car's body pitched under braking
  while the stack assumes it level, a mount a degree off its calibration). A sensor
  physically turned would also sample the world along turned rays; here the fan of laser
  cones turns with the frame, so each laser's elevation, seen in the follow-up's frame,
  changes by at most the angle, and the follow-up is a scan pattern as real as the
  recorded one (laser numbers and every other field stay). Nothing is invented, moved
  relative to anything else, or lost.
* **height** lowers every return by the change (the sensor raised: the road is farther
  below). Exact for a mount-height calibration off by that much; for a sensor physically
  raised it leaves out the parallax of the change: shadows behind objects move by
  centimetres and the rings on the road land at other distances (a ring at range ``d``
  from a sensor ``h`` above the road moves by ``d * dh / h``), while every judged object
  keeps all of its returns.

The ROI stays as it is: it is the map's, and pitch and roll move a point's bird's-eye
position by at most its height times the angle's sine plus its range times ``1 - cos``
(0.1-0.2 m at 3 degrees and 70 m): relations judge obstacles a margin inside it. Boxes
(the frame's labels) move with the returns.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box

__all__ = ["SensorPose"]


@dataclass(frozen=True)
class SensorPose:
    """The sensor pitched by ``pitch_deg`` (nose down positive), rolled by ``roll_deg``
    (left side up positive) and raised by ``height_m``, relative to where it recorded the
    sweep.

    A return ``p`` of the source becomes ``R.T @ (p - (0, 0, height_m))`` with ``R`` the
    sensor's new orientation, ``Ry(pitch) @ Rx(roll)``: a return on the road ahead
    rises when the sensor pitches nose down, the whole road drops when it is raised.
    """

    pitch_deg: float = 0.0
    roll_deg: float = 0.0
    height_m: float = 0.0

    def __post_init__(self) -> None:
        for name, limit in (("pitch_deg", 45.0), ("roll_deg", 45.0), ("height_m", 10.0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidArgument(f"{name}={value!r} must be a finite number")
            if not (math.isfinite(value) and abs(value) <= limit):
                raise InvalidArgument(f"{name}={value!r} must be finite and within ±{limit:g}")
            object.__setattr__(self, name, float(value))

    @property
    def rotation(self) -> NDArray[np.float64]:
        """(3, 3) float64: the sensor's new orientation in the recorded frame."""
        p, r = math.radians(self.pitch_deg), math.radians(self.roll_deg)
        pitch = np.array([[math.cos(p), 0.0, math.sin(p)], [0.0, 1.0, 0.0],
                          [-math.sin(p), 0.0, math.cos(p)]])  # fmt: skip
        roll = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(r), -math.sin(r)],
                         [0.0, math.sin(r), math.cos(r)]])  # fmt: skip
        return pitch @ roll

    def transform(self, xyz: NDArray[Any]) -> NDArray[np.float64]:
        """(n, 3) float64: points of the recorded frame in the posed sensor's frame."""
        shifted = np.asarray(xyz, dtype=np.float64).reshape(-1, 3) - (0.0, 0.0, self.height_m)
        return shifted @ self.rotation  # rows times R = (R.T @ p.T).T

    def move_box(self, box: Box) -> Box:
        """Where ``box`` is in the posed sensor's frame: its centre moved with the returns,
        its bird's-eye heading turned with them (size unchanged: a box tilted by a few
        degrees covers a footprint wider by its height times the angle's sine)."""
        (center,) = self.transform(np.array([box.center]))
        heading = np.array([[math.cos(box.yaw), math.sin(box.yaw), 0.0]]) @ self.rotation
        yaw = math.atan2(float(heading[0, 1]), float(heading[0, 0]))
        x, y, z = (float(v) for v in center)
        return Box((x, y, z), box.size, yaw, box.label, box.score, box.points)

    def apply(self, frame: Frame) -> Frame:
        """``frame`` as the posed sensor receives it (the ROI unchanged: module docstring)."""
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        points = frame.cloud.points.copy()
        points[:, :3] = self.transform(frame.cloud.points[:, :3]).astype(np.float32)
        return dataclasses.replace(
            frame,
            cloud=frame.cloud.with_points(points),
            boxes=tuple(self.move_box(box) for box in frame.boxes),
        )

    def params(self) -> dict[str, Any]:
        return {
            "pitch_deg": self.pitch_deg,
            "roll_deg": self.roll_deg,
            "height_m": self.height_m,
        }

    def describe(self) -> str:
        """E.g. ``pitched 1.5° nose down, raised 0.1 m``."""
        parts = []
        if self.pitch_deg:
            way = "nose down" if self.pitch_deg > 0 else "nose up"
            parts.append(f"pitched {abs(self.pitch_deg):g}° {way}")
        if self.roll_deg:
            way = "left side up" if self.roll_deg > 0 else "right side up"
            parts.append(f"rolled {abs(self.roll_deg):g}° {way}")
        if self.height_m:
            way = "raised" if self.height_m > 0 else "lowered"
            parts.append(f"{way} {abs(self.height_m):g} m")
        return ", ".join(parts) or "as recorded"
