"""Relations whose violations name the stage of a pipeline that went wrong."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from pytest_metamorphic.core.engine import MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.stages import BlamedRelation

__all__ = ["with_stage_blame"]


def with_stage_blame(
    relations: Sequence[MetamorphicRelation], pipeline: Any, *, radius: float = 0.0
) -> list[MetamorphicRelation]:
    """``relations``, each of whose violations also names the first stage of ``pipeline``
    (a :class:`~pytest_metamorphic.lidar.systems.stages.StagedPipeline`, or
    :func:`~pytest_metamorphic.lidar.systems.perception.trace.reference_stages`) whose
    output differs on the violating pair: a line ``stage blame: <stage> (...)`` in the
    failure and ``details["stage_blame"]`` in the verdict
    (:func:`~pytest_metamorphic.lidar.systems.stages.blame`; ``radius`` as there).

    The pipeline runs twice more on each violating pair (while Hypothesis shrinks, on
    each pair that still violates)."""
    if isinstance(relations, MetamorphicRelation):
        raise InvalidArgument("relations must be a sequence of relations (wrap one in a list)")
    return [
        dataclasses.replace(r, relation=BlamedRelation(r.relation, pipeline, radius=radius))
        for r in relations
    ]
