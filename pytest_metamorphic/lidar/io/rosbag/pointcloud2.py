"""``sensor_msgs/PointCloud2`` messages to and from clouds: field layouts, 16-byte block copies."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.io._common import (
    ZerosPolicy,
    check_policies,
    cloud_from_records,
    records_from_cloud,
    wrap_errors,
)
from pytest_metamorphic.lidar.io.rosbag.typestore import POINTCLOUD2, _typestore
from pytest_metamorphic.lidar.model.cloud import NonFinitePolicy, PointCloud

__all__ = ["cloud_to_pointcloud2", "pointcloud2_to_cloud"]

# sensor_msgs/PointField datatype codes.
_DATATYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_CODES = {code: datatype for datatype, code in _DATATYPES.items()}


def pointcloud2_to_cloud(
    message: Any,
    *,
    name: str = "PointCloud2",
    nonfinite: NonFinitePolicy = "reject",
    zeros: ZerosPolicy = "auto",
) -> PointCloud:
    """Decode a ``sensor_msgs/PointCloud2`` (a rosbags message object or look-alike).

    Parameters
    ----------
    message
      Has ``header`` (``stamp.sec``, ``stamp.nanosec``, ``frame_id``), ``height``,
      ``width``, ``fields`` (``name``, ``offset``, ``datatype``, ``count``),
      ``is_bigendian``, ``point_step``, ``row_step`` and ``data`` (uint8 buffer).
    name : str
      Named in errors (the bag, topic and message number).
    nonfinite, zeros
      As for :func:`~pytest_metamorphic.lidar.io.pcd.read_pcd`; ``zeros="auto"`` drops
      the x = y = z = 0 padding of organised clouds (height > 1).

    Returns
    -------
    PointCloud
      x, y, z, intensity (0 when there is no intensity field) and every other field with
      its own dtype in native byte order; frame id; timestamp in seconds (None for 0).
    """
    check_policies(nonfinite, zeros)
    with wrap_errors(name, "PointCloud2 message"):
        height, width = int(message.height), int(message.width)
        point_step, row_step = int(message.point_step), int(message.row_step)
        data = message.data
        if isinstance(data, (bytes, bytearray, memoryview)):
            data = np.frombuffer(data, np.uint8)
        data = np.asarray(data, np.uint8).reshape(-1)
        order = ">" if message.is_bigendian else "<"
        layout = [
            (str(f.name), int(f.offset), int(f.datatype), int(f.count)) for f in message.fields
        ]
        frame_id = str(message.header.frame_id)
        stamp = (int(message.header.stamp.sec), int(message.header.stamp.nanosec))
    dtype = _record_dtype(layout, order, point_step, name)
    count = height * width
    if count and (row_step < width * point_step):
        raise DataError(
            f"row_step {row_step} is less than width {width} x point_step {point_step}", path=name
        )
    needed = (height - 1) * row_step + width * point_step if count else 0
    if len(data) < needed:
        raise DataError(
            f"data holds {len(data)} bytes; {height} rows of {width} points "
            f"(row_step {row_step}, point_step {point_step}) need {needed}",
            path=name,
        )
    owned = True  # the records below are a fresh array, not a view of the message
    if not count:
        records = np.empty(0, dtype)
    elif height == 1 or row_step == width * point_step:
        records, owned = np.frombuffer(data, dtype, count), False
    else:  # rows padded beyond width * point_step: gather the rows, then view them
        rows = np.lib.stride_tricks.as_strided(
            data, (height, width * point_step), (row_step, 1), writeable=False
        )
        records = np.ascontiguousarray(rows).view(dtype).reshape(-1)
    seconds = stamp[0] + stamp[1] / 1e9 if stamp != (0, 0) else None
    return cloud_from_records(
        records,
        name=name,
        organised=height > 1,
        nonfinite=nonfinite,
        zeros=zeros,
        frame_id=frame_id,
        timestamp=seconds,
        owned=owned,
    )


def _record_dtype(
    layout: list[tuple[str, int, int, int]], order: str, point_step: int, name: str
) -> np.dtype:
    names, formats, offsets = [], [], []
    for field, offset, datatype, count in layout:
        if datatype not in _DATATYPES:
            raise DataError(
                f"field {field!r} has unknown PointField datatype {datatype}", path=name
            )
        if count < 1:
            raise DataError(f"field {field!r} has count {count}", path=name)
        code = order + _DATATYPES[datatype]
        size = np.dtype(code).itemsize * count
        if offset < 0 or offset + size > point_step:
            raise DataError(
                f"field {field!r} (offset {offset}, {size} bytes) does not fit in "
                f"point_step {point_step}",
                path=name,
            )
        if field in names:
            raise DataError(f"field {field!r} appears twice", path=name)
        names.append(field)
        formats.append(code if count == 1 else (code, (count,)))
        offsets.append(offset)
    with wrap_errors(name, "PointCloud2 field layout"):
        return np.dtype(
            {"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step}
        )


def cloud_to_pointcloud2(cloud: PointCloud, *, ros1: bool = False) -> Any:
    """A rosbags ``sensor_msgs/msg/PointCloud2`` (ROS 1 Noetic or ROS 2 Humble types).

    Unorganised (height 1), little-endian, dense; fields x, y, z, intensity (FLOAT32)
    then the cloud's extra fields (int8..uint32, float32, float64; a 2-D field becomes
    one PointField with ``count`` k).
    """
    records = records_from_cloud(cloud, allowed="i1 u1 i2 u2 i4 u4 f4 f8", fmt="PointCloud2")
    store = _typestore(ros1)
    types = store.types
    fields = []
    layout: Mapping[str, tuple[Any, ...]] = records.dtype.fields or {}
    for key in records.dtype.names or ():
        base, offset = layout[key][0], layout[key][1]
        shape = base.shape
        fields.append(
            types["sensor_msgs/msg/PointField"](
                name=key,
                offset=offset,
                datatype=_CODES[base.base.str[1:]],
                count=shape[0] if shape else 1,
            )
        )
    sec, nanosec = _split_stamp(cloud.timestamp)
    header_args: dict[str, Any] = {
        "stamp": types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
        "frame_id": cloud.frame_id,
    }
    if ros1:
        header_args["seq"] = 0
    step = records.dtype.itemsize
    return types[POINTCLOUD2](
        header=types["std_msgs/msg/Header"](**header_args),
        height=1,
        width=len(records),
        fields=fields,
        is_bigendian=False,
        point_step=step,
        row_step=step * len(records),
        data=records.view(np.uint8).reshape(-1) if len(records) else np.empty(0, np.uint8),
        is_dense=True,
    )


def _split_stamp(timestamp: float | None) -> tuple[int, int]:
    if timestamp is None:
        return 0, 0
    # ROS 2 stores seconds as int32 (ROS 1 as uint32): the common range.
    if not (0 <= timestamp < 2**31):
        raise InvalidArgument(f"timestamp {timestamp} cannot be a ROS time (0 .. 2**31 s)")
    sec = math.floor(timestamp)
    nanosec = round((timestamp - sec) * 1e9)
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return sec, nanosec
