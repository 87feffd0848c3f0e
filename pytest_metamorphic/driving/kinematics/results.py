"""What a simulation returns: the :class:`Collision` (which face of the car was hit) and the
trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.driving.scenario import KMH, Scenario

__all__ = ["Collision", "SimulationResult"]


@dataclass(frozen=True)
class Collision:
    """The first contact between the car and another actor.

    Attributes
    ----------
    time : float
        Seconds after the start.
    actor : str
        ``"pedestrian"`` or the parked car's name.
    location : {"front", "side", "rear"}
        The face of the car that was hit.
    side : {"left", "right"} or None
        For side contacts.
    impact_speed : float
        The car's speed at contact (m/s).
    ego_s : float
        Arc length of the front bumper at contact.
    """

    time: float
    actor: str
    location: Literal["front", "side", "rear"]
    side: Literal["left", "right"] | None
    impact_speed: float
    ego_s: float

    @property
    def impact_speed_kmh(self) -> float:
        return self.impact_speed / KMH

    def describe(self) -> str:
        where = self.location if self.side is None else f"{self.side} {self.location}"
        return (
            f"{where} collision with the {self.actor} at {self.impact_speed_kmh:.1f} km/h, "
            f"t={self.time:.2f} s"
        )


@dataclass(frozen=True)
class SimulationResult:
    """What happened in one run.

    Attributes
    ----------
    scenario : Scenario
    collision : Collision or None
    end_time : float
    final_speed : float
        m/s when the run ended.
    ego_s : float
        Front-bumper arc length when the run ended.
    first_brake_time : float or None
        First step with a non-zero deceleration command.
    stages : tuple of (time, stage)
        Every change of the controller's stage name.
    times, speeds, positions, decelerations : (n,) float64
        The trace (``positions`` = front-bumper arc length); not compared for equality.
    """

    scenario: Scenario
    collision: Collision | None
    end_time: float
    final_speed: float
    ego_s: float
    first_brake_time: float | None
    stages: tuple[tuple[float, str], ...]
    times: NDArray[np.float64] = field(compare=False, repr=False)
    speeds: NDArray[np.float64] = field(compare=False, repr=False)
    positions: NDArray[np.float64] = field(compare=False, repr=False)
    decelerations: NDArray[np.float64] = field(compare=False, repr=False)

    @property
    def collided(self) -> bool:
        return self.collision is not None

    @property
    def avoided(self) -> bool:
        return self.collision is None

    @property
    def impact_speed(self) -> float:
        """Impact speed in m/s, 0 when the collision was avoided."""
        return 0.0 if self.collision is None else self.collision.impact_speed

    @property
    def impact_speed_kmh(self) -> float:
        return self.impact_speed / KMH

    def describe(self) -> str:
        outcome = (
            self.collision.describe()
            if self.collision
            else f"avoided (car at {self.final_speed / KMH:.1f} km/h when the run ended)"
        )
        return f"{self.scenario.kind} at {self.scenario.ego_speed_kmh:g} km/h: {outcome}"
