"""The operating domain: the part of a car's world a test varies, as data.

A relation that varies only what its authors imagined leaves whole dimensions of the
car's world untested: the sensor's pose (a car pitches when it brakes, rolls in a bend,
sits lower when loaded; a mount is a degree off its calibration), the terrain (grades,
crests), the near field (the first metres around the car) and the far field.
:class:`OperatingDomain` states those dimensions and their ranges once; relations draw
their follow-ups from it (:func:`~pytest_metamorphic.relations.lidar.sensor_pose`), and a
user states their own car's and routes' ranges instead of the defaults::

    from pytest_metamorphic.lidar.model.domain import OperatingDomain

    delivery_van = OperatingDomain(pitch_deg=(-2.0, 4.0), height_m=(-0.12, 0.05))

The defaults are figures of real passenger cars and roads, each with its source:

* **pitch** ±3°: a braking car's body dives by 1-3 degrees per g of deceleration (its
  pitch gradient; Gillespie, *Fundamentals of Vehicle Dynamics*, SAE 1992, ch. 2 and 7),
  and an emergency stop decelerates at about 1 g (the AEB figures in ``REFERENCE.md``
  §7 use 9.8 m/s²); a loaded boot lifts the nose by about a degree; a roof mount sits
  within about a degree of its calibration;
* **roll** ±2.5°: passenger cars roll by 3-7 degrees per g of lateral acceleration
  (roll gradient, Gillespie ch. 8), everyday bends stay below 0.4 g;
* **height** -0.15 m to +0.15 m from the recording's mount height: a car loaded to its
  permitted mass sits up to about 10 cm lower on its springs, tyre pressure and ride
  height settings move it by centimetres, and the same stack goes onto sister vehicles
  whose roof racks differ by a few centimetres (a stack meant for *another* mount height,
  KITTI's 1.73 m against nuScenes' 1.84 m, needs a domain of its own);
* **grade** ±8 %: the steepest grades of urban arterial roads in AASHTO's *A Policy on
  Geometric Design of Highways and Streets* (the "Green Book": 5-8 % for arterials,
  up to 15 % for local streets, 3-6 % for freeways);
* **camber** 0 to 2.5 %: the normal cross slope of an urban road falling from its crown
  to the kerbs (AASHTO: 1.5-2 % on paved roads, up to 2.5 % where rain is heavy);
* **near field** 5 m: the first metres around the car, where self-filters, blind-zone
  handling and minimum ranges live (a passenger car is about 4.4 x 1.8 m, its sensor
  over the middle of its roof: a bumper is 2-2.5 m from the sensor);
* **far field**: up to the sensor's own maximum range (the sensor's catalogue entry);
* **the car itself** 4.4 x 1.8 m with the sensor over its middle: a mid-size passenger
  car (KITTI's VW Passat B6 is 4.77 x 1.82 m, its Velodyne 0.27 m behind the roof's
  middle; a Golf is 4.26 x 1.79 m). Nothing can stand inside it, so near-field
  placements keep 0.3 m clear of it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["DEFAULT_DOMAIN", "OperatingDomain"]


def _interval(name: str, value: Any, *, limit: float) -> tuple[float, float]:
    """``value`` as a (low, high) pair of finite floats with low <= high, |both| <= limit."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise InvalidArgument(f"{name}={value!r} must be a (low, high) pair of numbers")
    pair = []
    for end in value:
        if isinstance(end, bool) or not isinstance(end, (int, float)) or not math.isfinite(end):
            raise InvalidArgument(f"{name}={value!r} must be a (low, high) pair of finite numbers")
        pair.append(float(end))
    low, high = pair
    if low > high:
        raise InvalidArgument(f"{name}={value!r}: low must not exceed high")
    if max(abs(low), abs(high)) > limit:
        raise InvalidArgument(f"{name}={value!r} must stay within ±{limit:g}")
    return low, high


