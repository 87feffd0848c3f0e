"""The sensors real fleets run, as data: beam elevations, azimuth offsets, firing and
packet layout, range.

Where each number comes from (a number not stated by a source is marked *assumed*):

* **HDL-64E S3**: :mod:`pytest_metamorphic.lidar.model.hdl64` (ros-drivers/velodyne's
  ``64e_s3-xiesc.yaml``); 12 blocks a packet, upper and lower fire together: 6 firings.
* **HDL-32E**: ros-drivers/velodyne ``32db.yaml``: 32 lasers from -30.67 to +10.67
  degrees, 1.333 apart, laser ids interleaving the lower and upper halves; a firing cycle
  of 46.08 us (2170 firings a revolution at 10 Hz), 12 firings a packet; 100 m.
  *Assumed*: the 10 % detection range (70 m).
* **VLP-16**: ros-drivers/velodyne ``VLP16db.yaml``: -15 to +15 degrees, 2 apart, ids
  alternating low and high; ``distance_resolution: 0.002``; 24 firing sequences a packet
  (12 blocks of 2), 0.2 degrees each at 10 Hz; 100 m. *Assumed*: 10 % seen to 50 m.
* **VLP-32C**: Velodyne's VLP-32C manual (laser table: elevation and azimuth offset of
  each laser id, -25 to +15 degrees, dense around the horizon; the same table as decoders
  use); ranges in 4 mm units; 12 firings a packet; 200 m. Checked on the nebula VLP-32
  recording in ``shared/data``: the 32 peaks of its elevation histogram lie within 0.05
  degrees of the table. *Assumed*: 10 % seen to 80 m.
* **Ouster OS1-64** (gen 1): 64 beams evenly from +16.611 to -16.611 degrees, azimuth
  offsets cycling 3.164, 1.055, -1.055, -3.164 degrees (the nominal
  ``beam_altitude_angles`` / ``beam_azimuth_angles``); 2048 columns a revolution at
  10 Hz, 16 columns a packet; 3 mm range steps; 40 m for 10 % targets (datasheet).
  Checked on the pointcloudset OS1-64 recording: each ring's median elevation is within
  0.15 degrees of the table (Ouster numbers rings from the *top* beam; the model numbers
  them from the bottom, as Velodyne's drivers do).
* **Ouster OS1-128** (rev 6): 128 beams evenly over 45 degrees (+22.5 to -22.5); 2048
  columns, 16 a packet. *Assumed*: no azimuth offsets (they are per unit), 10 % seen to
  45 m.
* **Hesai Pandar40P**: the default angle table of Apollo's Hesai driver
  (``pandar40p_internal.cc``: elevations +15 to -25 degrees and azimuth offsets of the 40
  lines); 0.2 degrees a firing at 10 Hz, 10 blocks a packet; 200 m; 20 % targets seen to
  200 m (datasheet).
* **Livox Mid-40**: a non-repetitive rosette over a 38.4-degree circular field of view,
  100,000 points a second (10,000 in a 0.1 s sweep), 90 m for 10 % targets, 260 m range
  (datasheet). *Assumed*: the prisms' rates (any pair of opposite rates draws a rosette).
"""

from __future__ import annotations

import math

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.sensors.hdl64e import HDL64E
from pytest_metamorphic.lidar.model.sensors.layout import BeamLayout, RosetteScanner, ScanPattern

__all__ = [
    "HDL32E",
    "HDL64E",
    "LIVOX_MID40",
    "OS1_64",
    "OS1_128",
    "PANDAR40P",
    "SENSORS",
    "VLP16",
    "VLP32C",
    "sensor_named",
]


def _degrees(values: list[float]) -> np.ndarray:
    return np.radians(np.array(values, dtype=np.float64))


