"""Which obstacles a LiDAR relation judges: the ROI scope, and the scoped obstacle relations.

Zhou & Sun's MR1 is about obstacles *on the road*: noise off the road must not make the
car lose what is on it. Apollo (and :class:`~.perception.ReferencePerception`) drop every
point outside the HD-map ROI first, so they report nothing else. Most detectors do not:
learned ones (PointPillars, CenterPoint) and clustering stacks report obstacles over the
whole sweep, and noise outside the ROI legitimately changes the obstacles *outside* it
(a noise point joins a pedestrian 24 m behind the car). Judging those is a false alarm.

An :class:`ObstacleScope` says which obstacles are judged:

* ``"roi"`` (the default): an obstacle is judged when its bird's-eye footprint lies
  inside the ROI's exact polygons: at least ``min_overlap`` of it (default 1.0, all of
  it), measured on an 8 x 8 grid of sample points over the footprint (steps of 1/64).
  **Why the footprint, not the centre**: a box's centre can sit just inside the ROI
  while most of the object is off the road. **Straddling obstacles** (partly inside) are
  *boundary* obstacles, not judged: a detector that sees the whole sweep builds them
  from points on both sides, so off-road points legitimately join or leave them (a
  parked car on the kerb absorbs a noise point beside it). Their changes are counted
  with the other unjudged ones. A judged obstacle, wholly inside, that merges with noise
  just outside the ROI has been changed by off-road noise, which is exactly what MR1
  exists to catch: that is reported as a violation, with the obstacle's distance to the
  ROI's edge. Such cases are real but rare, and only at the edge: the whole-scene variant
  of the reference pipeline changed one judged obstacle, whose footprint came within 7 cm
  of the edge, in 120 KITTI follow-ups of 1000 noise points (off-road points beside it,
  whose ground the noise moved, joined its cluster). Pieces of a boundary obstacle that
  end up wholly inside in the follow-up (its off-road part removed) are boundary changes
  too, not new obstacles.
  ``min_overlap=0.5`` also judges obstacles mostly inside: right for ROI-first stacks,
  whose boxes of edge objects are cut at the ROI and overhang it by centimetres.
* ``"all"``: every obstacle is judged (for stacks that filter by ROI first, where any
  change is a fault, and the behaviour before scopes existed).

Changes to obstacles outside the judged set are counted (``unjudged_changes`` in a
verdict's details) and shown as information: in the plugin's summary, campaign tables
and reports, artifacts and bird's-eye pictures, never as violations.

The relations here are the output halves of :mod:`pytest_metamorphic.relations.lidar`:
:func:`obstacles_kept` (MR1, O ⊆ O' over judged source obstacles),
:func:`judged_count` (the paper's cardinality check over judged obstacles) and
:func:`judged_equal` (O == O' over judged obstacles, as multisets).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher, matched_pairs
from pytest_metamorphic.core.relations import (
    _COMPARISONS,
    CheckContext,
    Relation,
    Verdict,
    cardinality,
    equal,
    subset,
)
from pytest_metamorphic.lidar.model.obstacles import (
    Box,
    IoUMatcher,
    as_boxes,
    bev_iou,
    box_support,
    unmatched_twins,
)

__all__ = [
    "DEFAULT_SCOPE",
    "ObstacleScope",
    "ScopeLike",
    "as_scope",
    "footprint_overlap",
    "judged_count",
    "judged_equal",
    "obstacles_kept",
]

_SAMPLES = 8  # per side of the footprint grid: fractions in steps of 1/64
_SHOWN = 10


def footprint_overlap(boxes: Sequence[Box], roi: Any) -> NDArray[np.float64]:
    """(n,) float64: the fraction of each box's bird's-eye footprint inside the ROI.

    Measured on an 8 x 8 grid of sub-cell centres over the footprint, against the ROI's
    exact polygons (``roi.contains(xy, method="exact")``).

    Parameters
    ----------
    boxes : sequence of Box
    roi : ROI
        Anything with ``contains(xy, method=...) -> (n,) bool``.
    """
    boxes = as_boxes(boxes, "boxes")
    if not boxes:
        return np.empty(0)
    steps = (np.arange(_SAMPLES) + 0.5) / _SAMPLES - 0.5
    u, v = (grid.reshape(-1) for grid in np.meshgrid(steps, steps))
    centres = np.array([box.center[:2] for box in boxes])
    lengths = np.array([box.size[0] for box in boxes])[:, None]
    widths = np.array([box.size[1] for box in boxes])[:, None]
    yaw = np.array([box.yaw for box in boxes])[:, None]
    along, across = u[None, :] * lengths, v[None, :] * widths
    x = centres[:, :1] + along * np.cos(yaw) - across * np.sin(yaw)
    y = centres[:, 1:] + along * np.sin(yaw) + across * np.cos(yaw)
    xy = np.stack([x.reshape(-1), y.reshape(-1)], axis=1)
    inside = np.asarray(roi.contains(xy, method="exact"), dtype=bool)
    return inside.reshape(len(boxes), -1).mean(axis=1)


@dataclass(frozen=True)
class ObstacleScope:
    """Which obstacles of an output a relation judges (see the module docstring).

    Parameters
    ----------
    region : {"roi", "all"}
        ``"roi"``: obstacles inside the input frame's ROI; ``"all"``: every one.
    min_overlap : float
        In (0, 1]: the share of an obstacle's footprint that must lie inside the ROI for
        it to be judged (``region="roi"`` only).
    """

    region: Literal["roi", "all"] = "roi"
    min_overlap: float = 1.0

    def __post_init__(self) -> None:
        if self.region not in ("roi", "all"):
            raise InvalidArgument(f"scope region={self.region!r} must be 'roi' or 'all'")
        value = self.min_overlap
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"min_overlap={value!r} must be a number in (0, 1]")
        if not 0 < value <= 1:
            raise InvalidArgument(f"min_overlap={value!r} must be in (0, 1]")
        object.__setattr__(self, "min_overlap", float(value))

    @property
    def everything(self) -> bool:
        return self.region == "all"

    def describe(self) -> str:
        """Short name for relation names and reports, e.g. ``wholly in ROI``."""
        if self.everything:
            return "all obstacles"
        if self.min_overlap == 1.0:
            return "wholly in ROI"
        return f"in ROI (>= {self.min_overlap:.0%} footprint)"

    def roi(self, frame: Any) -> Any:
        """The ROI the scope reads from an input frame (None for ``"all"``)."""
        if self.everything:
            return None
        roi = getattr(frame, "roi", None)
        if roi is None or not callable(getattr(roi, "contains", None)):
            raise InvalidArgument(
                f"the ROI scope needs inputs with an ROI (frame.roi), got {frame!r}; pass "
                "scope='all' to judge every obstacle"
            )
        return roi

    def judged(self, boxes: Sequence[Box], frame: Any) -> NDArray[np.bool_]:
        """(n,) bool: which of ``boxes`` (an output on ``frame``) this scope judges."""
        boxes = as_boxes(boxes, "output")
        if self.everything:
            return np.ones(len(boxes), dtype=bool)
        return footprint_overlap(boxes, self.roi(frame)) >= self.min_overlap

    def select(self, boxes: Sequence[Box], frame: Any) -> list[Box]:
        """The judged obstacles of ``boxes``, in their order."""
        boxes = as_boxes(boxes, "output")
        return [box for box, keep in zip(boxes, self.judged(boxes, frame), strict=True) if keep]

    def where(self, box: Box, frame: Any) -> str:
        """Where ``box`` lies relative to the ROI's edge, for messages."""
        roi = None if self.everything else getattr(frame, "roi", None)
        if roi is None or not callable(getattr(roi, "boundary_distance", None)):
            return ""
        xy = [box.center[:2]]
        distance = float(roi.boundary_distance(xy)[0])
        side = "inside" if bool(roi.contains(xy, method="exact")[0]) else "outside"
        footprint = float(roi.boundary_distance(box.corners_bev()).min())
        return f"{distance:.1f} m {side} the ROI's edge, footprint {footprint:.2f} m from it"


