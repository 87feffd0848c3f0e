"""Stage blame: which stage of a pipeline first answered differently on a violating pair.

When an end-to-end relation fails, the next question is which component did it. A
pipeline declared as stages (:class:`StagedPipeline`: a few named callables, each
``frame -> its stage's output``; the reference pipeline's are
:func:`~pytest_metamorphic.lidar.systems.perception.trace.reference_stages`) is run on the
source and on the follow-up, and :func:`blame` names the first stage whose output differs
**where the violation is**: the obstacles of the last stage that have no match on the
other side (lost, gained or changed; all of them when every one matched, as when a box
only turned), and the returns under them that both sweeps share and the follow-up did
not change (farther than ``radius`` from its new and removed returns,
:mod:`~pytest_metamorphic.lidar.judging.correspondence`; turned, mirrored or shifted back
as the follow-up's parameters say). Stages before it agreed there, so the fault entered
at that stage.

A stage's output is one of

* a labelling of the sweep's returns
  (:class:`~pytest_metamorphic.lidar.model.point_outputs.PointLabels`, or an int or bool
  array: which returns the stage passed on): it differs when more than 0.1 % of the shared
  returns (at least one) changed label, or, for a stage that must pass on only the ROI's
  returns (``within_roi=True``), when a return the follow-up added outside the ROI passed
  it; and a filter (``passes=True``) differs when it drops most of the returns the
  follow-up added where the violation is (an inserted object's);
* a partition (:class:`~pytest_metamorphic.lidar.model.point_outputs.Partition`): it differs
  when more than 0.1 % of the shared returns changed object (pair agreement,
  :func:`~pytest_metamorphic.lidar.judging.points.changed_clusters`);
* boxes (``list[Box]``): it differs when a box overlapping the violation has no match of
  bird's-eye IoU >= 0.5 on the other side (of the same label, unless the stage is
  declared ``labels=False``).

:class:`BlamedRelation` wraps a relation so that its violations name the stage
(:func:`pytest_metamorphic.relations.lidar.blame.with_stage_blame`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.cases import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import matched_pairs
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.judging.correspondence import (
    PointCorrespondence,
    align_to_source,
    box_to_source,
    corresponding_points,
)
from pytest_metamorphic.lidar.judging.points import changed_clusters
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, IoUMatcher, footprint_distances
from pytest_metamorphic.lidar.model.point_outputs import Partition, PointLabels

__all__ = ["Blame", "BlamedRelation", "Stage", "StageOutput", "StagedPipeline", "blame"]

StageKind = Literal["labels", "clusters", "boxes"]

_MIN_SHARED = 5
"""Shared returns a box must hold to be judged by them."""
_MIN_ADDED = 10
"""Added returns a filter stage must see before dropping most of them counts."""
_FEW = 0.001
"""Share of the compared returns that may change label or object before a stage counts as
differing (returns on cell borders after a turn or mirror, local ground heights next to
removed returns)."""
_EDGE = 0.5
"""Metres from the ROI's edge within which a turned or mirrored follow-up's returns are not
compared (its ROI is rasterised afresh)."""
_TOUCH = 0.5
"""Metres: a box whose footprint lies this near a return the follow-up added or removed
is not compared (the change touches it; a correct stage may answer differently there)."""


@dataclass(frozen=True)
class StageOutput:
    """One stage's output on one sweep.

    Attributes
    ----------
    name : str
    kind : {"labels", "clusters", "boxes"}
    value : (n,) int64 or list of Box
        Per-return outputs are indexed like the sweep's cloud.
    within_roi : bool
        The stage must pass on only returns inside the ROI.
    labels : bool
        Boxes: compare their labels too.
    passes : bool
        Labels: a non-zero value means the stage passed the return on (a filter), so the
        returns a follow-up added where the violation is should mostly pass.
    """

    name: str
    kind: StageKind
    value: Any
    within_roi: bool = False
    labels: bool = True
    passes: bool = False


@dataclass(frozen=True)
class Stage:
    """A named stage of a :class:`StagedPipeline`: ``run(frame)`` returns its output
    (``PointLabels``, a bool array over the returns, a ``Partition`` or ``list[Box]``)."""

    name: str
    run: Callable[[Frame], Any]
    within_roi: bool = False
    labels: bool = True


def as_stage_output(stage: Stage, value: Any, returns: int) -> StageOutput:
    """A stage's raw output, checked and typed."""
    if isinstance(value, Partition):
        kind: StageKind = "clusters"
        array: Any = value.labels
    elif isinstance(value, PointLabels):
        kind, array = "labels", value.labels
    elif isinstance(value, np.ndarray) and value.ndim == 1:
        kind, array = "labels", value.astype(np.int64)
    elif isinstance(value, (list, tuple)) and all(isinstance(box, Box) for box in value):
        return StageOutput(stage.name, "boxes", list(value), stage.within_roi, stage.labels)
    else:
        raise InvalidArgument(
            f"stage {stage.name!r} returned {type(value).__name__}: a stage returns PointLabels, "
            "a bool array over the returns, a Partition or a list of Box"
        )
    if len(array) != returns:
        raise InvalidArgument(
            f"stage {stage.name!r} returned {len(array)} entries for a sweep of {returns} returns"
        )
    return StageOutput(stage.name, kind, array, stage.within_roi, stage.labels)


