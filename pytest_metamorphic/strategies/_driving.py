"""Strategies for AEB scenario testing: protocol-valid Euro NCAP scenarios and speed follow-ups.

Everything is drawn as a few small structured parameters (test kind, road width and lanes,
lane, protocol speed), so Hypothesis shrinks a failure toward the protocol's plain case:
the first kind listed, the 10 m test road, the lowest speed, the smallest speed change.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from hypothesis import strategies as st
from hypothesis.strategies import SearchStrategy

from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import (
    INITIAL_TTC,
    KEEP_MODES,
    KINDS,
    PROTOCOLS,
    Keep,
    Scenario,
    euro_ncap,
)

__all__ = ["aeb_scenarios", "ego_speed_changes", "straight_roads"]

_PROTOCOL_WIDTH = 10.0
_MIN_LANE_WIDTH = 2.5


def _number(value: Any, name: str, *, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name}={value!r} must be a number")
    if not math.isfinite(value) or (positive and value <= 0):
        raise InvalidArgument(f"{name}={value!r} must be a finite number > 0")
    return float(value)


def straight_roads(
    *,
    min_width: float = 3.0,
    max_width: float = 12.0,
    max_lanes: int = 3,
    length: float = 300.0,
) -> SearchStrategy[RoadGeometry]:
    """Straight roads of any width, in 0.25 m steps, shrinking toward the 10 m test road.

    Parameters
    ----------
    min_width, max_width : float
        Carriageway width range in metres.
    max_lanes : int
        At most this many lanes; a lane is never narrower than 2.5 m.
    length : float
    """
    low = _number(min_width, "min_width")
    high = _number(max_width, "max_width")
    if low > high:
        raise InvalidArgument(f"min_width={min_width} must be <= max_width={max_width}")
    if low < _MIN_LANE_WIDTH:
        raise InvalidArgument(f"min_width={min_width} must be >= {_MIN_LANE_WIDTH} (one lane)")
    if isinstance(max_lanes, bool) or not isinstance(max_lanes, int) or max_lanes < 1:
        raise InvalidArgument(f"max_lanes={max_lanes!r} must be an int >= 1")
    _number(length, "length")
    steps = range(math.ceil(low * 4), math.floor(high * 4) + 1)
    widths = sorted((q / 4 for q in steps), key=lambda w: (abs(w - _PROTOCOL_WIDTH), w))
    if not widths:
        raise InvalidArgument(f"no 0.25 m width step lies in [{min_width}, {max_width}]")

    @st.composite
    def roads(draw: Callable[[SearchStrategy[Any]], Any]) -> RoadGeometry:
        width = draw(st.sampled_from(widths))
        lanes = draw(st.integers(1, max(1, min(max_lanes, int(width // _MIN_LANE_WIDTH)))))
        return RoadGeometry.straight(length=length, width=width, lanes=lanes)

    return roads()


def aeb_scenarios(
    *,
    kinds: Sequence[str] = KINDS,
    roads: SearchStrategy[RoadGeometry] | Sequence[RoadGeometry] | None = None,
    speeds_kmh: Sequence[float] | None = None,
    initial_ttc: float = INITIAL_TTC,
) -> SearchStrategy[Scenario]:
    """Protocol-valid Euro NCAP AEB pedestrian scenarios.

    Parameters
    ----------
    kinds : sequence of str
        Tests to draw from (:data:`~pytest_metamorphic.driving.scenario.KINDS`); shrinks
        toward the first.
    roads : strategy or sequence of RoadGeometry, optional
        Default :func:`straight_roads`. Pass real OSM roads
        (``[RoadGeometry.from_osm(r) for r in load_roads(path)]``) to test on them.
    speeds_kmh : sequence of float, optional
        Car speeds to draw from; default each test's protocol speeds (10..60 km/h in 5 km/h
        steps; CPLA from 20 km/h).
    initial_ttc : float
        The car starts this many seconds before the impact (protocol: 6).

    Notes
    -----
    The car drives in the centre of a drawn lane; the collision point is placed so that
    the car starts on the road when the road is long enough.
    """
    kinds = list(kinds)
    if not kinds:
        raise InvalidArgument("kinds must name at least one test")
    unknown = [kind for kind in kinds if kind not in PROTOCOLS]
    if unknown:
        raise InvalidArgument(f"kinds contains unknown tests {unknown}; known: {list(KINDS)}")
    if roads is None:
        road_strategy: SearchStrategy[RoadGeometry] = straight_roads()
    elif isinstance(roads, SearchStrategy):
        road_strategy = roads
    else:
        road_list = list(roads)
        if not road_list or not all(isinstance(r, RoadGeometry) for r in road_list):
            raise InvalidArgument(
                "roads must be a strategy or a non-empty sequence of RoadGeometry"
            )
        road_strategy = st.sampled_from(road_list)
    speeds: list[float] | None = None
    if speeds_kmh is not None:
        speeds = [_number(v, "speeds_kmh[...]") for v in speeds_kmh]
        if not speeds:
            raise InvalidArgument("speeds_kmh must not be empty")
    ttc = _number(initial_ttc, "initial_ttc")

    @st.composite
    def scenarios(draw: Callable[[SearchStrategy[Any]], Any]) -> Scenario:
        kind = draw(st.sampled_from(kinds))
        road = draw(road_strategy)
        lane = draw(st.integers(0, road.lanes - 1))
        speed = draw(st.sampled_from(speeds or PROTOCOLS[kind].speeds_kmh))
        return euro_ncap(kind, ego_speed_kmh=speed, road=road, ego_lane=lane, initial_ttc=ttc)

    return scenarios()


def _check_speed_options(
    *, min_speed_kmh: float, max_speed_kmh: float, step_kmh: float, keep: str
) -> None:
    low = _number(min_speed_kmh, "min_speed_kmh")
    high = _number(max_speed_kmh, "max_speed_kmh")
    _number(step_kmh, "step_kmh")
    if low > high:
        raise InvalidArgument(
            f"min_speed_kmh={min_speed_kmh} must be <= max_speed_kmh={max_speed_kmh}"
        )
    if keep not in KEEP_MODES:
        raise InvalidArgument(f"keep={keep!r} must be one of {list(KEEP_MODES)}")


def ego_speed_changes(
    source: Scenario,
    *,
    min_speed_kmh: float = 15.0,
    max_speed_kmh: float = 100.0,
    step_kmh: float = 1.0,
    keep: Keep = "ego_start",
) -> SearchStrategy[Followup]:
    """The speed follow-up: the source at another car speed, pedestrian re-synchronised.

    Draws a change ``±k * step_kmh`` (k >= 1) keeping the new speed within
    ``[min_speed_kmh, max_speed_kmh]``; shrinks toward the smallest change. Yields
    :class:`~pytest_metamorphic.Followup` values whose parameters (new speed, change,
    time to the collision point, the pedestrian's new start time) appear in failures.
    Use directly as ``@metamorphic(followup=ego_speed_changes, ...)``.

    Parameters
    ----------
    source : Scenario
    min_speed_kmh, max_speed_kmh, step_kmh : float
        Iqbal's protocol: 15..100 km/h in 1 km/h steps.
    keep : {"ego_start", "time", "pedestrian"}
        See :meth:`Scenario.with_ego_speed` (default: the car starts where it did and the
        pedestrian's start moves; ``"pedestrian"``, Iqbal's campaign: the pedestrian
        walks as in the source, so a faster car arrives early).
    """
    if not isinstance(source, Scenario):
        raise InvalidArgument(f"source={source!r} must be a Scenario")
    _check_speed_options(
        min_speed_kmh=min_speed_kmh, max_speed_kmh=max_speed_kmh, step_kmh=step_kmh, keep=keep
    )
    speed = source.ego_speed_kmh
    lowest = math.ceil((min_speed_kmh - speed) / step_kmh - 1e-9)
    highest = math.floor((max_speed_kmh - speed) / step_kmh + 1e-9)
    if lowest > highest or (lowest == highest == 0):
        raise InvalidArgument(
            f"no speed change of {step_kmh:g} km/h steps from {speed:g} km/h stays within "
            f"[{min_speed_kmh:g}, {max_speed_kmh:g}] km/h"
        )

    def build(k: int) -> Followup:
        new_speed = round(speed + k * step_kmh, 9)
        followup = source.with_ego_speed(new_speed, keep=keep)
        return Followup(
            followup,
            params={
                "ego_speed_kmh": new_speed,
                "delta_kmh": round(new_speed - speed, 9),
                "time_to_collision_point_s": round(followup.time_to_collision_point, 3),
                "pedestrian_start_s": round(followup.pedestrian_start_time, 3),
            },
        )

    return st.integers(lowest, highest).filter(lambda k: k != 0).map(build)