DEFAULT_SCOPE = ObstacleScope()
ScopeLike = Literal["roi", "all"] | ObstacleScope


def as_scope(scope: Any) -> ObstacleScope:
    """``"roi"``, ``"all"`` or an :class:`ObstacleScope` as a scope; anything else raises."""
    if isinstance(scope, ObstacleScope):
        return scope
    if scope in ("roi", "all"):
        return ObstacleScope(region=scope)
    raise InvalidArgument(f"scope={scope!r} must be 'roi', 'all' or an ObstacleScope")


def _pieces_of(boxes: list[Box], boundary: list[Box]) -> NDArray[np.bool_]:
    """(len(boxes),) bool: which boxes overlap one of the ``boundary`` (unjudged) boxes."""
    if not boxes or not boundary:
        return np.zeros(len(boxes), dtype=bool)
    return np.asarray((bev_iou(boxes, boundary) > 0).any(axis=1), dtype=np.bool_)


def _is_box_list(value: Any) -> bool:
    return isinstance(value, (list, tuple)) and all(isinstance(item, Box) for item in value)


_EXACT = equal()


class _Scoped(Relation):
    """Splitting outputs into judged and unjudged obstacles; information on the unjudged."""

    scope: ObstacleScope

    def _split(
        self, source_output: Any, followup_output: Any, context: CheckContext
    ) -> tuple[list[Box], list[Box], NDArray[np.bool_], NDArray[np.bool_]]:
        source = as_boxes(source_output, "source output")
        followup = as_boxes(followup_output, "follow-up output")
        return (
            source,
            followup,
            self.scope.judged(source, context.source_input),
            self.scope.judged(followup, context.followup_input),
        )

    def _unjudged(
        self,
        source: list[Box],
        followup: list[Box],
        source_judged: NDArray[np.bool_],
        followup_judged: NDArray[np.bool_],
    ) -> dict[str, Any]:
        """Unjudged obstacles that changed (no identical twin on the other side): information."""
        outside = [box for box, judged in zip(source, source_judged, strict=True) if not judged]
        outside2 = [
            box for box, judged in zip(followup, followup_judged, strict=True) if not judged
        ]
        gone, new = unmatched_twins(outside, outside2)
        return {
            "scope": self.scope.describe(),
            # What the check tested: the judged source obstacles (a subset or count of an
            # empty set holds vacuously); equalities add the follow-up's (see _Equal).
            "judged": int(source_judged.sum()),
            "judged_source": int(source_judged.sum()),
            "judged_followup": int(followup_judged.sum()),
            "unjudged_changes": len(gone) + len(new),
            "unjudged_source": [int(i) for i in np.flatnonzero(~source_judged)],
            "unjudged_followup": [int(j) for j in np.flatnonzero(~followup_judged)],
            "unjudged_lost": [outside[i].describe() for i in gone[:_SHOWN]],
            "unjudged_gained": [outside2[j].describe() for j in new[:_SHOWN]],
        }

    def _note(self, details: dict[str, Any]) -> str:
        count = details["unjudged_changes"]
        if not count:
            return ""
        return (
            f" ({count} obstacle(s) outside the judged region ({self.scope.describe()}) "
            "changed: shown as information, not judged)"
        )


