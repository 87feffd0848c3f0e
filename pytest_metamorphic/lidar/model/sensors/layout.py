"""How a LiDAR samples the world: the rays of one sweep, for spinning multi-beam sensors
(:class:`BeamLayout`) and non-repetitive scanners without rings (:class:`RosetteScanner`).

Both are :class:`ScanPattern` objects: what the renderer casts, what the faults need to
know (which lasers exist, how wide a data packet is, how fine the range is), and what
the weather model needs (how far a 10 % target is seen). The sensors themselves, with
the numbers from their datasheets and drivers' calibration files, are in
:mod:`.catalog`.

Simplifications (documented, deliberate): every beam starts at the sensor origin (real
lasers sit centimetres apart), all lasers of a firing fire at the same instant, and the
vehicle does not move during a sweep.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["BeamLayout", "Rays", "RosetteScanner", "ScanPattern"]


@dataclass(frozen=True)
class Rays:
    """One sweep's rays from the sensor origin.

    Attributes
    ----------
    directions : (r, 3) float64
      Unit vectors, laser-major within each azimuth step.
    ring : (r,) uint8
      Laser index of each ray (sorted by elevation, 0 = lowest, as ROS ``ring``); all 0
      for a scanner without rings.
    azimuth : (r,) float64
      Azimuth of each ray in radians, counter-clockwise from +x.
    """

    directions: NDArray[np.float64]
    ring: NDArray[np.uint8]
    azimuth: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.directions)


class ScanPattern:
    """What every sensor model offers (see :class:`BeamLayout`, :class:`RosetteScanner`).

    Attributes
    ----------
    name : str
    has_rings : bool
        Whether returns come from a fixed set of lasers that each sweep a cone (a dead
        laser then removes one ring); False for non-repetitive scanners.
    lasers : int
        Number of lasers (rings); 0 without rings.
    elevations : (lasers,) float64
        Radians, by laser id; empty without rings.
    packet_degrees : float or None
        Azimuth one data packet covers (a lost packet removes that block of every laser);
        None when packets are not azimuth blocks.
    max_range, min_range, range_noise, range_resolution : float
        Metres.
    detection : (float, float)
        ``(reflectance, range m)``: the datasheet's detection limit (a target of that
        reflectance is seen up to that range); the weather model scales it as
        reflectance / range².
    """

    name: str
    max_range: float
    min_range: float
    range_noise: float
    range_resolution: float
    detection: tuple[float, float]

    @property
    def has_rings(self) -> bool:
        raise NotImplementedError

    @property
    def lasers(self) -> int:
        raise NotImplementedError

    elevations: NDArray[np.float64]

    @property
    def packet_degrees(self) -> float | None:
        raise NotImplementedError

    def rays(self, *, azimuth_range: tuple[float, float] | None = None) -> Rays:
        raise NotImplementedError

    @property
    def short_name(self) -> str:
        """The name up to its first parenthesis or comma (for reports)."""
        return self.name.split("(")[0].split(",")[0].strip()


def _check_ranges(pattern: Any) -> None:
    if not (0 <= pattern.min_range < pattern.max_range and math.isfinite(pattern.max_range)):
        raise InvalidArgument(
            f"need 0 <= min_range < max_range < inf, got {pattern.min_range}, {pattern.max_range}"
        )
    for name in ("range_noise", "range_resolution"):
        value = getattr(pattern, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"{name}={value!r} must be a number of metres >= 0")
        if not (math.isfinite(value) and value >= 0):
            raise InvalidArgument(f"{name}={value!r} must be a number of metres >= 0")
    try:
        reflectance, reach = (float(v) for v in pattern.detection)
    except (TypeError, ValueError):
        raise InvalidArgument(
            f"detection={pattern.detection!r} must be (reflectance, range in metres)"
        ) from None
    if not (0 < reflectance <= 1 and 0 < reach <= pattern.max_range * 10):
        raise InvalidArgument(
            f"detection={pattern.detection!r} needs a reflectance in (0, 1] and a range > 0"
        )
    object.__setattr__(pattern, "detection", (reflectance, reach))


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InvalidArgument(f"{name}={value!r} must be a positive int")
    return value


@dataclass(frozen=True)
class BeamLayout(ScanPattern):
    """A spinning multi-beam LiDAR: per-laser elevations and azimuth offsets, firing and
    packet layout, range.

    Parameters
    ----------
    name : str
    elevations : (L,) float64
      Radians, positive up, by laser id.
    azimuth_offsets : (L,) float64
      Radians added to the firing azimuth of each laser (for the HDL-64E, the
      calibration's ``rot_correction``; its sign convention does not matter for a
      synthetic sweep, which covers all azimuths).
    firings_per_revolution : int
      Azimuth steps per sweep.
    max_range, min_range : float
      Returns outside ``[min_range, max_range]`` metres are dropped (HDL-64E: 120 m; the
      0.9 m minimum is our assumption for returns blocked by the housing and vehicle).
    range_noise : float
      Standard deviation of the Gaussian range error in metres.
    packet_firings : int
      Firings (azimuth steps) one data packet holds: a lost packet is that many steps of
      every laser.
    range_resolution : float
      The range step the sensor reports, in metres.
    detection : (float, float)
      ``(reflectance, range m)`` of the datasheet's detection limit.
    """

    name: str
    elevations: NDArray[np.float64] = field(repr=False)
    azimuth_offsets: NDArray[np.float64] = field(repr=False)
    firings_per_revolution: int = 2083
    max_range: float = 120.0
    min_range: float = 0.9
    range_noise: float = 0.02
    packet_firings: int = 6
    range_resolution: float = 0.002
    detection: tuple[float, float] = (0.10, 50.0)

    def __post_init__(self) -> None:
        elevations = np.array(self.elevations, dtype=np.float64)
        offsets = np.array(self.azimuth_offsets, dtype=np.float64)
        if elevations.ndim != 1 or len(elevations) == 0:
            raise InvalidArgument(
                f"elevations must be a non-empty 1-D array, got {elevations.shape}"
            )
        if len(elevations) > 256:
            raise InvalidArgument(f"{len(elevations)} lasers: at most 256 are supported")
        if offsets.shape != elevations.shape:
            raise InvalidArgument(
                f"azimuth_offsets has shape {offsets.shape}, elevations {elevations.shape}"
            )
        if not (np.isfinite(elevations).all() and (np.abs(elevations) < math.pi / 2).all()):
            raise InvalidArgument("elevations must be finite and within ±90 degrees (radians)")
        if not np.isfinite(offsets).all():
            raise InvalidArgument("azimuth_offsets must be finite")
        _positive_int(self.firings_per_revolution, "firings_per_revolution")
        _positive_int(self.packet_firings, "packet_firings")
        _check_ranges(self)
        elevations.setflags(write=False)
        offsets.setflags(write=False)
        object.__setattr__(self, "elevations", elevations)
        object.__setattr__(self, "azimuth_offsets", offsets)

    @property
    def has_rings(self) -> bool:
        return True

    @property
    def lasers(self) -> int:
        return len(self.elevations)

    @property
    def azimuth_step(self) -> float:
        """Radians between consecutive firings of one laser."""
        return 2.0 * math.pi / self.firings_per_revolution

    @property
    def packet_degrees(self) -> float:
        """Degrees of azimuth one data packet covers."""
        return math.degrees(self.azimuth_step * self.packet_firings)

    def rays(self, *, azimuth_range: tuple[float, float] | None = None) -> Rays:
        """All rays of one sweep, or of the firings whose azimuth lies in a range.

        Parameters
        ----------
        azimuth_range : (float, float), optional
          ``(start, stop)`` radians; only firing azimuths ``start <= a < stop`` are kept
          (before per-laser offsets). Use it for partial sweeps in fast tests.
        """
        if azimuth_range is None:
            return self._full_sweep
        return self._sweep(azimuth_range)

    @functools.cached_property
    def _full_sweep(self) -> Rays:
        # Every render of a whole sweep casts the same rays: build them once per layout
        # (read-only, since every render shares them).
        return _frozen(self._sweep(None))

    def __getstate__(self) -> dict[str, Any]:
        # The cached sweep is rebuilt where it is needed, not shipped to workers.
        state = dict(self.__dict__)
        state.pop("_full_sweep", None)
        return state

    def _sweep(self, azimuth_range: tuple[float, float] | None) -> Rays:
        firing = _firings(self.firings_per_revolution, azimuth_range)
        # Rings number lasers from the lowest beam up, as drivers publish them.
        ring_of_laser = np.empty(self.lasers, dtype=np.uint8)
        ring_of_laser[np.argsort(self.elevations, kind="stable")] = np.arange(self.lasers)
        azimuth = (firing[:, None] + self.azimuth_offsets[None, :]).ravel()
        elevation = np.broadcast_to(self.elevations, (len(firing), self.lasers)).ravel()
        ring = np.broadcast_to(ring_of_laser, (len(firing), self.lasers)).ravel()
        return Rays(_directions(azimuth, elevation), np.ascontiguousarray(ring), azimuth)


def _firings(steps: int, azimuth_range: tuple[float, float] | None) -> NDArray[np.float64]:
    firing = np.arange(steps, dtype=np.float64) * (2.0 * math.pi / steps)
    if azimuth_range is not None:
        firing = firing[_within(firing, azimuth_range)]
    return firing


def _within(azimuth: NDArray[np.float64], azimuth_range: tuple[float, float]) -> NDArray[np.bool_]:
    """Which azimuths lie in ``[start, stop)`` (radians, wrapping at 2π)."""
    start, stop = (float(v) for v in azimuth_range)
    if not (math.isfinite(start) and math.isfinite(stop) and start < stop):
        raise InvalidArgument(f"azimuth_range={azimuth_range!r} needs start < stop")
    return np.asarray(np.mod(azimuth - start, 2 * math.pi) < stop - start)


def _directions(
    azimuth: NDArray[np.float64], elevation: NDArray[np.float64]
) -> NDArray[np.float64]:
    cos_e = np.cos(elevation)
    return np.stack([cos_e * np.cos(azimuth), cos_e * np.sin(azimuth), np.sin(elevation)], axis=1)


def _frozen(rays: Rays) -> Rays:
    for array in (rays.directions, rays.ring, rays.azimuth):
        array.setflags(write=False)
    return rays


@dataclass(frozen=True)
class RosetteScanner(ScanPattern):
    """A non-repetitive scanner (Livox's Risley prisms): one laser head steered along a
    rosette that covers a circular field of view more densely the longer it integrates.
    No rings, no azimuth packets: a dead-laser fault does not apply to it.

    The direction at time ``t`` is the sum of two counter-rotating circles of radius
    ``fov / 4`` (the two prisms) at ``prism_rates`` turns per second, about the forward
    axis ``pointing`` (azimuth, elevation in radians); ``points`` samples per sweep of
    ``sweep_seconds``.

    Parameters
    ----------
    name : str
    fov : float
        Full cone angle of the field of view, radians.
    points : int
        Returns per sweep (point rate x integration time).
    prism_rates : (float, float)
        Turns per second of the two prisms (opposite signs for a rosette).
    sweep_seconds : float
    pointing : (float, float)
        Azimuth and elevation of the cone's axis, radians.
    """

    name: str
    fov: float
    points: int
    prism_rates: tuple[float, float] = (120.0, -77.0)
    sweep_seconds: float = 0.1
    pointing: tuple[float, float] = (0.0, 0.0)
    max_range: float = 260.0
    min_range: float = 1.0
    range_noise: float = 0.02
    range_resolution: float = 0.002
    detection: tuple[float, float] = (0.10, 90.0)

    def __post_init__(self) -> None:
        if not (isinstance(self.fov, (int, float)) and 0 < self.fov < math.pi):
            raise InvalidArgument(f"fov={self.fov!r} must be in (0, π) radians")
        _positive_int(self.points, "points")
        if not (math.isfinite(self.sweep_seconds) and self.sweep_seconds > 0):
            raise InvalidArgument(f"sweep_seconds={self.sweep_seconds!r} must be > 0")
        _check_ranges(self)

    @property
    def has_rings(self) -> bool:
        return False

    @property
    def lasers(self) -> int:
        return 0

    @property
    def elevations(self) -> NDArray[np.float64]:  # type: ignore[override]  # no rings
        return np.zeros(0)

    @property
    def packet_degrees(self) -> None:
        return None

    def rays(self, *, azimuth_range: tuple[float, float] | None = None) -> Rays:
        t = np.linspace(0.0, self.sweep_seconds, self.points, endpoint=False)
        radius = self.fov / 4.0
        first, second = (2 * math.pi * rate * t for rate in self.prism_rates)
        # Offsets from the axis, as small angles (horizontal, vertical).
        horizontal = radius * (np.cos(first) + np.cos(second))
        vertical = radius * (np.sin(first) + np.sin(second))
        azimuth = self.pointing[0] + horizontal
        elevation = self.pointing[1] + vertical
        if azimuth_range is not None:
            keep = _within(azimuth, azimuth_range)
            azimuth, elevation = azimuth[keep], elevation[keep]
        ring = np.zeros(len(azimuth), dtype=np.uint8)
        return Rays(_directions(azimuth, elevation), ring, azimuth)
