"""Whether the inserted object is found."""

from __future__ import annotations

from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.followups.faults import _fraction
from pytest_metamorphic.lidar.followups.insert.insertion import InsertObject
from pytest_metamorphic.lidar.judging.found import (
    ClassRule,
    accepted_labels,
    check_class_rule,
    found_as,
)
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.judging.well_seen import WELL_SEEN, WellSeen
from pytest_metamorphic.lidar.model.obstacles import as_boxes

__all__ = ["MIN_SPAN", "InsertedDetected", "PlacedObjectCheck"]

MIN_SPAN = 0.35
"""Metres the returns of a placed object must span to be judged: a thinner slice is below
a detector's minimum obstacle height (the reference's and the examples' keep returns 0.3 m
above their ground). Measured: a VLP-16 1.73 m up sees the top 11 cm of a 1.15 m child
2.75 m ahead of it (52 returns), nothing of the rest."""


class PlacedObjectCheck(Relation):
    """What the checks of an object put into a sweep share: how many of its returns make
    it judged (``min_points``, spanning ``min_height_share`` of the height all its cast
    returns spanned and at least :data:`MIN_SPAN`), how many must be found
    (``min_detected``), as which classes (``classes``), and which objects are judged
    (``scope``)."""

    def __init__(
        self,
        *,
        min_points: int = 30,
        min_detected: float = 0.5,
        min_height_share: float = 0.8,
        classes: ClassRule = "own_or_unknown",
        scope: ScopeLike = "roi",
    ) -> None:
        if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 1:
            raise InvalidArgument(f"min_points={min_points!r} must be a positive int")
        self.min_points = min_points
        self.min_detected = _fraction(min_detected, "min_detected")
        self.min_height_share = _fraction(min_height_share, "min_height_share")
        self.classes = check_class_rule(classes)
        self.scope: ObstacleScope = as_scope(scope)

    def spans(self, insertion: InsertObject) -> tuple[float, bool]:
        """How high the placed returns reach (m), and whether that is enough of the
        object's height to judge it (a reduction may not end on a slice of it, and a
        sensor that sees only a slice of it, the top of a child's head beside the car,
        shows no detector an obstacle)."""
        z = insertion.points[:, 2]
        span = float(z.max() - z.min()) if len(z) else 0.0
        if span < MIN_SPAN:
            return span, False
        return span, not insertion.span or span >= self.min_height_share * insertion.span