class _Kept(_Scoped):
    """Every judged source obstacle has its own match in the follow-up (one-to-one)."""

    def __init__(self, matcher: Matcher, scope: ObstacleScope) -> None:
        self.matcher = matcher
        self.scope = scope
        self.name = f"subset[{matcher.name}; {scope.describe()}]"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source, followup, judged, followup_judged = self._split(
            source_output, followup_output, context
        )
        rows = np.flatnonzero(judged)
        pairs = matched_pairs(self.matcher, [source[i] for i in rows], followup)
        matched = {int(rows[r]) for r, _ in pairs}
        unmatched = [int(i) for i in rows if int(i) not in matched]
        details: dict[str, Any] = {
            "matched": [[int(rows[r]), c] for r, c in pairs],
            "unmatched": unmatched,
            "source_size": len(source),
            "followup_size": len(followup),
            **self._unjudged(source, followup, judged, followup_judged),
        }
        if not unmatched:
            return Verdict(True, self.name, self._note(details).strip(), details)
        lines = []
        for i in unmatched[:_SHOWN]:
            where = self.scope.where(source[i], context.source_input)
            lines.append(
                f"element #{i} ({source[i].describe()}) of the source has no match in "
                f"follow-up {context.index}{f' ({where})' if where else ''}"
            )
        if len(unmatched) > _SHOWN:
            lines.append(f"... and {len(unmatched) - _SHOWN} more")
        details["unmatched_where"] = [
            self.scope.where(source[i], context.source_input) for i in unmatched
        ]
        return Verdict(False, self.name, "; ".join(lines) + self._note(details), details)


