"""The Velodyne HDL-64E's beam layout (kept at this path; the sensor models live in
:mod:`pytest_metamorphic.lidar.model.sensors`, this one in its ``hdl64e`` module)."""

from pytest_metamorphic.lidar.model.sensors.hdl64e import (
    HDL64E,
    HDL64E_AZIMUTH_OFFSETS,
    HDL64E_ELEVATIONS,
    BeamLayout,
    Rays,
)

__all__ = ["HDL64E", "HDL64E_AZIMUTH_OFFSETS", "HDL64E_ELEVATIONS", "BeamLayout", "Rays"]