class InsertedDetected(PlacedObjectCheck):
    """The inserted object is detected with its class: when it has at least
    ``min_points`` returns that span at least ``min_height_share`` of the height all its
    cast returns spanned, and ``scope`` judges it, at least ``min_detected`` of its
    returns lie in follow-up obstacles (boxes grown by 10 cm) of its class or, by default,
    ``"unknown"`` (``classes``, :data:`~pytest_metamorphic.lidar.judging.found.CLASS_RULES`:
    a car seen from afar may come out as an unknown object, which is not missing it; a
    pedestrian reported as a car is). The class is the template's: ground truth of the
    recording it was cut from.

    The height condition matters when a violation is reduced to fewer returns: the 30
    lowest returns of a car 46 m away (a slice 0.3 m high, below any detector's minimum
    obstacle height) are not "a car of 30 returns", and a reduction may not stop there
    (the same rule as the fault relations' well-covered obstacles).

    A well-seen pedestrian or cyclist (``well_seen``,
    :class:`~pytest_metamorphic.lidar.judging.well_seen.WellSeen`: hundreds of returns
    from head to foot, standing apart) found as ``"unknown"`` is a violation whatever
    ``classes`` says; ``well_seen=None`` accepts it.
    """

    def __init__(
        self,
        *,
        min_points: int = 30,
        min_detected: float = 0.5,
        min_height_share: float = 0.8,
        classes: ClassRule = "own_or_unknown",
        well_seen: WellSeen | None = WELL_SEEN,
        scope: ScopeLike = "roi",
    ) -> None:
        super().__init__(
            min_points=min_points, min_detected=min_detected, min_height_share=min_height_share,
            classes=classes, scope=scope,
        )  # fmt: skip
        if well_seen is not None and not isinstance(well_seen, WellSeen):
            raise InvalidArgument(f"well_seen={well_seen!r} must be a WellSeen or None")
        self.well_seen = well_seen
        held = {
            "own": "obstacles of its class",
            "own_or_unknown": "obstacles of its class or unknown",
            "any": "obstacles",
        }[self.classes]
        self.name = (
            f"inserted object detected (>= {min_points} returns: >= {min_detected:.0%} of "
            f"them in {held}; {self.scope.describe()})"
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        insertion = context.params.get("insert_object", ())
        if insertion is None:
            return Verdict(True, self.name, "no free place to insert an object", {"judged": 0})
        if not isinstance(insertion, InsertObject):
            raise InvalidArgument(
                f"{self.name} needs the follow-up's InsertObject in params['insert_object'] "
                "(use object_insertion() or InsertObject.params())"
            )
        returns = len(insertion)
        details: dict[str, Any] = {"inserted": insertion.box.describe(), "returns": returns}
        judged = bool(self.scope.judged([insertion.box], context.followup_input)[0])
        if returns < self.min_points or not judged:
            details["judged"] = 0
            return Verdict(True, self.name, "too few returns or not judged", details)
        span, tall = self.spans(insertion)
        if not tall:
            details["judged"] = 0
            return Verdict(True, self.name, _slice(span, insertion.span), details)
        boxes = as_boxes(followup_output, "follow-up")
        accepted = accepted_labels(insertion.box.label, self.classes)
        found = found_as(insertion.points[:, :3], boxes, accepted)
        details.update(
            judged=1,
            detected_share=round(found.share, 3),
            detected_as_share=round(found.share_as, 3),
            found_as=found.main_label(),
            classes=self.classes,
        )
        template = insertion.template
        origin = "" if template is None else f", a labelled {template.label} from {template.origin}"
        what = f"the inserted {insertion.box.describe()} ({returns} returns{origin})"
        seen = self.well_seen
        if (
            seen is not None
            and seen.applies(insertion.box, insertion.points)
            and insertion.box.label in _reported(boxes, source_output)
        ):
            details["well_seen"] = True
            if seen.demoted(insertion.box, insertion.points[:, :3], boxes):
                return Verdict(
                    False,
                    self.name,
                    f"{what} is found as an unknown obstacle although well seen "
                    f"({seen.describe()}, "
                    f"standing apart): a {insertion.box.label} demoted",
                    details,
                )
        if found.share_as >= self.min_detected:
            return Verdict(True, self.name, details=details)
        if found.share >= self.min_detected:
            held = ", ".join(f"{label} {count}" for label, count in found.labels.most_common())
            wrong = [label for label in found.labels if accepted and label not in accepted]
            return Verdict(
                False,
                self.name,
                f"{what} is found as a {wrong[0]}, not a {insertion.box.label}: "
                f"{found.share_as:.0%} of its returns lie in obstacles of its class "
                f"(returns held by: {held})",
                details,
            )
        return Verdict(
            False,
            self.name,
            f"{what} is not detected: {found.share:.0%} of its returns lie in follow-up obstacles",
            details,
        )


def _slice(span: float, whole: float | None) -> str:
    """Why an object whose returns span ``span`` metres (of ``whole``) is not judged."""
    if span < MIN_SPAN:
        return (
            f"its returns span {span:.2f} m, less than {MIN_SPAN} m (below a detector's "
            "minimum obstacle height): a slice of the object, not judged"
        )
    return (
        f"its returns span {span:.2f} m of the {whole or 0:.2f} m all its returns spanned: a "
        "slice of the object, not judged"
    )


def _reported(boxes: list[Any], source_output: Any) -> set[str]:
    """The classes a detector showed it has: those of its follow-up and source obstacles."""
    return {box.label for box in boxes} | {box.label for box in as_boxes(source_output, "source")}
