"""Helpers shared by the LiDAR relation modules."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from hypothesis.strategies import SearchStrategy

from pytest_metamorphic.core.engine import MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import Relation
from pytest_metamorphic.lidar.judging.coverage import domain_cells
from pytest_metamorphic.lidar.judging.scope import DEFAULT_SCOPE, as_scope
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame

# An empty frame: strategies built on it validate a relation's arguments when it is made.
_PROBE = Frame(PointCloud.empty(), source="argument check")


def _frame(value: Any) -> Frame:
    if not isinstance(value, Frame):
        raise InvalidArgument(
            f"LiDAR relations need Frame source inputs (with .roi), got {type(value).__name__}"
        )
    return value


def _check_size(value: Any, name: str, *, allow_none: bool = False) -> None:
    if value is None and allow_none:
        return
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InvalidArgument(f"{name}={value!r} must be a positive int")


def _same_frame(source: Any, followup: Any) -> bool:
    """Whether a follow-up frame holds exactly its source's cloud (and ROI): it tests nothing."""
    if not (isinstance(source, Frame) and isinstance(followup, Frame)):
        return False
    return source.roi is followup.roi and source.cloud.equals(followup.cloud)


def coverage_of(relation: Relation) -> Callable[[Any, Any, Any, Any], list[str]]:
    """The operating-domain cells a follow-up of ``relation`` reached, judged in its
    scope (:func:`~pytest_metamorphic.lidar.judging.coverage.domain_cells`)."""
    scope = getattr(relation, "scope", None)
    return functools.partial(
        domain_cells, scope=DEFAULT_SCOPE if scope is None else as_scope(scope)
    )


def lidar_relation(
    name: str, followup: Callable[[Any], SearchStrategy[Any]], relation: Relation
) -> MetamorphicRelation:
    """A LiDAR relation: follow-ups equal to their source are counted as testing nothing,
    and each reports the cells of the operating domain it reached."""
    return MetamorphicRelation(
        name, followup, relation, same_input=_same_frame, coverage=coverage_of(relation)
    )
