"""Which sensor recorded a cloud, and which laser fired each return.

A relation that drops lasers, packets or re-casts objects needs the sensor. A frame knows
it from, in this order:

1. the user (``Frame(..., sensor=VLP16)``, ``FrameCatalog(..., sensor="vlp16")``);
2. a per-point laser field under one of the names real drivers use
   (:data:`RING_FIELDS`: ``ring`` for velodyne_pointcloud and Ouster, ``channel`` for
   Autoware's nebula, ``laser_id``, ``laser_number``, ...): the lasers are then known
   exactly, and the model is the catalogue's sensor whose beams fit the returns' elevations;
3. the storage order of a sweep written laser by laser (KITTI's ``.bin``): exact;
4. the elevations of the returns alone: each catalogue sensor is scored by the share of
   returns (beyond 3 m, where the lasers' few centimetres of offset no longer matter)
   that lie within 0.12 degrees of one of its beams, corrected for the share that would
   by chance; the best fit with a confidence of at least :data:`MIN_CONFIDENCE` is taken.

Otherwise the sensor is unknown, and a relation that needs it says so instead of
guessing (see :class:`SensorEstimate`).
"""

from __future__ import annotations

import itertools
import math
import weakref
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.sensors.catalog import SENSORS, sensor_named
from pytest_metamorphic.lidar.model.sensors.layout import ScanPattern

__all__ = [
    "MIN_CONFIDENCE",
    "RING_FIELDS",
    "SensorEstimate",
    "SensorLike",
    "as_sensor",
    "estimate_sensor",
    "frame_sensor",
    "ring_field",
]

RING_FIELDS = ("ring", "channel", "laser_id", "laser_number", "laser", "ring_id", "line", "beam")
"""Names of the per-point laser field, as drivers publish it (first match wins)."""
MIN_CONFIDENCE = 0.5
"""The least elevation-fit confidence at which a sensor is taken as identified."""
_TOLERANCE_DEG = 0.12
_NEAREST_M = 3.0

How = Literal["given", "ring field", "scan order", "elevations", "unknown"]
SensorLike = ScanPattern | str | None


def as_sensor(sensor: SensorLike, name: str = "sensor") -> ScanPattern | None:
    """A :class:`ScanPattern`, a catalogue key (``"vlp16"``) or None, as a ScanPattern or None."""
    if sensor is None or isinstance(sensor, ScanPattern):
        return sensor
    if isinstance(sensor, str):
        return sensor_named(sensor)
    raise InvalidArgument(
        f"{name}={sensor!r} must be a sensor model (lidar.model.sensors) or one of {list(SENSORS)}"
    )


@dataclass(frozen=True, eq=False)
class SensorEstimate:
    """What is known of the sensor that recorded a cloud.

    Attributes
    ----------
    sensor : ScanPattern or None
        The model, or None when it could not be identified.
    how : {"given", "ring field", "scan order", "elevations", "unknown"}
    confidence : float
        1 for a given sensor or a scan order; the elevation fit (0-1) otherwise.
    rings : (n,) int64 or None
        The laser of every point (the field's own numbering when read from a field), or
        None when the lasers are not known.
    ring_field : str or None
        The field the rings were read from.
    """

    sensor: ScanPattern | None
    how: How
    confidence: float
    rings: NDArray[np.int64] | None
    ring_field: str | None = None

    @property
    def lasers(self) -> list[int]:
        """The lasers that have returns in this cloud, ascending."""
        if self.rings is None:
            return []
        return [int(r) for r in np.unique(self.rings)]

    def describe(self) -> str:
        model = self.sensor.short_name if self.sensor is not None else "unknown sensor"
        if self.how == "given":
            return f"{model} (given)"
        if self.how == "ring field":
            found = f"{len(self.lasers)} lasers from the {self.ring_field!r} field"
            if self.sensor is None:
                return f"{found}; model not identified"
            return f"{found}; {model} by elevation fit {self.confidence:.2f}"
        if self.how == "scan order":
            return f"{model} (lasers from the storage order)"
        if self.how == "elevations":
            return f"{model} (elevation fit {self.confidence:.2f})"
        return "unknown sensor (no laser field, no catalogue sensor fits the elevations)"


def ring_field(cloud: PointCloud) -> str | None:
    """The name of ``cloud``'s per-point laser field, or None."""
    for name in RING_FIELDS:
        values = cloud.fields.get(name)
        if values is not None and np.asarray(values).ndim == 1:
            return name
    return None


