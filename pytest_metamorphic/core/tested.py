"""What one follow-up tested: the counts a relation's report is made of.

The engine calls :func:`count_tested` after every check. It counts the obstacles (elements)
the check judged and keeps the first reason a check gave for judging none; it counts a
follow-up equal to its source and one whose output changed only outside what the relation
judges; and where the relation has a ``coverage`` function
(:class:`~pytest_metamorphic.core.cases.MetamorphicRelation`), it counts the cells of the
operating domain the follow-up reached (a judged obstacle's distance band, its bearing,
the pose drawn), so that a report can name what a green run never reached.
"""

from __future__ import annotations

from typing import Any

from pytest_metamorphic.core.cases import Followup, MetamorphicRelation
from pytest_metamorphic.core.relations import CheckContext, Verdict, judged_count, unjudged_changes
from pytest_metamorphic.core.stats import UNJUDGED, Recorder, RelationStats

__all__ = ["count_tested"]


def count_tested(
    stats: RelationStats,
    mr: MetamorphicRelation,
    followup: Followup,
    verdict: Verdict,
    recorder: Recorder | None,
    *,
    context: CheckContext,
    outputs: tuple[Any, Any],
) -> None:
    """Count what one checked follow-up tested into ``stats`` (``outputs``: the compared
    source output and the follow-up's)."""
    if unjudged_changes(verdict):
        stats.unjudged_changes += 1
    judged = judged_count(verdict)
    if judged is not None:
        stats.counted += 1
        stats.judged += judged
        stats.judged_followups += judged > 0
        why = verdict.details.get("unjudged_reason") if verdict.details else None
        if why and not judged and recorder is not None:
            recorder.reasons.setdefault(mr.name + UNJUDGED, str(why))
    if not followup.before and mr.unchanged(context.source_input, followup.input):
        stats.unchanged += 1
    if mr.coverage is not None:
        for cell in mr.coverage(context, outputs[0], outputs[1], verdict):
            stats.coverage[cell] = stats.coverage.get(cell, 0) + 1
