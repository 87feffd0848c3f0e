"""Strategies for sensor faults and weather: dead beams, lost packets, fog and rain.

Each takes the source frame and returns a strategy of
:class:`~pytest_metamorphic.core.engine.Followup` (the faulty frame and its parameters),
for ``@metamorphic(..., followup=...)`` or a relation of one's own.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.faults import (
    PACKET_DEGREES,
    QUANTIZATION_RANGE,
    DropAzimuthBlock,
    DropRings,
    QuantizeRange,
    derive_rings,
)
from pytest_metamorphic.lidar.followups.perturb import SEED_BITS
from pytest_metamorphic.lidar.followups.weather import WEATHER_KINDS, Weather, WeatherKind
from pytest_metamorphic.lidar.model.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.strategies._noise import _check_frame

__all__ = ["dead_beams", "lost_packets", "quantized_ranges", "weathered_frames"]


def _positive(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InvalidArgument(f"{name}={value!r} must be a positive int")
    return value


def dead_beams(
    frame: Any, *, max_rings: int = 4, layout: BeamLayout = HDL64E
) -> st.SearchStrategy[Followup]:
    """The frame without every return of 1 to ``max_rings`` lasers
    (:class:`~pytest_metamorphic.lidar.followups.faults.DropRings`), shrinking toward fewer and
    lower
    rings. Raises at once when the frame's rings cannot be found."""
    frame = _check_frame(frame)
    if not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout")
    limit = min(_positive(max_rings, "max_rings"), layout.lasers)
    derive_rings(frame.cloud, layout=layout)
    rings = st.lists(st.integers(0, layout.lasers - 1), min_size=1, max_size=limit, unique=True)

    def drop(chosen: list[int]) -> Followup:
        fault = DropRings(tuple(chosen), layout)
        return Followup(fault.apply(frame), params=fault.params())

    return rings.map(drop)


def _roi_bearings(frame: Any) -> list[int]:
    """Bearings (tenths of a degree, 0-3599) at which the frame's ROI holds returns, the
    one straight ahead first and then outwards, both ways: where a lost packet can cut a
    judged obstacle, in the order a search should shrink toward. Every bearing when the
    frame has no ROI or its ROI holds no return."""
    everything = sorted(range(3600), key=lambda b: (min(b, 3600 - b), b))
    roi = getattr(frame, "roi", None)
    if roi is None or len(frame.cloud) == 0:
        return everything
    xyz = frame.cloud.xyz
    inside = np.asarray(roi.contains(xyz[:, :2]), dtype=bool)
    if not inside.any():
        return everything
    bearings = np.degrees(np.arctan2(xyz[inside, 1], xyz[inside, 0]))
    tenths = np.unique(np.floor(np.mod(bearings, 360.0) * 10).astype(np.int64) % 3600)
    return sorted((int(b) for b in tenths), key=lambda b: (min(b, 3600 - b), b))


def lost_packets(
    frame: Any, *, max_packets: int = 10, within_roi: bool = True
) -> st.SearchStrategy[Followup]:
    """The frame without 1 to ``max_packets`` consecutive packets (an azimuth block of
    :data:`~pytest_metamorphic.lidar.followups.faults.PACKET_DEGREES` each), shrinking
    toward one packet straight ahead.

    With ``within_roi`` (default) the block is centred on a bearing at which the frame's
    ROI holds returns (tenths of a degree): a packet lost where nothing is judged cannot
    fail the relation, and KITTI's camera-wedge ROI covers 80 of 360 degrees. Without
    it, or without an ROI, the centre is any bearing.
    """
    frame = _check_frame(frame)
    if not isinstance(within_roi, bool):
        raise InvalidArgument(f"within_roi={within_roi!r} must be True or False")
    centres = _roi_bearings(frame) if within_roi else _roi_bearings(None)
    blocks = st.tuples(
        st.sampled_from(centres), st.integers(1, _positive(max_packets, "max_packets"))
    )

    def lose(block: tuple[int, int]) -> Followup:
        centre, packets = block
        width = PACKET_DEGREES * packets
        fault = DropAzimuthBlock(math.radians(centre / 10 - width / 2), math.radians(width))
        return Followup(fault.apply(frame), params={**fault.params(), "packets": packets})

    return blocks.map(lose)


def _step(value: Any, name: str) -> float:
    try:
        return QuantizeRange(value).step
    except InvalidArgument:
        raise InvalidArgument(f"{name}={value!r} must be a number of metres in (0, 1]") from None


def quantized_ranges(
    frame: Any,
    *,
    steps: Sequence[float] | None = None,
    min_step: float = QUANTIZATION_RANGE[0],
    max_step: float = QUANTIZATION_RANGE[1],
) -> st.SearchStrategy[Followup]:
    """The frame with every range rounded to a step of metres
    (:class:`~pytest_metamorphic.lidar.followups.faults.QuantizeRange`): drawn in whole
    millimetres from ``min_step`` to ``max_step``, shrinking toward the finest, or, with
    ``steps``, one of those levels (shrinking toward the first)."""
    frame = _check_frame(frame)
    if steps is not None:
        levels = tuple(steps)
        if not levels:
            raise InvalidArgument("steps is empty")
        faults = [QuantizeRange(step) for step in levels]  # validates each step
        drawn: st.SearchStrategy[QuantizeRange] = st.sampled_from(faults)
    else:
        low, high = _step(min_step, "min_step"), _step(max_step, "max_step")
        if not low <= high:
            raise InvalidArgument(f"min_step={min_step!r} must not exceed max_step={max_step!r}")
        millimetres = st.integers(max(1, math.ceil(low * 1000)), max(1, math.floor(high * 1000)))
        drawn = millimetres.map(lambda mm: QuantizeRange(mm / 1000))

    def quantize(fault: QuantizeRange) -> Followup:
        return Followup(fault.apply(frame), params=fault.params())

    return drawn.map(quantize)


def weathered_frames(
    frame: Any,
    *,
    kinds: Sequence[WeatherKind] = WEATHER_KINDS,
    visibilities: Sequence[float] = (200.0, 100.0, 50.0),
) -> st.SearchStrategy[Followup]:
    """The frame in fog or rain (:class:`~pytest_metamorphic.lidar.followups.weather.Weather`) of
    one of ``kinds`` and ``visibilities`` (metres), with a drawn seed; shrinking toward
    the first kind, the first visibility and seed 0."""
    frame = _check_frame(frame)
    chosen = tuple(kinds)
    if not chosen or any(kind not in WEATHER_KINDS for kind in chosen):
        raise InvalidArgument(f"kinds={kinds!r} must be a non-empty subset of {WEATHER_KINDS}")
    levels = tuple(visibilities)
    if not levels or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
        for v in levels
    ):
        raise InvalidArgument(f"visibilities={visibilities!r} must be metres > 0")
    draws = st.tuples(
        st.sampled_from(chosen), st.sampled_from(levels), st.integers(0, 2**SEED_BITS - 1)
    )

    def weather(draw: tuple[WeatherKind, float, int]) -> Followup:
        kind, visibility, seed = draw
        transform = Weather(visibility, kind, seed)
        return Followup(transform.apply(frame), params=transform.params())

    return draws.map(weather)