def _elevations_deg(xyz: NDArray[np.float32]) -> NDArray[np.float64]:
    planar = np.hypot(xyz[:, 0].astype(np.float64), xyz[:, 1])
    keep = np.hypot(planar, xyz[:, 2]) >= _NEAREST_M
    return np.degrees(np.arctan2(xyz[keep, 2].astype(np.float64), planar[keep]))


def elevation_fit(elevations_deg: NDArray[np.float64], sensor: ScanPattern) -> float:
    """How well returns at ``elevations_deg`` fit ``sensor``'s beams: 0 (no better than
    chance) to 1 (every return on a beam); 0 for a sensor without rings."""
    if not sensor.has_rings or len(elevations_deg) == 0:
        return 0.0
    beams = np.sort(np.degrees(sensor.elevations))
    index = np.clip(np.searchsorted(beams, elevations_deg), 1, len(beams) - 1)
    nearest = np.minimum(
        np.abs(elevations_deg - beams[index - 1]), np.abs(elevations_deg - beams[index])
    )
    hit = float(np.mean(nearest <= _TOLERANCE_DEG))
    outside = float(np.mean((elevations_deg < beams[0] - 0.5) | (elevations_deg > beams[-1] + 0.5)))
    gaps = np.diff(beams)
    chance = float(np.minimum(gaps, 2 * _TOLERANCE_DEG).sum() / max(gaps.sum(), 1e-9))
    if chance >= 1.0:
        return 0.0
    fit = (hit - chance) / (1.0 - chance)
    return max(0.0, fit * max(0.0, 1.0 - 5.0 * outside))


def ring_fit(medians_deg: NDArray[np.float64], sensor: ScanPattern) -> float:
    """How well the median elevations of the lasers of a ring field fit ``sensor``'s
    beams: the share of lasers within 0.25 degrees of a beam, corrected for chance, times
    the share of the sensor's beams the field has (a 40-beam model for 15 lasers fits
    less well than a 16-beam one)."""
    if not sensor.has_rings or len(medians_deg) == 0 or len(medians_deg) > sensor.lasers:
        return 0.0
    beams = np.sort(np.degrees(sensor.elevations))
    index = np.clip(np.searchsorted(beams, medians_deg), 1, len(beams) - 1)
    nearest = np.minimum(np.abs(medians_deg - beams[index - 1]), np.abs(medians_deg - beams[index]))
    tolerance = 2 * _TOLERANCE_DEG
    hit = float(np.mean(nearest <= tolerance))
    gaps = np.diff(beams)
    chance = float(np.minimum(gaps, 2 * tolerance).sum() / max(gaps.sum(), 1e-9))
    if chance >= 1.0:
        return 0.0
    fit = max(0.0, (hit - chance) / (1.0 - chance))
    return fit * len(medians_deg) / sensor.lasers


def _ring_medians(xyz: NDArray[np.float32], rings: NDArray[np.int64]) -> NDArray[np.float64]:
    planar = np.hypot(xyz[:, 0].astype(np.float64), xyz[:, 1])
    far = np.hypot(planar, xyz[:, 2]) >= _NEAREST_M
    elevation = np.degrees(np.arctan2(xyz[:, 2].astype(np.float64), planar))
    medians = [np.median(elevation[far & (rings == r)]) for r in np.unique(rings[far])]
    return np.array(medians, dtype=np.float64)


def _best_fit(
    xyz: NDArray[np.float32], rings: NDArray[np.int64] | None = None
) -> tuple[ScanPattern | None, float]:
    """The catalogue sensor the elevations (or, with ``rings``, each laser's) fit best."""
    if rings is not None:
        medians = _ring_medians(xyz, rings)
        scored = [(ring_fit(medians, sensor), sensor) for sensor in SENSORS.values()]
    else:
        elevations = _elevations_deg(xyz)
        scored = [(elevation_fit(elevations, sensor), sensor) for sensor in SENSORS.values()]
    if not scored:
        return None, 0.0
    fit, sensor = max(scored, key=lambda pair: pair[0])
    return (sensor if fit >= MIN_CONFIDENCE else None), fit


def _azimuth(xyz: NDArray[np.float32]) -> NDArray[np.float64]:
    return np.mod(np.arctan2(xyz[:, 1].astype(np.float64), xyz[:, 0]), 2 * math.pi)


def _run_starts(xyz: NDArray[np.float32]) -> NDArray[np.intp]:
    """Where the azimuth drops by more than π: the starts of a laser's revolution."""
    return np.flatnonzero(np.diff(_azimuth(xyz)) < -math.pi) + 1


