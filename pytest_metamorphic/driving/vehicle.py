"""The car under test: its footprint, brakes and sensor latency."""

from __future__ import annotations

from dataclasses import dataclass

from pytest_metamorphic.core.arguments import check_number

__all__ = ["EURO_NCAP_CAR", "TYPICAL_CAR", "VehicleSpec"]


@dataclass(frozen=True)
class VehicleSpec:
    """The car under test.

    Parameters
    ----------
    length, width : float
        Footprint in metres (default: the Euro NCAP reference car, 4.358 x 1.815 m).
    wheelbase : float
        Used to turn the body smoothly through polyline corners.
    max_deceleration : float
        The most the brakes can do, m/s^2 (9.8: the MATLAB example's full braking).
    brake_delay : float
        Dead time between a brake command and the deceleration, seconds.
    sensor_latency : float
        Age of what the AEB sees: each observation describes the world this many seconds
        ago (perception and tracking time), seconds.
    """

    length: float = 4.358
    width: float = 1.815
    wheelbase: float = 2.7
    max_deceleration: float = 9.8
    brake_delay: float = 0.0
    sensor_latency: float = 0.0

    def __post_init__(self) -> None:
        for name in ("length", "width", "wheelbase", "max_deceleration"):
            check_number(getattr(self, name), f"VehicleSpec {name}", positive=True)
        for name in ("brake_delay", "sensor_latency"):
            check_number(getattr(self, name), f"VehicleSpec {name}")

    @property
    def system_delay(self) -> float:
        """Seconds from a pedestrian's move to the brakes acting on it (latency + delay)."""
        return self.sensor_latency + self.brake_delay

    def describe(self) -> str:
        return (
            f"{self.max_deceleration:g} m/s^2 peak, {self.brake_delay:g} s brake delay, "
            f"{self.sensor_latency:g} s sensor latency"
        )


#: The ideal car: the Euro NCAP reference footprint with the MATLAB example's brakes
#: (9.8 m/s^2 at once, no latency).
EURO_NCAP_CAR = VehicleSpec()
#: A production car as the campaign assumes it by default: 9.0 m/s^2 peak deceleration
#: (about 0.9 g, dry asphalt with ABS), 0.2 s from a brake command to that deceleration
#: (brake pre-fill and pressure build-up; pedestrian AEB brakes in a short ramp before its
#: steady phase, SAE 2020-01-0878) and 0.1 s sensor latency (one 10 Hz LiDAR/radar frame).
#: Assumptions, stated: :func:`~pytest_metamorphic.driving.sensitivity.sensitivity_campaign`
#: shows what changes over 8-9.8 m/s^2, 0-0.3 s and 0-0.2 s.
TYPICAL_CAR = VehicleSpec(max_deceleration=9.0, brake_delay=0.2, sensor_latency=0.1)
