"""Whether the inserted object is found."""

from __future__ import annotations

from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.followups.faults import _fraction
from pytest_metamorphic.lidar.followups.insert.insertion import InsertObject
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.model.obstacles import as_boxes, share_inside

__all__ = ["InsertedDetected"]


class InsertedDetected(Relation):
    """The inserted object is detected: when it has at least ``min_points`` returns that
    span at least ``min_height_share`` of the height all its cast returns spanned, and
    ``scope`` judges it, at least ``min_detected`` of its returns lie in follow-up
    obstacles (boxes grown by 10 cm, any label: a car seen from afar may come out as an
    unknown object, and the check is about not missing it).

    The height condition matters when a violation is reduced to fewer returns: the 30
    lowest returns of a car 46 m away (a slice 0.3 m high, below any detector's minimum
    obstacle height) are not "a car of 30 returns", and a reduction may not stop there
    (the same rule as the fault relations' well-covered obstacles).
    """

    def __init__(
        self,
        *,
        min_points: int = 30,
        min_detected: float = 0.5,
        min_height_share: float = 0.8,
        scope: ScopeLike = "roi",
    ) -> None:
        if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 1:
            raise InvalidArgument(f"min_points={min_points!r} must be a positive int")
        self.min_points = min_points
        self.min_detected = _fraction(min_detected, "min_detected")
        self.min_height_share = _fraction(min_height_share, "min_height_share")
        self.scope: ObstacleScope = as_scope(scope)
        self.name = (
            f"inserted object detected (>= {min_points} returns: >= {min_detected:.0%} of "
            f"them in obstacles; {self.scope.describe()})"
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
        z = insertion.points[:, 2]
        span = float(z.max() - z.min())
        if insertion.span and span < self.min_height_share * insertion.span:
            details["judged"] = 0
            return Verdict(
                True,
                self.name,
                f"its returns span {span:.2f} m of the {insertion.span:.2f} m all its returns "
                "spanned: a slice of the object, not judged",
                details,
            )
        share = share_inside(insertion.points[:, :3], as_boxes(followup_output, "follow-up"))
        details.update(judged=1, detected_share=round(share, 3))
        if share >= self.min_detected:
            return Verdict(True, self.name, details=details)
        template = insertion.template
        origin = "" if template is None else f", a labelled {template.label} from {template.origin}"
        return Verdict(
            False,
            self.name,
            f"the inserted {insertion.box.describe()} ({returns} returns{origin}) is not "
            f"detected: {share:.0%} of its returns lie in follow-up obstacles",
            details,
        )