def rings_from_scan_order(xyz: NDArray[np.float32], lasers: int) -> NDArray[np.int64] | None:
    """Rings of a sweep stored laser by laser, or None when it is not stored that way.

    Within one laser's revolution the azimuth in [0, 2π) grows; the next laser starts
    over, so the azimuth drops by more than π. Exactly ``lasers`` runs whose median
    elevations are ordered mean the layout is recognised; rings are numbered from the
    lowest beam (0) up, as ROS drivers publish them, whichever end the file starts at.
    """
    if len(xyz) < 2 * lasers:
        return None
    starts = _run_starts(xyz)
    if len(starts) != lasers - 1:
        return None
    bounds = np.concatenate([[0], starts, [len(xyz)]])
    planar = np.hypot(xyz[:, 0].astype(np.float64), xyz[:, 1])
    elevation = np.arctan2(xyz[:, 2].astype(np.float64), planar)
    medians = np.array([np.median(elevation[a:b]) for a, b in itertools.pairwise(bounds)])
    steps = np.diff(medians)
    if (steps < 0).all():
        rank = np.arange(lasers)[::-1]  # stored top beam first (KITTI)
    elif (steps > 0).all():
        rank = np.arange(lasers)
    else:
        return None
    return np.repeat(rank, np.diff(bounds)).astype(np.int64)


def rings_from_elevation(xyz: NDArray[np.float32], sensor: ScanPattern) -> NDArray[np.int64]:
    """The nearest beam of ``sensor`` by elevation, numbered from the lowest (0) up
    (exact for scans rendered with it; a real unit's own calibration differs)."""
    beams = np.sort(sensor.elevations)
    planar = np.hypot(xyz[:, 0].astype(np.float64), xyz[:, 1])
    elevation = np.arctan2(xyz[:, 2].astype(np.float64), planar)
    right = np.clip(np.searchsorted(beams, elevation), 1, len(beams) - 1)
    left = right - 1
    nearer_left = (elevation - beams[left]) < (beams[right] - elevation)
    return np.where(nearer_left, left, right).astype(np.int64)


def estimate_sensor(cloud: PointCloud, *, sensor: SensorLike = None) -> SensorEstimate:
    """What is known of the sensor that recorded ``cloud`` (see the module docstring).

    Parameters
    ----------
    cloud : PointCloud
    sensor : ScanPattern or str, optional
        The sensor, when the user knows it: its lasers are then read from a ring field,
        the storage order or the elevations, in that order.
    """
    if not isinstance(cloud, PointCloud):
        raise InvalidArgument(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    given = as_sensor(sensor)
    field = ring_field(cloud)
    if given is not None:
        return _given(cloud, given, field)
    if field is not None:
        rings = np.asarray(cloud.fields[field]).astype(np.int64)
        model, fit = _best_fit(cloud.xyz, rings)
        return SensorEstimate(model, "ring field", fit, rings, field)
    # The number of revolutions in storage order picks the candidates: counted once.
    runs = len(_run_starts(cloud.xyz)) + 1 if len(cloud) > 1 else 0
    for model in SENSORS.values():
        if model.has_rings and model.lasers == runs:
            ordered = rings_from_scan_order(cloud.xyz, model.lasers)
            if ordered is not None:
                return SensorEstimate(model, "scan order", 1.0, ordered)
    model, fit = _best_fit(cloud.xyz)
    if model is None:
        return SensorEstimate(None, "unknown", fit, None)
    return SensorEstimate(model, "elevations", fit, rings_from_elevation(cloud.xyz, model))


def _given(cloud: PointCloud, sensor: ScanPattern, field: str | None) -> SensorEstimate:
    if not sensor.has_rings:
        return SensorEstimate(sensor, "given", 1.0, None)
    if field is not None:
        rings = np.asarray(cloud.fields[field]).astype(np.int64)
        return SensorEstimate(sensor, "given", 1.0, rings, field)
    rings_or_none = rings_from_scan_order(cloud.xyz, sensor.lasers)
    if rings_or_none is None:
        rings_or_none = rings_from_elevation(cloud.xyz, sensor)
    return SensorEstimate(sensor, "given", 1.0, rings_or_none)


_ESTIMATES: weakref.WeakKeyDictionary[Any, SensorEstimate] = weakref.WeakKeyDictionary()


def frame_sensor(frame: Any) -> SensorEstimate:
    """The sensor of a :class:`~pytest_metamorphic.lidar.model.frame.Frame`: its
    ``sensor`` when set, else estimated from its cloud (once per frame)."""
    cloud = getattr(frame, "cloud", None)
    if not isinstance(cloud, PointCloud):
        raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
    known = _ESTIMATES.get(frame)
    if known is None:
        known = estimate_sensor(cloud, sensor=getattr(frame, "sensor", None))
        _ESTIMATES[frame] = known
    return known
