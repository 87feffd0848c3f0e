"""Checks that obstacles move with the scene: turned, mirrored or shifted.

A rigid change of the cloud and the ROI (:mod:`pytest_metamorphic.lidar.followups.symmetry`,
:class:`~pytest_metamorphic.lidar.followups.perturb.RotateAboutSensor`) should move a detector's
boxes the same way. :class:`MovedObstacles` compares the source's boxes, moved, with the
follow-up's, one to one within tolerances; the subclasses say how a box moves. The
relations (:func:`~pytest_metamorphic.relations.lidar.rotation_equivariance`,
``mirror_symmetry``, ``translation_equivariance``) and the symmetry campaigns
(:func:`~pytest_metamorphic.lidar.campaign.symmetry_campaign`) share them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import one_to_one
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.model.obstacles import Box, as_boxes, box_gap, box_support
from pytest_metamorphic.lidar.model.pose import SensorPose
from pytest_metamorphic.lidar.model.terrain import Terrain

__all__ = [
    "SAME_OBSTACLE",
    "TURN_TOLERANCES",
    "MirroredObstacles",
    "MovedObstacles",
    "PosedObstacles",
    "RotatedObstacles",
    "ShiftedObstacles",
    "TerrainObstacles",
    "moved_obstacles",
]

#: What "the same obstacle" means after a quarter turn or the mirror (centre m, length
#: and width m, heading degrees; labels compared): wide enough for clustering with ties,
#: far below what a real fault moves. A sensor-anchored grid maps onto itself, so the
#: reference pipeline's boxes move exactly; a DBSCAN detector, whose border points go to
#: whichever touching cluster reaches them first (the KD-tree of a turned sweep visits
#: them in another order), moved boxes by up to 2.1 cm, 3.8 cm and 1.4 degrees over the
#: six KITTI sweeps (the outside detector of issue 26, Open3D DBSCAN: 1.5 cm, 3 cm,
#: 2.4 degrees); a 2-degree error in the output frame (``turned_output_frame``) moves the
#: mirrored boxes by 1.1-5.0 m on every sweep.
SAME_OBSTACLE: tuple[float, float, float] = (0.10, 0.15, 5.0)

#: Default (centre m, size m, yaw degrees, min points, ROI-edge margin m) of rotation
#: checks: quarter turns map a sensor-anchored grid onto itself (:data:`SAME_OBSTACLE`,
#: labels compared); other angles cut objects differently (see ``rotation_equivariance``).
TURN_TOLERANCES: dict[str, tuple[float, float, float, int, float]] = {
    "quarter_turns": (*SAME_OBSTACLE, 0, 0.5),
    "any": (0.8, 0.8, 20.0, 30, 1.0),
}


class MovedObstacles(Relation):
    """``O'`` is ``O`` moved as the scene was (turned, mirrored), within tolerances.

    Compared are the *clear* obstacles of either side: labelled car, pedestrian or
    cyclist, with at least ``min_points`` points, and whose footprint circle stays more
    than ``boundary_margin`` metres from the ROI's edges (the moved ROI is rasterised
    afresh, as Apollo does every frame, so cells along its edges differ). Each clear
    source obstacle, moved, needs its own follow-up obstacle (of the same label when
    ``same_label``) with the centre within ``center_tolerance``, length and width each
    within ``size_tolerance`` and, for elongated boxes (length - width > 0.3 m), the heading within
    ``yaw_tolerance`` degrees modulo 180 (a box's front is not defined); and each clear
    follow-up obstacle needs its own such source obstacle (with ``exclusive=False``, any
    such obstacle: pieces of one object may share it; with ``extras_judged=False`` the
    follow-up's obstacles are not judged, only the source's kept). With a ``scope``
    (:mod:`pytest_metamorphic.lidar.judging.scope`, default the ROI) only obstacles it judges are
    clear; others are counted in ``unjudged`` details, as information.
    """

    def __init__(
        self,
        *,
        center_tolerance: float,
        size_tolerance: float,
        yaw_tolerance: float,
        min_points: int,
        boundary_margin: float,
        same_label: bool = True,
        exclusive: bool = True,
        extras_judged: bool = True,
        scope: ScopeLike = "roi",
    ) -> None:
        self.scope: ObstacleScope = as_scope(scope)
        for flag, setting in (("same_label", same_label), ("exclusive", exclusive),
                              ("extras_judged", extras_judged)):  # fmt: skip
            if not isinstance(setting, bool):
                raise InvalidArgument(f"{flag}={setting!r} must be True or False")
        self.exclusive = exclusive
        self.extras_judged = extras_judged
        for label, value in (
            ("center_tolerance", center_tolerance),
            ("size_tolerance", size_tolerance),
            ("yaw_tolerance", yaw_tolerance),
            ("boundary_margin", boundary_margin),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                raise InvalidArgument(f"{label}={value!r} must be a number >= 0")
        if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 0:
            raise InvalidArgument(f"min_points={min_points!r} must be an int >= 0")
        self.center_tolerance = float(center_tolerance)
        self.size_tolerance = float(size_tolerance)
        self.yaw_tolerance = math.radians(yaw_tolerance)
        self.min_points = min_points
        self.boundary_margin = float(boundary_margin)
        self.same_label = same_label
        self.name = (
            f"{self.moved}(centre<={center_tolerance:g} m, size<={size_tolerance:g} m, "
            f"yaw<={yaw_tolerance:g} deg{', same label' if same_label else ''}"
            f"{'' if exclusive else ', pieces share a match'}; "
            f"{self.scope.describe()})"
        )

    moved = "moved"

    @property
    def note(self) -> str:
        """What a violation's message adds about the follow-up. Rotations, the mirror,
        shifts and poses move every point and add or drop none, so the follow-up holds
        the same scene: whatever differs was decided by the detector."""
        return (
            f" (the follow-up holds exactly the source's points, {self.moved}: any "
            "difference is the detector's)"
        )

    def move(self, box: Box, context: CheckContext) -> Box:
        """Where ``box`` should be in the follow-up."""
        raise NotImplementedError

    def move_details(self, context: CheckContext) -> dict[str, Any]:
        return {}

    def _param(self, context: CheckContext, key: str, what: str, makers: str) -> float:
        """The follow-up's ``params[key]`` (its ``what``, e.g. "rotation"), as a float."""
        if key not in context.params:
            raise InvalidArgument(
                f"{self.name} needs the follow-up's {what} in params[{key!r}] "
                f"(use {makers}.params())"
            )
        return float(context.params[key])

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        moved = self.move_details(context)  # validates the follow-up's parameters first
        expected = [self.move(box, context) for box in as_boxes(source_output, "source")]
        found = as_boxes(followup_output, "follow-up")
        roi = getattr(context.followup_input, "roi", None)
        # Judged in the follow-up's frame: the turned source boxes and the found ones.
        judged_expected = self.scope.judged(expected, context.followup_input)
        judged_found = self.scope.judged(found, context.followup_input)
        cloud = getattr(context.followup_input, "cloud", None)
        xyz = None if cloud is None else cloud.xyz
        clear_expected = self._clear(expected, roi, judged_expected, xyz)
        clear_found = self._clear(found, roi, judged_found, xyz)
        if not self.extras_judged:
            clear_found = []
        missing = self._unmatched(expected, clear_expected, found)
        extra = self._unmatched(found, clear_found, expected)
        details = {
            **moved,
            "judged": len(clear_expected) + len(clear_found),
            "missing": [],
            "extra": [],
            "scope": self.scope.describe(),
            "unjudged_changes": self._unjudged_changes(
                expected, found, judged_expected, judged_found
            ),
            # Source indices: what a picture marks as lost, and what it shows as not judged.
            "blamed": [],
            "unjudged_source": [int(i) for i in np.flatnonzero(~judged_expected)],
        }
        if not clear_expected and not clear_found:
            details["unjudged_reason"] = self._why_unjudged(expected, found, judged_expected,
                                                            judged_found)  # fmt: skip
        if not missing and not extra:
            return Verdict(True, self.name, details=details)
        lines = [
            f"source {expected[i].describe()} ({self.moved}) has no match"
            + self._diagnosis(expected[i], found, context.followup_input)
            for i in missing
        ]
        lines += [f"follow-up {found[j].describe()} has no source counterpart" for j in extra]
        note = self.note
        details["blamed"] = list(missing)
        details["missing"] = [expected[i].describe() for i in missing]
        details["extra"] = [found[j].describe() for j in extra]
        return Verdict(False, self.name, "; ".join(lines[:10]) + note, details)

    def _why_unjudged(
        self,
        expected: Sequence[Box],
        found: Sequence[Box],
        judged_expected: NDArray[np.bool_],
        judged_found: NDArray[np.bool_],
    ) -> str:
        """Why no obstacle was clear enough to judge (the NOTHING TESTED line says it)."""
        in_scope = [b for b, j in zip(expected, judged_expected, strict=True) if j]
        in_scope += [b for b, j in zip(found, judged_found, strict=True) if j]
        if not in_scope:
            return f"no obstacle in scope ({self.scope.describe()}) on either side"
        if all(box.label == "unknown" for box in in_scope):
            return (
                f"every obstacle in scope ({len(in_scope)}) was 'unknown', and this relation "
                "judges only cars, pedestrians and cyclists: report road-user classes (map "
                "your detector's to car, pedestrian and cyclist), or rely on the relations "
                "that judge every class (the invariances, beam and packet loss, weather)"
            )
        return (
            f"no road user in scope had >= {self.min_points} returns and lay "
            f"{self.boundary_margin:g} m inside the ROI's edge"
        )

    def _diagnosis(self, moved: Box, found: Sequence[Box], followup: Any) -> str:
        """How a lost obstacle came out: where its points went (per follow-up obstacle)
        and how far the nearest follow-up obstacle is from the tolerances."""
        parts = []
        cloud = getattr(followup, "cloud", None)
        if cloud is not None:
            inside = moved.contains(cloud.xyz)
            points = cloud.xyz[inside]
            counts = [(int(box.contains(points).sum()), box) for box in found]
            groups = sorted((c for c in counts if c[0]), key=lambda c: -c[0])[:3]
            grouped = ", ".join(f"{n} in the {box.describe()}" for n, box in groups)
            parts.append(f"its {len(points)} points: {grouped or 'none in any obstacle'}")
        if found:
            near = min(found, key=moved.center_distance)
            turned = math.degrees(abs(math.remainder(moved.yaw - near.yaw, math.pi)))
            parts.append(
                f"nearest: {near.describe()}, centre {moved.center_distance(near):.2f} m off, "
                f"length {near.size[0] - moved.size[0]:+.2f} m, "
                f"width {near.size[1] - moved.size[1]:+.2f} m, "
                f"height {near.size[2] - moved.size[2]:+.2f} m, heading {turned:.1f} deg"
            )
        return f" ({'; '.join(parts)})" if parts else ""

    def _unjudged_changes(
        self,
        expected: list[Box],
        found: list[Box],
        judged_expected: NDArray[np.bool_],
        judged_found: NDArray[np.bool_],
    ) -> int:
        """Unjudged obstacles, on either side, without a partner within the tolerances."""
        outside = [i for i, judged in enumerate(judged_expected) if not judged]
        outside2 = [j for j, judged in enumerate(judged_found) if not judged]
        return len(self._unmatched(expected, outside, found)) + len(
            self._unmatched(found, outside2, expected)
        )

    def _clear(
        self, boxes: Sequence[Box], roi: Any, judged: NDArray[np.bool_], xyz: Any = None
    ) -> list[int]:
        # Support from Box.points, or counted in the moved cloud for boxes that carry no
        # count (converters' and processes' boxes): otherwise they would never be judged.
        support = box_support(boxes, xyz) if self.min_points else None
        chosen = []
        for index, box in enumerate(boxes):
            if not judged[index]:
                continue
            if box.label == "unknown" or (support is not None and support[index] < self.min_points):
                continue
            if roi is not None and self.boundary_margin > 0:
                reach = math.hypot(box.size[0], box.size[1]) / 2.0 + self.boundary_margin
                if roi.boundary_distance([box.center[:2]])[0] <= reach:
                    continue
            chosen.append(index)
        return chosen

    def _unmatched(
        self, boxes: Sequence[Box], chosen: list[int], others: Sequence[Box]
    ) -> list[int]:
        """Indices in ``chosen`` (into ``boxes``) left without a partner among ``others``."""
        if not chosen:
            return []
        compatible = np.zeros((len(chosen), len(others)), dtype=bool)
        cost = np.zeros(compatible.shape)
        for row, index in enumerate(chosen):
            for col, other in enumerate(others):
                distance, ok = self._compatible(boxes[index], other)
                compatible[row, col], cost[row, col] = ok, distance
        if not self.exclusive:  # pieces of one object may share their partner
            return [index for row, index in enumerate(chosen) if not compatible[row].any()]
        pairs = one_to_one(compatible, cost)
        matched = {chosen[row] for row, _ in pairs}
        return [index for index in chosen if index not in matched]

    def _compatible(self, a: Box, b: Box) -> tuple[float, bool]:
        distance = a.center_distance(b)
        if (self.same_label and a.label != b.label) or distance > self.center_tolerance:
            return distance, False
        if abs(a.size[0] - b.size[0]) > self.size_tolerance:
            return distance, False
        if abs(a.size[1] - b.size[1]) > self.size_tolerance:
            return distance, False
        elongated = a.size[0] - a.size[1] > 0.3 and b.size[0] - b.size[1] > 0.3
        turned = abs(math.remainder(a.yaw - b.yaw, math.pi))
        return distance, not (elongated and turned > self.yaw_tolerance)


class RotatedObstacles(MovedObstacles):
    """``O'`` is ``O`` turned by the follow-up's ``theta_deg`` about the sensor (see
    :class:`MovedObstacles` for what is compared and the tolerances)."""

    moved = "turned"

    def _theta(self, context: CheckContext) -> float:
        degrees = self._param(
            context, "theta_deg", "rotation", "rotation_equivariance() or RotateAboutSensor"
        )
        return math.radians(degrees)

    def move(self, box: Box, context: CheckContext) -> Box:
        return box.rotated(self._theta(context))

    def move_details(self, context: CheckContext) -> dict[str, Any]:
        self._theta(context)
        return {"theta_deg": context.params["theta_deg"]}


class MirroredObstacles(MovedObstacles):
    """``O'`` is ``O`` reflected in the sensor's x axis (see :class:`MovedObstacles`)."""

    moved = "mirrored"

    def move(self, box: Box, context: CheckContext) -> Box:
        return box.mirrored()


class ShiftedObstacles(MovedObstacles):
    """``O'`` is ``O`` shifted by the follow-up's ``shift_x_m`` along x and ``shift_y_m``
    (default 0) along y (see :class:`MovedObstacles`)."""

    moved = "shifted"

    def _dx(self, context: CheckContext) -> float:
        return self._param(
            context, "shift_x_m", "shift", "translation_equivariance(), ShiftAlongX or ShiftScene"
        )

    def _dy(self, context: CheckContext) -> float:
        if "shift_y_m" not in context.params:
            return 0.0
        return self._param(context, "shift_y_m", "shift", "ShiftScene")

    def move(self, box: Box, context: CheckContext) -> Box:
        return box.translated(self._dx(context), self._dy(context))

    def move_details(self, context: CheckContext) -> dict[str, Any]:
        return {"shift_x_m": self._dx(context), "shift_y_m": self._dy(context)}


class PosedObstacles(MovedObstacles):
    """``O'`` keeps ``O``'s road users where the sensor's new pose puts them: the
    follow-up's ``pitch_deg``, ``roll_deg`` and ``height_m``
    (:class:`~pytest_metamorphic.lidar.model.pose.SensorPose`; see
    :class:`MovedObstacles` for what is compared)."""

    moved = "seen from the posed sensor"

    def _pose(self, context: CheckContext) -> SensorPose:
        values = {
            key: self._param(context, key, "sensor pose", "sensor_pose() or SensorPose")
            for key in ("pitch_deg", "roll_deg", "height_m")
        }
        return SensorPose(**values)

    def move(self, box: Box, context: CheckContext) -> Box:
        return self._pose(context).move_box(box)

    def move_details(self, context: CheckContext) -> dict[str, Any]:
        return {"pose": self._pose(context).describe()}


class TerrainObstacles(MovedObstacles):
    """``O'`` keeps ``O``'s road users where they stood, each raised or lowered with the
    road under it: the follow-up's ``grade_percent``, ``grade_start_m``,
    ``grade_curve_m``, ``camber_percent`` and ``crown_y_m``
    (:class:`~pytest_metamorphic.lidar.model.terrain.Terrain`; see
    :class:`MovedObstacles` for what is compared)."""

    moved = "on the road's new shape"

    @property
    def note(self) -> str:
        return (
            " (the follow-up is the same scene rendered again on the new road: the same "
            "objects, beams and noise)"
        )

    def _terrain(self, context: CheckContext) -> Terrain:
        values = {
            key: self._param(context, key, "road shape", "road_terrain() or Terrain.params()")
            for key in (
                "grade_percent",
                "grade_start_m",
                "grade_curve_m",
                "camber_percent",
                "crown_y_m",
            )
        }
        return Terrain(
            values["grade_percent"], values["grade_start_m"], values["grade_curve_m"],
            values["camber_percent"], values["crown_y_m"],
        )  # fmt: skip

    def move(self, box: Box, context: CheckContext) -> Box:
        rise = float(self._terrain(context).height(box.center[0], box.center[1]))
        return box.translated(0.0, 0.0, rise)

    def _compatible(self, a: Box, b: Box) -> tuple[float, bool]:
        # Every object is cast anew, as a moved one is: a heading is compared only for
        # footprints at least 2.2 m long and 1.5 times as long as wide, as relocation
        # does (a cyclist of 98 returns turned its box by 32 degrees on a 0.3 % camber).
        distance = a.center_distance(b)
        if (self.same_label and a.label != b.label) or distance > self.center_tolerance:
            return distance, False
        for axis in (0, 1):
            if abs(a.size[axis] - b.size[axis]) > self.size_tolerance:
                return distance, False
        if not all(max(x.size[:2]) >= 2.2 and max(x.size[:2]) >= 1.5 * min(x.size[:2])
                   for x in (a, b)):  # fmt: skip
            return distance, True
        return distance, abs(math.remainder(a.yaw - b.yaw, math.pi)) <= self.yaw_tolerance

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        """As :class:`MovedObstacles`, and no *phantom*: a follow-up obstacle the scope
        judges, of >= 30 returns, more than 1 m from every object of the scene
        (``params["scene_objects"]``: road users and background, as boxes) and from every
        source obstacle. Nothing but road stands there: the road became an obstacle (a
        ground model that cannot follow the slope; a phantom ahead brakes the car)."""
        verdict = super().check(source_output, followup_output, context)
        objects = context.params.get("scene_objects")
        if not verdict.holds or objects is None:
            return verdict
        near = [*as_boxes(objects, "scene_objects"), *as_boxes(source_output, "source")]
        found = as_boxes(followup_output, "follow-up")
        judged = self.scope.judged(found, context.followup_input)
        phantoms = [
            box for box, keep in zip(found, judged, strict=True)
            if keep and (box.points or 0) >= _PHANTOM_POINTS
            and all(box_gap(box, other) > _PHANTOM_GAP for other in near)
        ]  # fmt: skip
        details = {**verdict.details, "phantoms": [box.describe() for box in phantoms]}
        if not phantoms:
            return Verdict(True, self.name, verdict.explanation, details)
        listed = "; ".join(box.describe() for box in phantoms[:5])
        return Verdict(
            False,
            self.name,
            f"the road became an obstacle {self.moved}: {listed} (nothing of the scene "
            f"within {_PHANTOM_GAP:g} m){self.note}",
            details,
        )

    def move_details(self, context: CheckContext) -> dict[str, Any]:
        return {"terrain": self._terrain(context).describe()}


_PHANTOM_POINTS = 30  # returns a phantom obstacle needs to count
_PHANTOM_GAP = 1.0  # metres from every object of the scene


_CHECKS: dict[str, type[MovedObstacles]] = {
    "rotation": RotatedObstacles,
    "mirror": MirroredObstacles,
    "translation": ShiftedObstacles,
}


def moved_obstacles(
    symmetry: Literal["rotation", "mirror", "translation"],
    *,
    quarter_turns: bool = True,
    center_tolerance: float | None = None,
    size_tolerance: float | None = None,
    yaw_tolerance: float | None = None,
    min_points: int | None = None,
    boundary_margin: float | None = None,
    same_label: bool | None = None,
    exclusive: bool = True,
    scope: ScopeLike = "roi",
) -> MovedObstacles:
    """The check for ``symmetry``, with :data:`TURN_TOLERANCES` filling what is not given:
    a quarter turn's (labels compared), or with ``quarter_turns=False`` (rotations by
    other angles) the loose ones (labels not compared); ``same_label`` overrides."""
    if symmetry not in _CHECKS:
        raise InvalidArgument(f"symmetry={symmetry!r} must be one of {sorted(_CHECKS)}")
    defaults = TURN_TOLERANCES["quarter_turns" if quarter_turns else "any"]
    given = (center_tolerance, size_tolerance, yaw_tolerance, min_points, boundary_margin)
    values = [d if g is None else g for g, d in zip(given, defaults, strict=True)]
    return _CHECKS[symmetry](
        center_tolerance=values[0],
        size_tolerance=values[1],
        yaw_tolerance=values[2],
        min_points=values[3],  # type: ignore[arg-type]
        boundary_margin=values[4],
        same_label=quarter_turns if same_label is None else same_label,
        exclusive=exclusive,
        scope=scope,
    )
