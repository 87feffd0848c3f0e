"""Sensor faults and weather as campaigns: a robustness curve per relation."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from pytest_metamorphic.core.campaign import Campaign
from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.campaign.sources import (
    SourceFn,
    _severities,
    scoped_campaign,
)
from pytest_metamorphic.lidar.followups.faults import (
    PACKET_DEGREES,
    CoveredObstaclesKept,
    DropAzimuthBlock,
    DropRings,
    QuantizeRange,
)
from pytest_metamorphic.lidar.followups.perturb import SEED_BITS
from pytest_metamorphic.lidar.followups.weather import Weather
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors import frame_sensor

__all__ = [
    "FAULT_SEVERITIES",
    "dead_beams_followup",
    "fault_campaign",
    "fog_followup",
    "lost_packets_followup",
    "quantized_followup",
    "rain_followup",
]


#: Default severities: dead lasers (of 64), lost packets (of 1.04 degrees each). The
#: relation holds for the reference pipeline up to 8 dead lasers on the KITTI sweeps; with
#: 16 it loses 1 well-covered obstacle in 24 follow-ups (beyond the relation's validity).
#: Fog and rain: the visibility in metres (smaller is worse); quantisation: the range step
#: in centimetres.
FAULT_SEVERITIES: dict[str, tuple[int, ...]] = {
    "beam_loss": (1, 2, 4, 8),
    "packet_loss": (1, 5, 10, 20, 40),
    "fog": (400, 200, 100, 50),
    "rain": (400, 200, 100, 50),
    "quantization": (5, 10, 20),
}
_SEVERITY_LIMITS = {
    "beam_loss": HDL64E.lasers,
    "packet_loss": int(360 / PACKET_DEGREES),
    "fog": 100_000,
    "rain": 100_000,
    "quantization": 100,
}


def dead_beams_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """``severity`` random lasers of the frame's sensor (of those with returns) return
    nothing; raises when its lasers cannot be known or it has too few."""
    estimate = frame_sensor(frame)
    lasers = estimate.lasers
    if len(lasers) <= severity:
        raise InvalidArgument(
            f"beam loss of {severity} lasers on {frame!r}: {estimate.describe()} has "
            f"{len(lasers)} lasers with returns; pass the frame's sensor= or lower severities"
        )
    rings = rng.choice(lasers, size=severity, replace=False)
    fault = DropRings(tuple(int(r) for r in rings))
    return Followup(fault.apply(frame), params={**fault.params(), "sensor": estimate.describe()})


def lost_packets_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """``severity`` consecutive packets of the frame's sensor lost, from a random azimuth;
    raises when the sensor's packets are unknown."""
    sensor = frame_sensor(frame).sensor
    degrees = None if sensor is None else sensor.packet_degrees
    if degrees is None:
        raise InvalidArgument(
            f"packet loss on {frame!r}: the packet width of {frame_sensor(frame).describe()} "
            "is not known; pass the frame's sensor="
        )
    start = float(rng.uniform(0.0, 2 * math.pi))
    fault = DropAzimuthBlock(start, math.radians(degrees * severity))
    return Followup(fault.apply(frame), params={**fault.params(), "packets": severity})


def fog_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """Fog of ``severity`` metres visibility (see
    :mod:`pytest_metamorphic.lidar.followups.weather`)."""
    weather = Weather(float(severity), "fog", int(rng.integers(2**SEED_BITS)))
    return Followup(weather.apply(frame), params=weather.params())


def rain_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """Rain of ``severity`` metres visibility."""
    weather = Weather(float(severity), "rain", int(rng.integers(2**SEED_BITS)))
    return Followup(weather.apply(frame), params=weather.params())


def quantized_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """Every range rounded to ``severity`` centimetres."""
    fault = QuantizeRange(severity / 100.0)
    return Followup(fault.apply(frame), params=fault.params())


#: How the reports name each fault's severity.
_SEVERITY_LABELS = {
    "beam_loss": "dead lasers",
    "packet_loss": "lost packets",
    "fog": "visibility m",
    "rain": "visibility m",
    "quantization": "range step cm",
}

_FAULT_FOLLOWUPS = {
    "beam_loss": dead_beams_followup,
    "packet_loss": lost_packets_followup,
    "fog": fog_followup,
    "rain": rain_followup,
    "quantization": quantized_followup,
}


def fault_campaign(
    system: Callable[[Frame], Sequence[Box]],
    *,
    fault: Literal["beam_loss", "packet_loss", "fog", "rain", "quantization"],
    name: str,
    frames: SourceFn | FrameCatalog | str | os.PathLike[str] | None = None,
    sources: int | None = None,
    severities: Sequence[int] | None = None,
    followups: int = 1,
    seed: int = 0,
    min_points: int = 30,
    min_share: float | None = None,
    min_height_share: float = 0.8,
    min_detected: float = 0.5,
    scope: ScopeLike = "roi",
) -> Campaign:
    """A sensor-fault relation as a campaign: violation rates per severity, with Wilson
    intervals, i.e. a robustness curve per relation (Robo3D reports mAP drops; this
    reports how often a well-covered obstacle is lost).

    Parameters
    ----------
    system : callable(Frame) -> sequence of Box
    fault : {"beam_loss", "packet_loss", "fog", "rain", "quantization"}
        Dead lasers (severity: how many of the 64), lost packets (severity: how many
        consecutive 1.04-degree blocks), fog and rain (severity: the visibility in
        metres; obstacles farther than it are not judged), or a coarser range resolution
        (severity: the step in centimetres).
    name, frames, sources, followups, seed, scope
        As for :func:`mr1_campaign`.
    severities : sequence of int, optional
        Default :data:`FAULT_SEVERITIES` for the fault.
    min_points, min_share, min_height_share, min_detected
        What counts as well covered and as kept
        (:class:`~pytest_metamorphic.lidar.followups.faults.CoveredObstaclesKept`); ``min_share``
        defaults to 0.8 for fog and rain (as
        :func:`~pytest_metamorphic.relations.lidar.adverse_weather`) and 0.5 otherwise.
    """
    if fault not in _FAULT_FOLLOWUPS:
        raise InvalidArgument(f"fault={fault!r} must be one of {sorted(_FAULT_FOLLOWUPS)}")
    levels = _severities(severities, FAULT_SEVERITIES[fault], _SEVERITY_LIMITS[fault])
    weather = fault in ("fog", "rain")
    share = (0.8 if weather else 0.5) if min_share is None else min_share
    return scoped_campaign(
        system,
        name=name,
        frames=frames,
        sources=sources,
        followup=_FAULT_FOLLOWUPS[fault],
        relation=lambda chosen: CoveredObstaclesKept(
            min_points=min_points,
            min_share=share,
            min_height_share=min_height_share,
            min_detected=min_detected,
            scope=chosen,
            range_param="visibility_m" if weather else None,
        ),
        sizes=levels,
        followups=followups,
        seed=seed,
        scope=scope,
        size_label=_SEVERITY_LABELS[fault],
    )