class _Count(_Scoped):
    """Compares the numbers of judged obstacles: ``|O| <op> |O'|``."""

    def __init__(self, op: str, scope: ObstacleScope) -> None:
        self.op = op
        self.scope = scope
        self.name = f"cardinality(|O| {op} |O'|; {scope.describe()})"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source, followup, judged, followup_judged = self._split(
            source_output, followup_output, context
        )
        details = self._unjudged(source, followup, judged, followup_judged)
        n, m = details["judged_source"], details["judged_followup"]
        details.update(source_size=n, followup_size=m)
        if _COMPARISONS[self.op](n, m):
            return Verdict(True, self.name, self._note(details).strip(), details)
        return Verdict(
            False,
            self.name,
            f"the source has {n} judged obstacle(s), follow-up {context.index} has {m}; "
            f"expected |O| {self.op} |O'|" + self._note(details),
            details,
        )


class _Equal(_Scoped):
    """Judged obstacles are identical on both sides (multisets: order does not matter).

    Outputs that are not lists of Box (a point count, a mask) are compared exactly.
    """

    def __init__(self, scope: ObstacleScope) -> None:
        self.scope = scope
        self.name = f"equal({scope.describe()})"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        if not (_is_box_list(source_output) and _is_box_list(followup_output)):
            # Not obstacles (a point count, a mask): no scope applies, compare exactly.
            return _EXACT.check(source_output, followup_output, context)
        source, followup, judged, followup_judged = self._split(
            source_output, followup_output, context
        )
        details: dict[str, Any] = self._unjudged(source, followup, judged, followup_judged)
        details["judged"] += int(followup_judged.sum())
        # A judged obstacle needs an identical twin among *all* obstacles on the other side.
        gone, _ = unmatched_twins([source[i] for i in np.flatnonzero(judged)], followup)
        new, _ = unmatched_twins([followup[j] for j in np.flatnonzero(followup_judged)], source)
        lost = [int(np.flatnonzero(judged)[i]) for i in gone]
        gained = [int(np.flatnonzero(followup_judged)[j]) for j in new]
        pieces = _pieces_of(
            [followup[j] for j in gained], [source[i] for i in np.flatnonzero(~judged)]
        )
        if pieces.any():
            details["unjudged_changes"] += int(pieces.sum())
            details["boundary_pieces"] = [followup[j].describe() for j in np.array(gained)[pieces]]
            gained = [j for j, piece in zip(gained, pieces, strict=True) if not piece]
        details.update(changed_source=lost, changed_followup=gained)
        if not lost and not gained:
            return Verdict(True, self.name, self._note(details).strip(), details)
        lines = [
            f"source {source[i].describe()} has no identical obstacle in follow-up {context.index}"
            for i in lost[:_SHOWN]
        ]
        lines += [
            f"follow-up {context.index}'s {followup[j].describe()} has no identical obstacle "
            "in the source"
            for j in gained[:_SHOWN]
        ]
        return Verdict(False, self.name, "; ".join(lines) + self._note(details), details)


