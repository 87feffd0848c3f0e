"""Sensor models as data: which LiDAR recorded a frame, how it samples the world.

* :mod:`.layout`: :class:`ScanPattern` and its kinds, :class:`BeamLayout` (spinning
  multi-beam sensors) and :class:`RosetteScanner` (non-repetitive scanners, no rings);
* :mod:`.catalog`: the sensors, from datasheets and drivers' calibration files
  (HDL-64E, HDL-32E, VLP-16, VLP-32C, Ouster OS1-64 and OS1-128, Hesai Pandar40P,
  Livox Mid-40) and :func:`sensor_named`;
* :mod:`.identify`: which sensor and which laser, for a cloud or frame
  (:func:`frame_sensor`, :func:`estimate_sensor`).
"""

from __future__ import annotations

from pytest_metamorphic.lidar.model.sensors.catalog import (
    HDL32E,
    HDL64E,
    LIVOX_MID40,
    OS1_64,
    OS1_128,
    PANDAR40P,
    SENSORS,
    VLP16,
    VLP32C,
    sensor_named,
)
from pytest_metamorphic.lidar.model.sensors.identify import (
    MIN_CONFIDENCE,
    RING_FIELDS,
    SensorEstimate,
    SensorLike,
    as_sensor,
    estimate_sensor,
    frame_sensor,
    ring_field,
)
from pytest_metamorphic.lidar.model.sensors.layout import (
    BeamLayout,
    Rays,
    RosetteScanner,
    ScanPattern,
)

__all__ = [
    "HDL32E",
    "HDL64E",
    "LIVOX_MID40",
    "MIN_CONFIDENCE",
    "OS1_64",
    "OS1_128",
    "PANDAR40P",
    "RING_FIELDS",
    "SENSORS",
    "VLP16",
    "VLP32C",
    "BeamLayout",
    "Rays",
    "RosetteScanner",
    "ScanPattern",
    "SensorEstimate",
    "SensorLike",
    "as_sensor",
    "estimate_sensor",
    "frame_sensor",
    "ring_field",
    "sensor_named",
]
