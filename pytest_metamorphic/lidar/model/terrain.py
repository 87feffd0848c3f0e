"""The road's shape around the car: grades, crests, dips and camber, as a height field.

Every rendered street was flat and every recording is what it is, so no relation put the
car on an uphill road, before a crest or across a cambered road, where a ground model
written for a flat road fails (a plane through the lowest returns, a height band in the
sensor frame, a slope limit tuned on level car parks). :class:`Terrain` describes the road
around the sensor as a height above the flat road it replaces:

* a **grade change** ``start_m`` metres ahead (along the sensor's x): from level to
  ``grade_percent`` (rise over run x 100; positive uphill) over a parabolic vertical
  curve ``curve_m`` long, as road design lays them out (AASHTO's Green Book: the
  vertical curve between two grades is a parabola). Uphill ahead of a level stretch is
  a *sag* (a dip's far side), downhill ahead is a *crest*;
* **camber** ``camber_percent``: the road falls away from its crown (the line
  ``y = crown_y_m``) to both sides by that cross slope (1.5-2.5 % on urban roads,
  AASHTO's normal cross slope).

The sensor's own ground (at x <= ``start_m``, on the crown) is the flat road: the sensor
keeps its mount height above it. A grade is the same on both sides of the crown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["FLAT", "Terrain"]


def _number(name: str, value: Any, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InvalidArgument(f"{name}={value!r} must be a finite number")
    if not low <= value <= high:
        raise InvalidArgument(f"{name}={value!r} must be between {low:g} and {high:g}")
    return float(value)


@dataclass(frozen=True)
class Terrain:
    """A road's height field around the sensor (module docstring).

    Attributes
    ----------
    grade_percent : float
        The grade reached ahead, positive uphill; within ±30.
    start_m : float
        Metres ahead (x) where the vertical curve begins; 0 to 100.
    curve_m : float
        Length of the vertical curve (m), > 0: the grade grows linearly along it.
    camber_percent : float
        Cross slope away from the crown, positive falling to both sides; within ±8.
    crown_y_m : float
        Where the crown lies (y, metres).
    """

    grade_percent: float = 0.0
    start_m: float = 10.0
    curve_m: float = 20.0
    camber_percent: float = 0.0
    crown_y_m: float = 0.0

    def __post_init__(self) -> None:
        for name, low, high in (("grade_percent", -30.0, 30.0), ("start_m", 0.0, 100.0),
                                ("curve_m", 0.1, 500.0), ("camber_percent", -8.0, 8.0),
                                ("crown_y_m", -50.0, 50.0)):  # fmt: skip
            object.__setattr__(self, name, _number(name, getattr(self, name), low, high))

    @property
    def flat(self) -> bool:
        return self.grade_percent == 0.0 and self.camber_percent == 0.0

    def height(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
        """Height (m) of the road above the flat road at bird's-eye ``(x, y)``."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        grade = self.grade_percent / 100.0
        along = np.clip(x - self.start_m, 0.0, None)
        within = np.minimum(along, self.curve_m)
        # The parabola's grade grows from 0 to ``grade`` along the curve, then stays.
        rise = grade * within**2 / (2.0 * self.curve_m) + grade * (along - within)
        fall = self.camber_percent / 100.0 * np.abs(y - self.crown_y_m)
        return rise - fall

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        """(dz/dx, dz/dy) of the road at ``(x, y)``: how a thing standing there tilts."""
        grade = self.grade_percent / 100.0
        along = x - self.start_m
        dzdx = 0.0 if along <= 0 else grade * min(along / self.curve_m, 1.0)
        dzdy = -self.camber_percent / 100.0 * math.copysign(1.0, y - self.crown_y_m)
        return dzdx, dzdy if y != self.crown_y_m else 0.0

    def params(self) -> dict[str, Any]:
        return {
            "grade_percent": self.grade_percent,
            "grade_start_m": self.start_m,
            "grade_curve_m": self.curve_m,
            "camber_percent": self.camber_percent,
            "crown_y_m": self.crown_y_m,
        }

    def describe(self) -> str:
        if self.flat:
            return "a flat road"
        parts = []
        if self.grade_percent:
            kind = "uphill" if self.grade_percent > 0 else "downhill"
            parts.append(
                f"{abs(self.grade_percent):g} % {kind} from {self.start_m:g} m ahead "
                f"(over a {self.curve_m:g} m curve)"
            )
        if self.camber_percent:
            parts.append(f"{self.camber_percent:g} % camber")
        return "a road " + " and ".join(parts)


FLAT = Terrain()
"""The flat road every rendering had before."""
