"""What a per-frame system ran on before: earlier sweeps, made from the sweep itself.

A detector that is per-frame by contract must give a sweep the same obstacles whatever
it saw before. State that leaks across calls breaks that: a ground height or a cluster
cache kept per grid cell, a tracker's smoothing left on in a detector, a cache keyed by
something two sweeps share (the point count, the header, the first points). The earlier
sweeps of :class:`EarlierSweeps` are made from the source sweep, so that they look like
the sweeps a recording holds around it (the same street, the same sensor) while every
grid cell changes:

* ``"turned 90"``, ``"turned 180"``, ``"turned 270"``: the sweep turned about the sensor
  (and its ROI with it), as after the car turned;
* ``"mirrored"``: reflected in the car's forward axis;
* ``"first half"``: its first half of the points (a sweep cut short: the same header, the
  same leading points, the same count-independent fields).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.perturb import RotateAboutSensor
from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX
from pytest_metamorphic.lidar.model.frame import Frame

__all__ = ["HISTORY_STEPS", "EarlierSweeps", "HistoryStep"]

HistoryStep = Literal["turned 90", "turned 180", "turned 270", "mirrored", "first half"]
HISTORY_STEPS: tuple[HistoryStep, ...] = (
    "turned 90",
    "turned 180",
    "turned 270",
    "mirrored",
    "first half",
)


@dataclass(frozen=True)
class EarlierSweeps:
    """Sweeps a system runs on, in order, before it runs on the source sweep again.

    Parameters
    ----------
    steps : sequence of str
        Each one of :data:`HISTORY_STEPS`: how an earlier sweep is made from the source.
    """

    steps: tuple[HistoryStep, ...]

    def __post_init__(self) -> None:
        steps = tuple(self.steps) if isinstance(self.steps, Sequence) else None
        if not steps or isinstance(self.steps, str):
            raise InvalidArgument(f"steps={self.steps!r} must be a non-empty sequence of steps")
        for step in steps:
            if step not in HISTORY_STEPS:
                raise InvalidArgument(f"step {step!r} must be one of {HISTORY_STEPS}")
        object.__setattr__(self, "steps", steps)

    def inputs(self, frame: Frame) -> list[Frame]:
        """The earlier sweeps made from ``frame``, in the order the system sees them."""
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        return [_earlier(frame, step) for step in self.steps]

    # The engine's replay protocol: inputs to run, in order, before the follow-up.
    earlier_inputs = inputs

    def params(self) -> dict[str, Any]:
        return {"earlier_sweeps": ", then ".join(self.steps), "history": self}

    def to_json(self) -> dict[str, Any]:
        return {"type": "EarlierSweeps", "steps": list(self.steps)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> EarlierSweeps:
        """The history :meth:`to_json` describes (artifacts replay with it)."""
        return cls(tuple(data["steps"]))

    def __repr__(self) -> str:
        return f"EarlierSweeps({', then '.join(self.steps)})"


def _earlier(frame: Frame, step: HistoryStep) -> Frame:
    if step == "mirrored":
        return MirrorAcrossX().apply(frame)
    if step == "first half":
        return frame.with_cloud(frame.cloud[: len(frame.cloud) // 2])
    degrees = int(step.split()[1])
    return RotateAboutSensor(math.radians(degrees)).apply(frame)
