"""What a violation's picture shows: the obstacles it blames, what the follow-up added,
the follow-up's boxes moved back into the source's frame, and a title from the verdict."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.perturbation import as_reducible
from pytest_metamorphic.reports.inputs import is_box

__all__ = ["draw_violation"]


def draw_violation(
    record: Any, folder: Path, source_spec: Mapping[str, Any]
) -> tuple[str | None, str]:
    """Draw a LiDAR violation's bird's-eye picture into ``folder`` (``birdseye.png``);
    ``(file name or None, a note on why there is none)``."""
    followup = record.minimal_followup
    kind = getattr(record.source_output, "kind", None)
    if kind in ("labels", "clusters") and source_spec["kind"] == "frame":
        return _draw_points(record, folder, kind)
    source_boxes = _boxes_or_none(record.source_output)
    followup_boxes = _boxes_or_none(record.minimal_output)
    if followup_boxes is None or source_boxes is None or source_spec["kind"] != "frame":
        return None, ""
    followup_boxes, moved_back = _in_source_frame(followup_boxes, followup.params)
    try:
        from pytest_metamorphic.reports.birdseye import draw_birdseye
    except ImportError as error:  # matplotlib is an optional extra
        return None, f"no picture: {error}"
    draw_birdseye(
        folder / "birdseye.png",
        source=record.source,
        source_boxes=source_boxes,
        followup_boxes=followup_boxes,
        hidden=_hidden(record),
        unjudged=_unjudged(record),
        scope=str(record.minimal_verdict.details.get("scope", "")),
        injected=_added_points(record.followup.params),
        minimal=_injected_points(followup.params),
        title=_picture_title(record) + moved_back,
    )
    return "birdseye.png", ""


def _draw_points(record: Any, folder: Path, kind: str) -> tuple[str | None, str]:
    """A component's violation: returns coloured by label or cluster, changed ones marked."""
    try:
        from pytest_metamorphic.reports.point_picture import draw_point_violation
    except ImportError as error:  # matplotlib is an optional extra
        return None, f"no picture: {error}"
    details = record.minimal_verdict.details
    draw_point_violation(
        folder / "points.png",
        source=record.source,
        labels=record.source_output.labels,
        kind=kind,
        changed=details.get("changed_points", []) if isinstance(details, Mapping) else [],
        added=_added_points(record.followup.params),
        minimal=_injected_points(record.minimal_followup.params),
        title=_picture_title(record),
    )
    return "points.png", ""


def _boxes_or_none(value: Any) -> list[Any] | None:
    if isinstance(value, (list, tuple)) and all(is_box(box) for box in value):
        return list(value)
    return None


def _hidden(record: Any) -> list[Any]:
    """What the violation lost: the source obstacles the relation blames (``blamed`` in its
    details: a turned or mirrored obstacle without its match, one a fault lost), else its
    unmatched elements, else the obstacles without an identical twin."""
    details = record.minimal_verdict.details
    blamed = details.get("blamed") if isinstance(details, Mapping) else None
    if blamed is None and isinstance(details, Mapping):  # checks joined by &: their parts'
        parts = [part.get("blamed") for part in details.values() if isinstance(part, Mapping)]
        found = [index for part in parts if isinstance(part, list) for index in part]
        blamed = sorted(set(found)) if found else None
    source = record.source_output
    if isinstance(blamed, list) and isinstance(source, Sequence):
        return [source[i] for i in blamed if isinstance(i, int) and 0 <= i < len(source)]
    unmatched = details.get("unmatched") if isinstance(details, Mapping) else None
    if isinstance(unmatched, list) and record.minimal_verdict.relation.startswith("subset"):
        source = record.source_output
        return [source[i] for i in unmatched if isinstance(i, int) and i < len(source)]
    source_boxes = _boxes_or_none(record.source_output)
    followup_boxes = _boxes_or_none(record.minimal_output)
    if source_boxes is not None and followup_boxes is not None:
        from pytest_metamorphic.lidar.followups.minimize import lost_obstacles

        return [source_boxes[i] for i in lost_obstacles(source_boxes, followup_boxes)]
    return []


def _unjudged(record: Any) -> list[Any]:
    """Source obstacles outside the relation's scope (drawn as not judged)."""
    details = record.minimal_verdict.details
    indices = details.get("unjudged_source") if isinstance(details, Mapping) else None
    source = record.source_output
    if not isinstance(indices, list):
        return []
    return [source[i] for i in indices if isinstance(i, int) and i < len(source)]


def _injected_points(value: Any) -> Any:
    """(n, 4) points of a point perturbation in ``params``, or None."""
    for item in value.values() if isinstance(value, Mapping) else ():
        points = getattr(as_reducible(item), "points", None)
        if points is not None:
            return points
    return None


def _added_points(value: Any) -> Any:
    """The points a follow-up added, to draw: a perturbation's, or an edit's
    ``injected_points`` (a moved object's returns where it went), or None."""
    points = _injected_points(value)
    for item in value.values() if points is None and isinstance(value, Mapping) else ():
        points = getattr(item, "injected_points", None)
        if points is not None:
            break
    return points


def _in_source_frame(boxes: list[Any], params: Mapping[str, Any]) -> tuple[list[Any], str]:
    """A rigid-motion follow-up's boxes moved back where the source's would be (the picture
    draws both over the source's cloud), and a title line saying so; other boxes as they
    are. Without this, every source obstacle of a turned sweep looked lost."""
    movable = all(hasattr(box, name) for box in boxes for name in ("rotated", "mirrored"))
    if not isinstance(params, Mapping) or not movable:  # a user's own box type: as it is
        return boxes, ""
    if "theta_deg" in params:
        degrees = float(params["theta_deg"])
        turn = math.radians(-degrees)
        return [box.rotated(turn) for box in boxes], (
            f"\nfollow-up obstacles turned back by {degrees:g} degrees"
        )
    if "mirrored" in params:
        return [box.mirrored() for box in boxes], "\nfollow-up obstacles mirrored back"
    if "shift_x_m" in params:
        dx, dy = float(params["shift_x_m"]), float(params.get("shift_y_m", 0.0))
        back = f"{dx:g} m" if not dy else f"({dx:g}, {dy:g}) m"
        return [box.translated(-dx, -dy) for box in boxes], (
            f"\nfollow-up obstacles shifted back by {back}"
        )
    return boxes, ""


_TITLE_WIDTH = 110
_TITLE_LINES = 2


def _picture_title(record: Any) -> str:
    reduction = record.reduction
    # Two lines of the verdict, cut at a word with a mark: a hard cut at 110 characters
    # left titles like "the inserted car at (-2." that named nothing.
    first_line = (record.minimal_verdict.explanation or "").split("\n", 1)[0]
    wrapped = textwrap.wrap(first_line, _TITLE_WIDTH)
    if len(wrapped) > _TITLE_LINES:
        wrapped = [
            *wrapped[: _TITLE_LINES - 1],
            textwrap.shorten(
                " ".join(wrapped[_TITLE_LINES - 1 :]), _TITLE_WIDTH, placeholder=" ..."
            ),
        ]
    lines = [f"{record.relation}", *wrapped]
    if reduction is not None:
        proof = "proven 1-minimal" if reduction.proven_minimal else "NOT proven minimal"
        lines.append(
            f"{reduction.size} of {reduction.original_size} {reduction.key} elements, {proof}, "
            f"{reduction.calls} SUT calls"
        )
    return "\n".join(lines)