# HDL-32E laser ids: even ids -30.67, -29.33, ...; odd ids -9.33, -8.00, ... (32db.yaml).
_HDL32_ELEVATIONS = [
    (-30.67 + (i // 2) * 4 / 3) if i % 2 == 0 else (-9.33 + (i // 2) * 4 / 3) for i in range(32)
]
HDL32E = BeamLayout(
    name="Velodyne HDL-32E (32db.yaml), 10 Hz",
    elevations=_degrees(_HDL32_ELEVATIONS),
    azimuth_offsets=np.zeros(32),
    firings_per_revolution=2170,
    max_range=100.0,
    packet_firings=12,
    range_resolution=0.002,
    detection=(0.10, 70.0),
)
"""The HDL-32E at 10 Hz: 32 x 2170 rays, 100 m, packets of 12 firings (1.99 degrees)."""

# VLP-16 laser ids alternate -15, +1, -13, +3, ... (VLP16db.yaml).
_VLP16_ELEVATIONS = [(-15.0 + i) if i % 2 == 0 else (i - 0.0) for i in range(16)]
VLP16 = BeamLayout(
    name="Velodyne VLP-16 (VLP16db.yaml), 10 Hz",
    elevations=_degrees(_VLP16_ELEVATIONS),
    azimuth_offsets=np.zeros(16),
    firings_per_revolution=1800,
    max_range=100.0,
    packet_firings=24,
    range_resolution=0.002,
    detection=(0.10, 50.0),
)
"""The VLP-16 at 10 Hz: 16 x 1800 rays, 100 m, packets of 24 firings (4.8 degrees)."""

# (elevation, azimuth offset) in degrees by laser id, from the VLP-32C manual's table.
_VLP32C = [
    (-25, 1.4), (-1, -4.2), (-1.667, 1.4), (-15.639, -1.4), (-11.31, 1.4), (0, -1.4),
    (-0.667, 4.2), (-8.843, -1.4), (-7.254, 1.4), (0.333, -4.2), (-0.333, 1.4),
    (-6.148, -1.4), (-5.333, 4.2), (1.333, -1.4), (0.667, 4.2), (-4, -1.4), (-4.667, 1.4),
    (1.667, -4.2), (1, 1.4), (-3.667, -4.2), (-3.333, 4.2), (3.333, -1.4), (2.333, 1.4),
    (-2.667, -1.4), (-3, 1.4), (7, -1.4), (4.667, 1.4), (-2.333, -4.2), (-2, 4.2),
    (15, -1.4), (10.333, 1.4), (-1.333, -1.4),
]  # fmt: skip
VLP32C = BeamLayout(
    name="Velodyne VLP-32C (manual's laser table), 10 Hz",
    elevations=_degrees([e for e, _ in _VLP32C]),
    azimuth_offsets=_degrees([a for _, a in _VLP32C]),
    firings_per_revolution=1800,
    max_range=200.0,
    packet_firings=12,
    range_resolution=0.004,
    detection=(0.10, 80.0),
)
"""The VLP-32C at 10 Hz: 32 x 1800 rays, 200 m, packets of 12 firings (2.4 degrees)."""

OS1_64 = BeamLayout(
    name="Ouster OS1-64 (gen 1, nominal beam angles), 10 Hz",
    elevations=np.radians(np.linspace(16.611, -16.611, 64)),
    azimuth_offsets=_degrees([3.164, 1.055, -1.055, -3.164] * 16),
    firings_per_revolution=2048,
    max_range=120.0,
    min_range=0.8,
    range_noise=0.03,
    packet_firings=16,
    range_resolution=0.003,
    detection=(0.10, 40.0),
)
"""The OS1-64 at 10 Hz (2048 columns): 120 m, packets of 16 columns (2.8 degrees)."""

OS1_128 = BeamLayout(
    name="Ouster OS1-128 (rev 6, even beams over 45 degrees), 10 Hz",
    elevations=np.radians(np.linspace(22.5, -22.5, 128)),
    azimuth_offsets=np.zeros(128),
    firings_per_revolution=2048,
    max_range=120.0,
    min_range=0.5,
    range_noise=0.03,
    packet_firings=16,
    range_resolution=0.001,
    detection=(0.10, 45.0),
)
"""The OS1-128 at 10 Hz (2048 columns): packets of 16 columns (2.8 degrees)."""

_PANDAR40P_ELEVATIONS = [
    15.0, 11.0, 8.0, 5.0, 3.0, 2.0, 1.67, 1.33, 1.0, 0.67, 0.33, 0.0, -0.33, -0.67, -1.0,
    -1.33, -1.66, -2.0, -2.33, -2.67, -3.0, -3.33, -3.67, -4.0, -4.33, -4.67, -5.0, -5.33,
    -5.67, -6.0, -7.0, -8.0, -9.0, -10.0, -11.0, -12.0, -13.0, -14.0, -19.0, -25.0,
]  # fmt: skip
_PANDAR40P_OFFSETS = [-1.042] * 6 + [3.125, -5.208, -1.042] * 8 + [-1.042] * 10
PANDAR40P = BeamLayout(
    name="Hesai Pandar40P (default angle table), 10 Hz",
    elevations=_degrees(_PANDAR40P_ELEVATIONS),
    azimuth_offsets=_degrees(_PANDAR40P_OFFSETS),
    firings_per_revolution=1800,
    max_range=200.0,
    min_range=0.5,
    packet_firings=10,
    range_resolution=0.004,
    detection=(0.20, 200.0),
)
"""The Pandar40P at 10 Hz: 40 x 1800 rays, 200 m, packets of 10 firings (2 degrees)."""

LIVOX_MID40 = RosetteScanner(
    name="Livox Mid-40 (non-repetitive rosette), 10 Hz frames",
    fov=math.radians(38.4),
    points=10_000,
    max_range=260.0,
    detection=(0.10, 90.0),
)
"""The Livox Mid-40: 10,000 points a 0.1 s frame over a 38.4-degree cone, no rings."""

SENSORS: dict[str, ScanPattern] = {
    "hdl64e": HDL64E,
    "hdl32e": HDL32E,
    "vlp16": VLP16,
    "vlp32c": VLP32C,
    "os1-64": OS1_64,
    "os1-128": OS1_128,
    "pandar40p": PANDAR40P,
    "livox-mid40": LIVOX_MID40,
}
"""Every sensor of the catalogue by its short key."""


def sensor_named(name: str) -> ScanPattern:
    """The catalogue's sensor for a key of :data:`SENSORS` (case and ``_``/``-``/space
    ignored: ``"VLP-16"``, ``"os1_64"``)."""
    if not isinstance(name, str):
        raise InvalidArgument(f"sensor={name!r} must be a sensor model or one of {list(SENSORS)}")
    key = name.lower().replace("_", "-").replace(" ", "")
    candidates = {key, key.replace("-", "")}
    for known, sensor in SENSORS.items():
        if known in candidates or known.replace("-", "") in candidates:
            return sensor
    raise InvalidArgument(f"sensor={name!r} is not one of {list(SENSORS)}")