@dataclass(frozen=True)
class OperatingDomain:
    """The ranges a test varies, with defaults from real cars and roads (module docstring).

    Attributes
    ----------
    pitch_deg : (low, high) float
        Sensor pitch in degrees, positive nose down (a braking car), as the sensor's
        rotation about its y axis (left). Within ±15.
    roll_deg : (low, high) float
        Sensor roll in degrees, positive left side up (the car leaning to its right, as
        in a left-hand bend), about its x axis (forward). Within ±15.
    height_m : (low, high) float
        Change of the sensor's height above the road in metres, positive higher. Within
        ±1.
    grade_percent : (low, high) float
        Road grades in percent (rise over run x 100), positive uphill ahead. Within ±30.
    camber_percent : (low, high) float
        Cross slopes in percent, positive falling from the crown to both sides. Within ±8.
    near_field_m : float
        Bird's-eye distance from the sensor within which an object is in the near field.
    max_range_m : float or None
        The farthest distance objects are placed at; None: the sensor's own maximum range.
    ego_size_m : (length, width) float
        The car carrying the sensor, centred under it: no object is placed within 0.3 m
        of it.
    """

    pitch_deg: tuple[float, float] = (-3.0, 3.0)
    roll_deg: tuple[float, float] = (-2.5, 2.5)
    height_m: tuple[float, float] = (-0.15, 0.15)
    grade_percent: tuple[float, float] = (-8.0, 8.0)
    camber_percent: tuple[float, float] = (0.0, 2.5)
    near_field_m: float = 5.0
    max_range_m: float | None = None
    ego_size_m: tuple[float, float] = (4.4, 1.8)

    def __post_init__(self) -> None:
        for name, limit in (("pitch_deg", 15.0), ("roll_deg", 15.0), ("height_m", 1.0),
                            ("grade_percent", 30.0), ("camber_percent", 8.0)):  # fmt: skip
            object.__setattr__(self, name, _interval(name, getattr(self, name), limit=limit))
        for name in ("near_field_m", "max_range_m"):
            value = getattr(self, name)
            if value is None and name == "max_range_m":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidArgument(f"{name}={value!r} must be a number of metres > 0")
            if not (math.isfinite(value) and value > 0):
                raise InvalidArgument(f"{name}={value!r} must be a number of metres > 0")
            object.__setattr__(self, name, float(value))
        ego = self.ego_size_m
        if (
            isinstance(ego, (str, bytes)) or not isinstance(ego, Sequence) or len(ego) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) and 0 < v <= 30 for v in ego)
        ):  # fmt: skip
            raise InvalidArgument(
                f"ego_size_m={ego!r} must be the car's (length, width) in metres, each 0-30"
            )
        object.__setattr__(self, "ego_size_m", (float(ego[0]), float(ego[1])))

    def far_limit(self, sensor_range: float) -> float:
        """The farthest distance (m) objects are placed at with a sensor of
        ``sensor_range``: ``max_range_m`` where nearer, else the sensor's own."""
        return sensor_range if self.max_range_m is None else min(self.max_range_m, sensor_range)

    def describe(self) -> str:
        """One line, e.g. for a report: the ranges this domain varies."""
        far = "the sensor's range" if self.max_range_m is None else f"{self.max_range_m:g} m"
        return (
            f"pitch {_span(self.pitch_deg, '°')}, roll {_span(self.roll_deg, '°')}, "
            f"height {_span(self.height_m, ' m')}, grade {_span(self.grade_percent, ' %')}, "
            f"camber {_span(self.camber_percent, ' %')}, "
            f"near field {self.near_field_m:g} m, far field {far}"
        )


def _span(pair: tuple[float, float], unit: str) -> str:
    low, high = pair
    if low == -high:
        return f"±{high:g}{unit}"
    return f"{low:+g} to {high:+g}{unit}"


#: The defaults, for relations given no domain.
DEFAULT_DOMAIN = OperatingDomain()