class StagedPipeline:
    """A pipeline declared as stages, in order.

    Parameters
    ----------
    stages : sequence of Stage or (name, callable)
        Each callable runs on the whole frame and returns its stage's output (it may run
        the stages before it again: only its output is compared).
    """

    def __init__(self, stages: Sequence[Stage | tuple[str, Callable[[Frame], Any]]]) -> None:
        made = [stage if isinstance(stage, Stage) else Stage(*stage) for stage in stages]
        if not made:
            raise InvalidArgument("stages must name at least one stage")
        names = [stage.name for stage in made]
        if len(set(names)) != len(names):
            raise InvalidArgument(f"stage names must differ, got {names}")
        for stage in made:
            if not callable(stage.run):
                raise InvalidArgument(f"stage {stage.name!r}: {stage.run!r} is not callable")
        self.stages = made

    def __repr__(self) -> str:
        return f"StagedPipeline({[stage.name for stage in self.stages]})"

    def trace(self, frame: Frame) -> list[StageOutput]:
        """Every stage's output on ``frame``."""
        return [as_stage_output(stage, stage.run(frame), len(frame.cloud)) for stage in self.stages]


@dataclass(frozen=True)
class Blame:
    """What :func:`blame` found.

    Attributes
    ----------
    stage : str or None
        The first stage whose output differs; None when none does.
    difference : str
        How it differs.
    agreed : list of str
        The stages before it, which agree.
    """

    stage: str | None
    difference: str
    agreed: list[str] = field(default_factory=list)

    def describe(self) -> str:
        if self.stage is None:
            return f"stage blame: no stage differs ({self.difference})"
        before = f"; {', '.join(self.agreed)} agree" if self.agreed else ""
        return (
            f"stage blame: {self.stage} (the first stage that differs: {self.difference}{before})"
        )


