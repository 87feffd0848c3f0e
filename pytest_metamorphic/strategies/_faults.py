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
    QUANTIZATION_RANGE,
    DropAzimuthBlock,
    DropRings,
    QuantizeRange,
)
from pytest_metamorphic.lidar.followups.perturb import SEED_BITS
from pytest_metamorphic.lidar.followups.weather import WEATHER_KINDS, Weather, WeatherKind
from pytest_metamorphic.lidar.model.hdl64 import BeamLayout
from pytest_metamorphic.lidar.model.sensors import SensorEstimate, estimate_sensor, frame_sensor
from pytest_metamorphic.strategies._noise import _check_frame

__all__ = ["dead_beams", "lost_packets", "quantized_ranges", "weathered_frames"]


def _positive(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InvalidArgument(f"{name}={value!r} must be a positive int")
    return value


def dead_beams(
    frame: Any, *, max_rings: int = 4, layout: BeamLayout | None = None
) -> st.SearchStrategy[Followup]:
    """The frame without every return of 1 to ``max_rings`` of its lasers
    (:class:`~pytest_metamorphic.lidar.followups.faults.DropRings`), shrinking toward fewer
    and lower rings.

    The lasers are the frame's sensor's (``layout``, else
    :func:`~pytest_metamorphic.lidar.model.sensors.frame_sensor`: a laser field, the
    storage order, or a catalogue sensor fitted to the elevations), and only lasers that
    have returns are drawn, never all of them. When they cannot be known (a non-repetitive
    scanner, an unidentified sensor without a laser field) the follow-up is
    :meth:`~pytest_metamorphic.core.cases.Followup.not_applicable`, with the reason.
    """
    frame = _check_frame(frame)
    if layout is not None and not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout or None (the frame's)")
    limit = _positive(max_rings, "max_rings")

    def beams() -> st.SearchStrategy[Followup]:
        estimate = (
            frame_sensor(frame) if layout is None else estimate_sensor(frame.cloud, sensor=layout)
        )
        lasers = estimate.lasers
        if estimate.rings is None or len(lasers) < 2:
            return st.just(Followup.not_applicable(frame, f"beam loss: {_no_lasers(estimate)}"))
        rings = st.lists(
            st.sampled_from(lasers), min_size=1, max_size=min(limit, len(lasers) - 1), unique=True
        )

        def drop(chosen: list[int]) -> Followup:
            fault = DropRings(tuple(chosen), layout)
            return Followup(fault.apply(frame), {**fault.params(), "sensor": estimate.describe()})

        return rings.map(drop)

    # The sensor is identified when the first example is drawn, not when the strategy is made.
    return st.deferred(beams)


def _no_lasers(estimate: SensorEstimate) -> str:
    """Why beam loss cannot act on a frame (for the report)."""
    if estimate.sensor is not None and not estimate.sensor.has_rings:
        return f"{estimate.sensor.short_name} has no lasers to lose"
    if estimate.rings is None:
        return (
            f"the lasers cannot be known: {estimate.describe()}; pass sensor= to the Frame "
            "or FrameCatalog"
        )
    return "the frame has returns of fewer than 2 lasers"


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
    frame: Any,
    *,
    max_packets: int = 10,
    within_roi: bool = True,
    packet_degrees: float | None = None,
) -> st.SearchStrategy[Followup]:
    """The frame without 1 to ``max_packets`` consecutive packets (an azimuth block of
    ``packet_degrees`` each; default the frame's sensor's,
    ``BeamLayout.packet_degrees`` of :mod:`pytest_metamorphic.lidar.model.sensors`: 1.04 for
    the HDL-64E, 4.8 for a VLP-16), shrinking toward one packet straight ahead.

    With ``within_roi`` (default) the block is centred on a bearing at which the frame's
    ROI holds returns (tenths of a degree): a packet lost where nothing is judged cannot
    fail the relation, and KITTI's camera-wedge ROI covers 80 of 360 degrees. Without
    it, or without an ROI, the centre is any bearing. Not applicable (with the reason)
    when the sensor, and so its packets, are unknown, or its packets are not azimuth
    blocks (a non-repetitive scanner).
    """
    frame = _check_frame(frame)
    if not isinstance(within_roi, bool):
        raise InvalidArgument(f"within_roi={within_roi!r} must be True or False")
    if packet_degrees is not None and not (
        isinstance(packet_degrees, (int, float))
        and not isinstance(packet_degrees, bool)
        and 0 < packet_degrees < 36
    ):
        raise InvalidArgument(f"packet_degrees={packet_degrees!r} must be in (0, 36) degrees")
    limit = _positive(max_packets, "max_packets")

    def packets() -> st.SearchStrategy[Followup]:
        degrees = packet_degrees
        if degrees is None:
            sensor = frame_sensor(frame).sensor
            degrees = None if sensor is None else sensor.packet_degrees
            if degrees is None:
                why = (
                    f"the sensor is not known ({frame_sensor(frame).describe()}); pass "
                    "sensor= to the Frame or FrameCatalog, or packet_degrees="
                    if sensor is None
                    else f"a {sensor.short_name}'s packets are not azimuth blocks"
                )
                return st.just(Followup.not_applicable(frame, f"packet loss: {why}"))
        centres = _roi_bearings(frame) if within_roi else _roi_bearings(None)
        blocks = st.tuples(st.sampled_from(centres), st.integers(1, limit))
        width_of_one = float(degrees)

        def lose(block: tuple[int, int]) -> Followup:
            centre, count = block
            width = width_of_one * count
            fault = DropAzimuthBlock(math.radians(centre / 10 - width / 2), math.radians(width))
            return Followup(fault.apply(frame), params={**fault.params(), "packets": count})

        return blocks.map(lose)

    return st.deferred(packets)


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
