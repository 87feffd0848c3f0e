"""Fog and rain as follow-up transforms: attenuated returns and echoes from droplets.

A physical model after LISA (Kilic et al. 2021) and LiRTest's weather operators, reduced
to what a recorded sweep lets us compute:

* **Attenuation** (Beer-Lambert): a return at range ``r`` comes back with
  ``exp(-2 α r)`` of its clear-air power, where the extinction coefficient follows from
  the meteorological optical range ``V`` (the visibility, 5 % contrast): ``α = 3.0 / V``.
  Its intensity is scaled by the same factor. It is still detected while
  ``ρ exp(-2 α r) / r² >= τ``, with ``τ`` set by the frame's sensor's specification
  (``ScanPattern.detection``: for the HDL-64E a 10 % reflective target is seen to 50 m,
  for an OS1-64 to 40 m; the HDL-64E's when the sensor is not known) and ``ρ`` the
  return's intensity read as reflectance (0-1; 0-255 scales are divided by 255), but never
  less than twice what it needed to be seen in clear air: every recorded return *was*
  detected, and a return recorded with intensity 0 (a tenth of a KITTI sweep) is taken to
  have had a 3 dB margin, not none.
* **Droplet echoes** (backscatter): along each beam the first droplet lies at an
  exponentially distributed range (mean ``1 / α``); with probability ``scatter`` (fog:
  0.1, rain: 0.02; rain drops are larger and fewer) it reflects enough to be reported
  instead of what lies behind it, if it is nearer than that and within the range at which
  a droplet of 2 % reflectance is at the detection threshold (22 m for the HDL-64E). The
  return moves along its beam to the droplet, with the droplet's intensity (0.02); its
  fields (ring, ...) stay.

Beams that returned nothing in the recording (the sky) cannot be given echoes: a real
sensor would show a few more. The randomness comes from ``seed`` only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import intensity_scale
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.sensors import frame_sensor

__all__ = ["SCATTER", "WEATHER_KINDS", "Weather", "WeatherKind", "extinction"]

WeatherKind = Literal["fog", "rain"]
WEATHER_KINDS: tuple[WeatherKind, ...] = ("fog", "rain")
SCATTER: dict[str, float] = {"fog": 0.1, "rain": 0.02}
"""Default share of beams whose first droplet echo is strong enough to be reported."""

_THRESHOLD = 0.10 / 50.0**2  # reflectance / range² at the detection limit (HDL-64E spec)
_CLEAR_AIR_MARGIN = 2.0  # the least a recorded return is assumed to exceed the threshold by
_DROPLET_REFLECTANCE = 0.02
_MIN_RANGE = 0.9  # metres: nearer echoes are blocked by the housing (see BeamLayout)


def _sensor_limits(frame: Frame) -> tuple[float, float]:
    """(reflectance / range² at the detection limit, minimum range) of the frame's sensor:
    its datasheet's (e.g. a 10 % target at 40 m for an OS1-64), the HDL-64E's when the
    sensor is not known."""
    sensor = frame_sensor(frame).sensor if len(frame.cloud) else None
    if sensor is None:
        return _THRESHOLD, _MIN_RANGE
    reflectance, reach = sensor.detection
    return reflectance / reach**2, sensor.min_range


def extinction(visibility: float) -> float:
    """Extinction coefficient (1/m) for a meteorological optical range of ``visibility``
    metres (Koschmieder, 5 % contrast: ``-ln 0.05 / V``)."""
    return -math.log(0.05) / visibility


@dataclass(frozen=True)
class Weather:
    """Fog or rain of the given visibility applied to a sweep.

    Parameters
    ----------
    visibility : float
        Meteorological optical range in metres (> 0): dense fog 50 m, fog 200 m; heavy
        rain is usually a few hundred metres to a kilometre.
    kind : {"fog", "rain"}
        Sets the default ``scatter``.
    seed : int
        Seeds the droplet echoes.
    scatter : float, optional
        Share of beams whose first droplet is reported (default :data:`SCATTER`).
    """

    visibility: float
    kind: WeatherKind = "fog"
    seed: int = 0
    scatter: float | None = None

    def __post_init__(self) -> None:
        value = self.visibility
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"visibility={value!r} must be a number of metres > 0")
        if not (math.isfinite(value) and value > 0):
            raise InvalidArgument(f"visibility={value!r} must be a number of metres > 0")
        if self.kind not in WEATHER_KINDS:
            raise InvalidArgument(f"kind={self.kind!r} must be one of {WEATHER_KINDS}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)):
            raise InvalidArgument(f"seed={self.seed!r} must be an int")
        scatter = SCATTER[self.kind] if self.scatter is None else self.scatter
        if isinstance(scatter, bool) or not isinstance(scatter, (int, float)):
            raise InvalidArgument(f"scatter={scatter!r} must be a number in [0, 1]")
        if not 0.0 <= scatter <= 1.0:
            raise InvalidArgument(f"scatter={scatter!r} must be a number in [0, 1]")
        object.__setattr__(self, "visibility", float(value))
        object.__setattr__(self, "scatter", float(scatter))
        object.__setattr__(self, "seed", int(self.seed))

    @property
    def echo_probability(self) -> float:
        """``scatter`` as set (the kind's default filled in when constructed)."""
        return SCATTER[self.kind] if self.scatter is None else self.scatter

    @property
    def alpha(self) -> float:
        """Extinction coefficient in 1/m."""
        return extinction(self.visibility)

    def effects(
        self, frame: Frame
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float32]]:
        """``(lost, echo, intensity)`` per point: returns too weak to be detected, the
        droplet range replacing each return (``nan`` where none does) and the attenuated
        intensity."""
        xyz = frame.cloud.xyz.astype(np.float64)
        intensity = frame.cloud.intensity
        ranges = np.linalg.norm(xyz, axis=1)
        threshold, min_range = _sensor_limits(frame)
        floor = _CLEAR_AIR_MARGIN * threshold * ranges**2
        reflectance = np.maximum(intensity / intensity_scale(frame.cloud.intensity), floor)
        transmitted = np.exp(-2.0 * self.alpha * ranges)
        lost = reflectance * transmitted < threshold * ranges**2
        rng = np.random.default_rng([self.seed, len(xyz)])
        droplet = rng.exponential(1.0 / self.alpha, len(xyz))
        reported = rng.random(len(xyz)) < self.echo_probability
        droplet_range = math.sqrt(_DROPLET_REFLECTANCE / threshold)
        near = (droplet < ranges) & (droplet >= min_range) & (droplet <= droplet_range)
        echo = np.where(reported & near, droplet, np.nan)
        return lost, echo, (intensity * transmitted).astype(np.float32)

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        lost, echo, intensity = self.effects(frame)
        moved = ~np.isnan(echo)
        keep = moved | ~lost
        points = frame.cloud.points.copy()
        points[:, 3] = intensity
        ranges = np.linalg.norm(points[moved, :3].astype(np.float64), axis=1)
        points[moved, :3] *= (echo[moved] / ranges)[:, None].astype(np.float32)
        points[moved, 3] = _DROPLET_REFLECTANCE * intensity_scale(frame.cloud.intensity)
        return frame.with_cloud(frame.cloud.with_points(points)[keep])

    def params(self) -> dict[str, Any]:
        return {
            "weather": self.kind,
            "visibility_m": self.visibility,
            "weather_seed": self.seed,
            "weather_transform": self,
        }

    def __repr__(self) -> str:
        return f"Weather({self.kind}, visibility {self.visibility:g} m, seed {self.seed})"