def blame(
    pipeline: Any,
    source: Frame,
    followup: Frame,
    params: Mapping[str, Any] | None = None,
    *,
    radius: float = 0.0,
) -> Blame:
    """The first stage of ``pipeline`` (anything with ``trace(frame)``) whose output on
    ``followup`` differs from its output on ``source`` (see the module docstring), judged
    where the violation is: on the obstacles of the last box stage that have no match on
    the other side (lost, gained or changed), and the returns under them."""
    if not callable(getattr(pipeline, "trace", None)):
        raise InvalidArgument(f"pipeline={pipeline!r} has no trace(frame) (a StagedPipeline)")
    if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not radius >= 0:
        raise InvalidArgument(f"radius={radius!r} must be a number of metres >= 0")
    params = dict(params or {})
    match = corresponding_points(source, followup, params)
    before_trace, after_trace = _traces(pipeline, source, followup, params)
    focus = _Focus.of(before_trace, after_trace, match, source, followup, params)
    shared = match.kept & match.far_from_change(source.cloud.xyz, radius) & focus.returns
    if _moves(params) and source.roi is not None:
        # A turned or mirrored ROI is rasterised afresh: near its edge the ROI filter may
        # pass other returns, correctly (the rotation relation's boundary margin).
        edge = np.asarray(source.roi.boundary_distance(source.cloud.xyz[:, :2]))
        shared &= edge > _EDGE
    # First by what each stage keeps (a box dropped, a return moved); when every stage
    # keeps everything, by shape (a box turned or resized).
    for strict in (False, True):
        agreed: list[str] = []
        reached = focus.new_returns & (match.origin < 0)  # added returns where it is
        for before, after in zip(before_trace, after_trace, strict=True):
            if strict and before.kind == "boxes":
                difference = _strict_difference(before, after.value, focus, params)
            else:
                difference = _difference(
                    before, after, match, shared, focus, source, followup, params
                )
            if not difference and before.passes:
                difference, reached = _added_dropped(
                    before, after, reached, source, followup, params
                )
            if difference:
                return Blame(before.name, difference, agreed)
            agreed.append(before.name)
    return Blame(None, f"{len(agreed)} stage(s) agree where the violation is", agreed)


def _traces(
    pipeline: Any, source: Frame, followup: Frame, params: Mapping[str, Any]
) -> tuple[list[StageOutput], list[StageOutput]]:
    """The stages' outputs on both sides; a history follow-up (``params["history"]``, an
    object with ``inputs(frame)``) replays as the engine ran it: the follow-up's input
    twice (the source itself for a plain history, a degraded sweep under faults), the
    earlier sweeps, then the follow-up; "before" is then the second run."""
    history = params.get("history")
    earlier = getattr(history, "inputs", None)
    if not callable(earlier):
        return pipeline.trace(source), pipeline.trace(followup)
    replayed = Followup(followup, before=tuple(earlier(source)))
    return replayed.compared_output(pipeline.trace, None), pipeline.trace(followup)


@dataclass(frozen=True)
class _Focus:
    """Where the violation is: the footprints of the last box stage's obstacles without a
    match on the other side, and the source's returns under them."""

    boxes: list[Box]  # in the source's frame
    returns: NDArray[np.bool_]  # (n,) source returns under them
    new_returns: NDArray[np.bool_]  # (m,) follow-up returns under them

    @staticmethod
    def of(
        before: list[StageOutput],
        after: list[StageOutput],
        match: PointCorrespondence,
        source: Frame,
        followup: Frame,
        params: Mapping[str, Any],
    ) -> _Focus:
        last = [i for i, stage in enumerate(before) if stage.kind == "boxes"]
        if not last:  # no boxes: the whole sweep
            return _Focus([], np.ones(len(source.cloud), bool), np.ones(len(followup.cloud), bool))
        was = list(before[last[-1]].value)
        now = [box_to_source(box, params) for box in after[last[-1]].value]
        pairs = matched_pairs(IoUMatcher(0.5, same_label=True), was, now)
        boxes = [box for i, box in enumerate(was) if i not in {p[0] for p in pairs}]
        boxes += [box for j, box in enumerate(now) if j not in {p[1] for p in pairs}]
        # An object the follow-up put into the sweep (inserted, moved) is where the
        # violation is even when the pipeline reports it nowhere.
        boxes += [
            placed
            for value in params.values()
            if isinstance(placed := getattr(value, "box", None), Box)
            and any(key.startswith(("insert", "relocat")) for key in params)
        ]
        if not boxes:  # matched one to one, yet the relation failed (a size, a heading)
            boxes = was + now
        grown = [box.grown(_TOUCH) for box in boxes]
        under = footprint_distances(source.cloud.xyz, grown) == 0
        aligned, _ = align_to_source(followup.cloud.xyz, params)
        new_under = footprint_distances(aligned, grown) == 0
        return _Focus(boxes, under, new_under)


