"""Metamorphic relations for AEB systems under the speed follow-up (Iqbal's MR).

The follow-up changes the car's speed and re-synchronises the pedestrian, or keeps the
pedestrian's own timing (Iqbal's campaign; ``keep="pedestrian"``) (:meth:`Scenario.with_ego_speed`,
drawn by :func:`pytest_metamorphic.strategies.ego_speed_changes`). The system under test
returns a :class:`~pytest_metamorphic.driving.kinematics.SimulationResult` for each
scenario. Relations:

* :func:`avoided_stays_avoided` -- a collision avoided in the source stays avoided in the
  follow-up, unless the follow-up's collision was physically unavoidable (at a higher
  speed the same warning time may simply not be enough to stop), judged from the scenario
  alone by :func:`~pytest_metamorphic.driving.judge.judge_avoidable` (or, with
  ``judge="simulated"``, by ideal braking in the built-in simulator,
  :func:`~pytest_metamorphic.driving.kinematics.physically_avoidable`);
* :func:`impact_speed_monotone` -- approaching more slowly never raises the impact speed
  (an avoided collision counts as 0 km/h).

:func:`speed_relation` bundles the follow-up and both checks as a ``MetamorphicRelation``.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.driving.judge import RELEVANCE_STANDARDS, Judgement, judge_avoidable
from pytest_metamorphic.driving.kinematics import (
    Avoidability,
    Sensor,
    SimulationResult,
    physically_avoidable,
)
from pytest_metamorphic.driving.scenario import Keep

__all__ = [
    "AvoidedStaysAvoided",
    "ImpactSpeedMonotone",
    "avoided_stays_avoided",
    "impact_speed_monotone",
    "speed_relation",
]


def _result(value: Any, which: str, relation: str) -> SimulationResult:
    if not isinstance(value, SimulationResult):
        raise InvalidArgument(
            f"{relation} needs the system under test to return a SimulationResult "
            f"(from pytest_metamorphic.driving.kinematics.simulate); the {which} output is "
            f"{type(value).__name__}"
        )
    return value


class AvoidedStaysAvoided(Relation):
    """A collision avoided in the source stays avoided in the follow-up.

    Parameters
    ----------
    excuse_unavoidable : bool
        Do not blame the system for a follow-up collision that no braking could have
        avoided. With False the relation is Iqbal's literal MR, which a perfect AEB also
        violates at high enough speeds.
    judge : {"scenario", "simulated"}
        Who decides avoidability: :func:`~pytest_metamorphic.driving.judge.judge_avoidable`
        from the scenario alone (default; shares no code with controllers or simulator),
        or :func:`physically_avoidable` (ideal braking in the built-in simulator).
    slack : float
        Seconds of grace after the pedestrian becomes relevant (the scenario judge's
        ``decision_time``; :func:`physically_avoidable`'s ``slack``).
    relevance : str, optional
        When the pedestrian starts to count: the scenario judge's ``"carriageway"``
        (default), ``"lane"`` or ``"path"``; the simulated judge's ``"road"`` (default) or
        ``"lane"``.
    sensor : Sensor, optional
        The sensor model the system under test used (simulated judge only).
    """

    def __init__(
        self,
        *,
        excuse_unavoidable: bool = True,
        judge: Literal["scenario", "simulated"] = "scenario",
        slack: float = 0.1,
        relevance: str | None = None,
        sensor: Sensor | None = None,
    ) -> None:
        if not isinstance(excuse_unavoidable, bool):
            raise InvalidArgument(f"excuse_unavoidable={excuse_unavoidable!r} must be a bool")
        if not (isinstance(slack, (int, float)) and math.isfinite(slack) and slack >= 0):
            raise InvalidArgument(f"slack={slack!r} must be a number >= 0")
        if sensor is not None and not isinstance(sensor, Sensor):
            raise InvalidArgument(f"sensor={sensor!r} must be a Sensor")
        if judge not in ("scenario", "simulated"):
            raise InvalidArgument(f"judge={judge!r} must be 'scenario' or 'simulated'")
        allowed = RELEVANCE_STANDARDS if judge == "scenario" else ("road", "lane")
        relevance = allowed[0] if relevance is None else relevance
        if relevance not in allowed:
            raise InvalidArgument(
                f"relevance={relevance!r} must be one of {list(allowed)} for judge={judge!r}"
            )
        self.judge = judge
        self.relevance = relevance
        self.excuse_unavoidable = excuse_unavoidable
        self.slack = float(slack)
        self.sensor = sensor
        self.name = "avoided collision stays avoided" + (
            " (when physically avoidable)" if excuse_unavoidable else ""
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source = _result(source_output, "source", self.name)
        followup = _result(followup_output, "follow-up", self.name)
        details: dict[str, Any] = {
            "source_speed_kmh": source.scenario.ego_speed_kmh,
            "followup_speed_kmh": followup.scenario.ego_speed_kmh,
            "source_collided": source.collided,
            "followup_collided": followup.collided,
        }
        if source.collided or followup.avoided:
            return Verdict(True, self.name, details=details)
        assert followup.collision is not None
        details["location"] = followup.collision.location
        details["impact_speed_kmh"] = followup.collision.impact_speed_kmh
        avoidability: Avoidability | Judgement | None = None
        if self.excuse_unavoidable and self.judge == "scenario":
            avoidability = judge_avoidable(
                followup.scenario,
                relevance=self.relevance,  # type: ignore[arg-type]
                decision_time=self.slack,
            )
        elif self.excuse_unavoidable:
            avoidability = physically_avoidable(
                followup.scenario,
                slack=self.slack,
                relevance=self.relevance,  # type: ignore[arg-type]
                sensor=self.sensor,
            )
        if avoidability is not None:
            details["physically_avoidable"] = avoidability.avoidable
            details["relevant_time"] = avoidability.relevant_time
            if not avoidability.avoidable:
                return Verdict(True, self.name, avoidability.describe(), details)
        because = f"; {avoidability.describe()}" if avoidability else ""
        return Verdict(
            False,
            self.name,
            f"the source avoided the collision ({source.describe()}) but follow-up "
            f"{context.index} did not: {followup.describe()}{because}",
            details,
        )


def avoided_stays_avoided(
    *,
    excuse_unavoidable: bool = True,
    judge: Literal["scenario", "simulated"] = "scenario",
    slack: float = 0.1,
    relevance: str | None = None,
    sensor: Sensor | None = None,
) -> AvoidedStaysAvoided:
    """Iqbal's MR: an avoided collision stays avoided when the car's speed changes.

    See :class:`AvoidedStaysAvoided`.
    """
    return AvoidedStaysAvoided(
        excuse_unavoidable=excuse_unavoidable,
        judge=judge,
        slack=slack,
        relevance=relevance,
        sensor=sensor,
    )


class ImpactSpeedMonotone(Relation):
    """Approaching more slowly never raises the impact speed (avoided = 0 km/h).

    Only follow-ups slower than the source are judged: a faster follow-up may avoid a
    collision the source had (it reaches the braking stages earlier), so nothing is
    required there.
    """

    def __init__(self, *, tolerance_kmh: float = 1.0) -> None:
        if not (
            isinstance(tolerance_kmh, (int, float))
            and math.isfinite(tolerance_kmh)
            and tolerance_kmh >= 0
        ):
            raise InvalidArgument(f"tolerance_kmh={tolerance_kmh!r} must be a number >= 0")
        self.tolerance_kmh = float(tolerance_kmh)
        self.name = f"slower approach, no faster impact (±{self.tolerance_kmh:g} km/h)"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source = _result(source_output, "source", self.name)
        followup = _result(followup_output, "follow-up", self.name)
        before, after = source.impact_speed_kmh, followup.impact_speed_kmh
        details = {
            "source_speed_kmh": source.scenario.ego_speed_kmh,
            "followup_speed_kmh": followup.scenario.ego_speed_kmh,
            "source_impact_kmh": before,
            "followup_impact_kmh": after,
        }
        slower = followup.scenario.ego_speed_kmh < source.scenario.ego_speed_kmh
        if not slower or after <= before + self.tolerance_kmh:
            return Verdict(True, self.name, details=details)
        return Verdict(
            False,
            self.name,
            f"follow-up {context.index} approached at {followup.scenario.ego_speed_kmh:g} "
            f"km/h instead of {source.scenario.ego_speed_kmh:g} km/h, yet hit at "
            f"{after:.1f} km/h instead of {before:.1f} km/h",
            details,
        )


def impact_speed_monotone(*, tolerance_kmh: float = 1.0) -> ImpactSpeedMonotone:
    """See :class:`ImpactSpeedMonotone`."""
    return ImpactSpeedMonotone(tolerance_kmh=tolerance_kmh)


def speed_relation(
    *,
    min_speed_kmh: float = 15.0,
    max_speed_kmh: float = 100.0,
    step_kmh: float = 1.0,
    keep: Keep = "ego_start",
    excuse_unavoidable: bool = True,
    judge: Literal["scenario", "simulated"] = "scenario",
    slack: float = 0.1,
    tolerance_kmh: float = 1.0,
    sensor: Sensor | None = None,
) -> Any:
    """Iqbal's speed MR as a ``MetamorphicRelation`` for ``@metamorphic(relations=[...])``.

    The follow-up is :func:`~pytest_metamorphic.strategies.ego_speed_changes`
    with the given speed range; the check is :func:`avoided_stays_avoided` ``&``
    :func:`impact_speed_monotone`. With ``keep="pedestrian"`` (Iqbal's follow-up: the
    pedestrian walks as in the source, so the car and the pedestrian no longer meet at
    the same moment) only :func:`avoided_stays_avoided`: a slower car then arrives after
    the pedestrian, and how hard it could hit is no longer comparable.
    """
    from pytest_metamorphic.core.engine import MetamorphicRelation
    from pytest_metamorphic.strategies import ego_speed_changes

    options: dict[str, Any] = {
        "min_speed_kmh": min_speed_kmh,
        "max_speed_kmh": max_speed_kmh,
        "step_kmh": step_kmh,
        "keep": keep,
    }
    # Validate now (at decoration time), not on the first draw.
    from pytest_metamorphic.strategies._driving import _check_speed_options

    _check_speed_options(**options)

    def followup(source: Any) -> Any:
        return ego_speed_changes(source, **options)

    followup.__name__ = "ego_speed_changes"
    check: Relation = avoided_stays_avoided(
        excuse_unavoidable=excuse_unavoidable, judge=judge, slack=slack, sensor=sensor
    )
    if keep != "pedestrian":
        check = check & impact_speed_monotone(tolerance_kmh=tolerance_kmh)
    return MetamorphicRelation("ego speed change", followup, check)