class _Same(_Scoped):
    """Judged obstacles are the same on both sides up to ``matcher``: each judged obstacle
    of either output has its own match (one-to-one) among all obstacles of the other.
    Obstacles a detector says fewer than ``min_points`` returns support are not judged."""

    def __init__(self, matcher: Matcher, scope: ObstacleScope, min_points: int = 0) -> None:
        self.matcher = matcher
        self.scope = scope
        self.min_points = min_points
        support = f", >= {min_points} points" if min_points else ""
        self.name = f"same[{matcher.name}; {scope.describe()}{support}]"

    def _split(
        self, source_output: Any, followup_output: Any, context: CheckContext
    ) -> tuple[list[Box], list[Box], NDArray[np.bool_], NDArray[np.bool_]]:
        source, followup, judged, followup_judged = super()._split(
            source_output, followup_output, context
        )
        if self.min_points:
            judged &= _supported(source, self.min_points, context.source_input)
            followup_judged &= _supported(followup, self.min_points, context.followup_input)
        return source, followup, judged, followup_judged

    def _note(self, details: dict[str, Any]) -> str:
        count = details["unjudged_changes"]
        if not count or not self.min_points:
            return super()._note(details)
        return (
            f" ({count} obstacle(s) outside the judged region ({self.scope.describe()}) or "
            f"seen by fewer than {self.min_points} returns changed: shown as information, "
            "not judged)"
        )

    def _unmatched(
        self, boxes: list[Box], judged: NDArray[np.bool_], other: list[Box]
    ) -> list[int]:
        rows = np.flatnonzero(judged)
        matched = {
            int(rows[r]) for r, _ in matched_pairs(self.matcher, [boxes[i] for i in rows], other)
        }
        return [int(i) for i in rows if int(i) not in matched]

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source, followup, judged, followup_judged = self._split(
            source_output, followup_output, context
        )
        details: dict[str, Any] = self._unjudged(source, followup, judged, followup_judged)
        details["judged"] += int(followup_judged.sum())
        lost = self._unmatched(source, judged, followup)
        gained = self._unmatched(followup, followup_judged, source)
        details.update(changed_source=lost, changed_followup=gained)
        if not lost and not gained:
            return Verdict(True, self.name, self._note(details).strip(), details)
        lines = [
            f"source {source[i].describe()} has no match in follow-up {context.index}"
            for i in lost[:_SHOWN]
        ]
        lines += [
            f"follow-up {context.index}'s {followup[j].describe()} has no match in the source"
            for j in gained[:_SHOWN]
        ]
        return Verdict(False, self.name, "; ".join(lines) + self._note(details), details)


def _supported(boxes: list[Box], min_points: int, frame: Any) -> NDArray[np.bool_]:
    """(n,) bool: supported by at least ``min_points`` returns (``Box.points``, or counted
    in the frame's cloud for boxes that do not say: a converter's or a process's)."""
    cloud = getattr(frame, "cloud", None)
    return box_support(boxes, None if cloud is None else cloud.xyz) >= min_points


def obstacles_kept(*, matcher: Matcher | None = None, scope: ScopeLike = "roi") -> Relation:
    """MR1's output relation: every judged source obstacle has its own match in ``O'``.

    Parameters
    ----------
    matcher : Matcher, optional
        Default: same label and bird's-eye IoU >= 0.5. Judged source obstacles are matched
        one-to-one against *all* follow-up obstacles (one that moved a little across the
        ROI's edge still counts).
    scope : "roi", "all" or ObstacleScope
        ``"all"`` is the plain :func:`~pytest_metamorphic.core.relations.subset`.
    """
    chosen = as_scope(scope)
    matcher = matcher or IoUMatcher(0.5, same_label=True)
    if chosen.everything:
        return subset(matcher=matcher)
    return _Kept(matcher, chosen)


def judged_count(op: str = "<=", *, scope: ScopeLike = "roi") -> Relation:
    """The paper's check, ``|O| <op> |O'|``, counting judged obstacles on both sides."""
    if op not in _COMPARISONS:
        raise InvalidArgument(f"op={op!r} must be one of {sorted(_COMPARISONS)}")
    chosen = as_scope(scope)
    return cardinality(op) if chosen.everything else _Count(op, chosen)


def judged_equal(
    *, scope: ScopeLike = "roi", matcher: Matcher | None = None, min_points: int = 0
) -> Relation:
    """``O == O'`` over judged obstacles: each needs an identical one on the other side.

    Obstacles are compared as multisets (the order a detector lists them in is not
    part of its answer: DBSCAN numbers clusters in the order it meets their points) and
    identical means equal up to floating-point rounding
    (:data:`~pytest_metamorphic.lidar.model.obstacles.matching.ROUNDING`), for every scope,
    ``"all"`` included. Outputs that are not lists of boxes are compared exactly. With a
    ``matcher`` (a detector whose outputs jitter, e.g. a neural network) "identical"
    becomes "matched": every judged obstacle of either side needs its own match on the
    other, one to one; then obstacles whose ``points`` (the returns the detector says
    support them) are fewer than ``min_points`` are not judged either: a network's
    detection of an object seen by 2 or 3 returns flips when one of them is repeated.
    """
    chosen = as_scope(scope)
    if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 0:
        raise InvalidArgument(f"min_points={min_points!r} must be an int >= 0")
    if matcher is not None:
        return _Same(matcher, chosen, min_points)
    if min_points:
        raise InvalidArgument("min_points needs a matcher (exact comparison judges every box)")
    return _Equal(chosen)