def _difference(
    before: StageOutput,
    after: StageOutput,
    match: PointCorrespondence,
    shared: NDArray[np.bool_],
    focus: _Focus,
    source: Frame,
    followup: Frame,
    params: Mapping[str, Any],
) -> str:
    if before.kind == "boxes":
        return _box_difference(before, after.value, match, focus, source, followup, params)
    rows = np.flatnonzero(match.origin >= 0)
    rows = rows[shared[match.origin[rows]]]
    was, now = before.value[match.origin[rows]], after.value[rows]
    # A few returns may change on a correct stage: after a turn or a mirror, one lying
    # exactly on a grid's cell border changes sides (millimetre coordinates put 1 in 1000
    # on a 1 m border); next to returns that fog removed, a local ground height moves.
    tolerated = int(_FEW * len(rows))
    if before.kind == "clusters":
        changed, _ = changed_clusters(was, now)
        count = int(np.count_nonzero(changed))
        what = "changed object"
    else:
        count = int(np.count_nonzero(was != now))
        what = "changed label"
    if count > tolerated:
        return f"{count} of {len(rows)} shared returns {what}"
    if before.within_roi and source.roi is not None:
        new = np.flatnonzero((match.origin < 0) & (after.value != 0) & focus.new_returns)
        aligned, _ = align_to_source(followup.cloud.xyz[new], params)
        outside = new[~np.asarray(source.roi.contains(aligned[:, :2], method="exact"), dtype=bool)]
        if len(outside):
            return f"{len(outside)} return(s) added outside the ROI passed it"
    return ""


def _added_dropped(
    before: StageOutput,
    after: StageOutput,
    reached: NDArray[np.bool_],
    source: Frame,
    followup: Frame,
    params: Mapping[str, Any],
) -> tuple[str, NDArray[np.bool_]]:
    """A stage that drops most of the returns a follow-up added where the violation is (an
    inserted object's), of those the stages before it passed on; and the returns it passed
    on. Passed on: a filter's non-zero label, a cluster's member, a box's return."""
    judged = reached.copy()
    if before.within_roi and source.roi is not None:
        aligned, _ = align_to_source(followup.cloud.xyz, params)
        judged &= np.asarray(source.roi.contains(aligned[:, :2], method="exact"), dtype=bool)
    if after.kind == "boxes":
        passed = np.zeros(len(judged), dtype=bool)
        rows = np.flatnonzero(judged)
        for box in after.value:
            passed[rows] |= box.contains(followup.cloud.xyz[rows])
    elif after.kind == "clusters":
        passed = judged & (after.value >= 0)
    else:
        passed = judged & (after.value != 0)
    count, dropped = int(np.count_nonzero(judged)), int(np.count_nonzero(judged & ~passed))
    if count >= _MIN_ADDED and dropped * 2 > count:
        what = f"{dropped} of {count} returns the follow-up added where the violation is dropped"
        return what, passed
    return "", reached & passed if after.kind != "boxes" else reached


def _moves(params: Mapping[str, Any]) -> bool:
    """Whether the follow-up turned, mirrored or shifted the sweep."""
    return align_to_source(np.zeros((0, 3)), params)[1]


def _box_difference(
    before: StageOutput,
    after: list[Box],
    match: PointCorrespondence,
    focus: _Focus,
    source: Frame,
    followup: Frame,
    params: Mapping[str, Any],
) -> str:
    """Boxes overlapping the violation compared by the returns they hold: a box is kept
    when most of its returns that both sweeps share lie in one box of the other side (of
    its label, unless ``labels=False``). So a box that a lost packet trims, or a turn
    moves, is the same box; one that is dropped, split, merged or relabelled is not."""
    rows = np.flatnonzero(match.origin >= 0)
    to_followup = np.full(len(source.cloud), -1, dtype=np.intp)
    to_followup[match.origin[rows[::-1]]] = rows[::-1]  # the first copy of each return
    source_xyz, followup_xyz = source.cloud.xyz, followup.cloud.xyz
    was = [box for box in before.value if _overlaps(box, focus, {})]
    now = [box for box in after if _overlaps(box, focus, params)]
    lost = sum(
        not _held(box, _shared(box, source_xyz, to_followup), followup_xyz, after, before.labels)
        for box in was
    )
    gained = sum(
        not _held(
            box, _shared(box, followup_xyz, match.origin), source_xyz, before.value, before.labels
        )
        for box in now
    )
    if not (lost or gained):
        return ""
    what = "boxes" if before.labels else "boxes (labels aside)"
    return (
        f"{lost} of {len(was)} {what} where the violation is not kept, {gained} of {len(now)} "
        "not there before (judged by the returns they hold)"
    )


