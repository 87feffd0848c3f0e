"""Strategies for sensor faults and weather: dead beams, lost packets, fog and rain.

Each takes the source frame and returns a strategy of
:class:`~pytest_metamorphic.core.engine.Followup` (the faulty frame and its parameters),
for ``@metamorphic(..., followup=...)`` or a relation of one's own.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.faults import (
    PACKET_DEGREES,
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


def lost_packets(frame: Any, *, max_packets: int = 10) -> st.SearchStrategy[Followup]:
    """The frame without 1 to ``max_packets`` consecutive packets (an azimuth block of
    :data:`~pytest_metamorphic.lidar.followups.faults.PACKET_DEGREES` each), from a start drawn in
    tenths of a degree; shrinking toward one packet straight ahead."""
    frame = _check_frame(frame)
    blocks = st.tuples(st.integers(0, 3599), st.integers(1, _positive(max_packets, "max_packets")))

    def lose(block: tuple[int, int]) -> Followup:
        start, packets = block
        fault = DropAzimuthBlock(math.radians(start / 10), math.radians(PACKET_DEGREES * packets))
        return Followup(fault.apply(frame), params={**fault.params(), "packets": packets})

    return blocks.map(lose)


def quantized_ranges(
    frame: Any, *, steps: Sequence[float] = (0.05, 0.1, 0.2)
) -> st.SearchStrategy[Followup]:
    """The frame with every range rounded to one of ``steps`` metres
    (:class:`~pytest_metamorphic.lidar.followups.faults.QuantizeRange`), shrinking toward the
    first."""
    frame = _check_frame(frame)
    levels = tuple(steps)
    if not levels:
        raise InvalidArgument("steps is empty")
    faults = [QuantizeRange(step) for step in levels]  # validates each step

    def quantize(fault: QuantizeRange) -> Followup:
        return Followup(fault.apply(frame), params=fault.params())

    return st.sampled_from(faults).map(quantize)


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
