"""The car's sensor: actors within range and field of view that are not hidden behind others."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.kinematics.geometry import Box, Point, _centre, _segment_hits_box

__all__ = ["Sensor"]


@dataclass(frozen=True)
class Sensor:
    """The car's object sensor (ground truth, limited by range, field of view and occlusion).

    Parameters
    ----------
    range : float
        Metres from the front bumper.
    field_of_view : float
        Full horizontal opening angle in degrees (180: everything ahead of the bumper).
    occlusion : bool
        Hide actors completely behind other actors (the parked cars of CPNCO).
    """

    range: float = 100.0
    field_of_view: float = 180.0
    occlusion: bool = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.range) and self.range > 0):
            raise InvalidArgument(f"Sensor range={self.range!r} must be > 0")
        if not 0 < self.field_of_view <= 360:
            raise InvalidArgument(
                f"Sensor field_of_view={self.field_of_view!r} must be in (0, 360] degrees"
            )

    def sees(self, origin: Point, heading: float, box: Box, occluders: Sequence[Box]) -> bool:
        """Whether ``box`` is visible from ``origin`` looking along ``heading`` (radians).

        Visible means: the box's centre or one of its corners is within range and field of
        view, with a line of sight that passes through no occluder.
        """
        half_fov = math.radians(self.field_of_view) / 2
        for point in (_centre(box), *box):
            dx, dy = point[0] - origin[0], point[1] - origin[1]
            if math.hypot(dx, dy) > self.range:
                continue
            bearing = (math.atan2(dy, dx) - heading + math.pi) % (2 * math.pi) - math.pi
            if abs(bearing) > half_fov + 1e-9:
                continue
            if not self.occlusion or not any(
                _segment_hits_box(origin, point, occluder) for occluder in occluders
            ):
                return True
        return False