def _overlaps(box: Box, focus: _Focus, params: Mapping[str, Any]) -> bool:
    aligned = box_to_source(box, params) if params else box
    return any(aligned.iou_bev(other) > 0 for other in focus.boxes)


def _shared(box: Box, xyz: NDArray[np.float32], other: NDArray[np.intp]) -> NDArray[np.intp]:
    """Rows of the other sweep that are the returns ``box`` holds (those both share); none
    when the follow-up kept fewer than half of them, or fewer than a handful (a box it
    mostly removed may go, as may a remnant of a return or two)."""
    rows = other[box.contains(xyz)]
    shared = rows[rows >= 0]
    return shared if len(shared) * 2 >= len(rows) and len(shared) >= _MIN_SHARED else shared[:0]


def _held(
    box: Box, rows: NDArray[np.intp], xyz: NDArray[np.float32], boxes: list[Box], labels: bool
) -> bool:
    """Whether most of ``rows`` (of ``xyz``) lie in ``boxes`` (of ``box``'s label): kept,
    trimmed, split or merged, but not dropped or relabelled."""
    if len(rows) == 0:
        return True  # nothing shared to judge by
    points = xyz[rows]
    inside = np.zeros(len(points), dtype=bool)
    for other in boxes:
        if not labels or other.label == box.label:
            inside |= other.contains(points)
    return int(np.count_nonzero(inside)) * 2 > len(points)


def _strict_difference(
    before: StageOutput, after: list[Box], focus: _Focus, params: Mapping[str, Any]
) -> str:
    """Boxes overlapping the violation, each matched one to one by bird's-eye IoU >= 0.5
    (and label): for violations no box was lost in (a turned or resized box)."""
    was = [box for box in before.value if _overlaps(box, focus, {})]
    now = [box_to_source(box, params) for box in after if _overlaps(box, focus, params)]
    pairs = matched_pairs(IoUMatcher(0.5, same_label=before.labels), was, now)
    lost, gained = len(was) - len(pairs), len(now) - len(pairs)
    if not (lost or gained):
        return ""
    return (
        f"{lost} of {len(was)} boxes where the violation is have no match of IoU >= 0.5, "
        f"{gained} new"
    )


class BlamedRelation(Relation):
    """``relation``, whose violations also name the first stage of ``pipeline`` that
    differs (:func:`blame`): in the explanation and in ``details["stage_blame"]``."""

    def __init__(self, relation: Relation, pipeline: Any, *, radius: float = 0.0) -> None:
        if not isinstance(relation, Relation):
            raise InvalidArgument(f"relation={relation!r} must be a Relation")
        if not callable(getattr(pipeline, "trace", None)):
            raise InvalidArgument(f"pipeline={pipeline!r} has no trace(frame) (a StagedPipeline)")
        self.relation, self.pipeline, self.radius = relation, pipeline, radius
        self.name = relation.name

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        verdict = self.relation.check(source_output, followup_output, context)
        source, followup = context.source_input, context.followup_input
        if verdict.holds or not (isinstance(source, Frame) and isinstance(followup, Frame)):
            return verdict
        found = blame(self.pipeline, source, followup, context.params, radius=self.radius)
        return Verdict(
            False,
            verdict.relation,
            f"{verdict.explanation}\n{found.describe()}",
            {**verdict.details, "stage_blame": found.stage, "stage_difference": found.difference},
        )
