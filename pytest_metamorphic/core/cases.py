"""The drawn side of a metamorphic test: follow-ups, relations, cases, and their validation.

A case is a source input plus, for every :class:`MetamorphicRelation`, a few follow-up
inputs drawn from its transform; both are drawn through Hypothesis, so a failure shrinks
the source *and* the transform parameters.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from hypothesis import strategies as st
from hypothesis.strategies import SearchStrategy

from pytest_metamorphic.core.comparison import describe_params, describe_value
from pytest_metamorphic.core.errors import (
    InvalidArgument,
)
from pytest_metamorphic.core.relations import Relation
from pytest_metamorphic.core.stats import (
    DEFAULT_FOLLOWUPS,
    current_recorder,
)

__all__ = ["Followup", "MetamorphicCase", "MetamorphicRelation"]

CASE_ARGUMENT = "case"
_MAX_FOLLOWUPS = 100


@dataclass(frozen=True)
class Followup:
    """A follow-up input together with the transform parameters that made it.

    Transforms may yield plain inputs; yield ``Followup(value, params={...})`` when the
    parameters (a rotation angle, the injected points) should appear in failure messages
    and reports. A transform that cannot make a follow-up of a source (no object to
    insert, no laser to drop) yields :meth:`not_applicable` with the reason: the system is
    not run on it, and a relation that never applied is reported as having tested nothing,
    never as passing.

    ``before``: inputs the system runs on, in order, just before this follow-up, their
    outputs discarded (a history: the same sweep after other sweeps tests that a per-frame
    system carries nothing from one call to the next). The engine then runs the
    follow-up's own input twice first (the source itself for a plain history, a degraded
    sweep for a history under faults) and compares the follow-up's output with the second
    run's (that input right after itself: a failing case replays alike, whatever ran
    before it), runs the follow-up afresh, never batched, and does not re-check its
    violation for determinism (a history violation *is* one).
    """

    input: Any
    params: Mapping[str, Any] = field(default_factory=dict)
    skipped: str | None = None
    before: tuple[Any, ...] = ()

    def compared_output(self, system: Callable[[Any], Any], source_output: Any) -> Any:
        """What this follow-up's output is compared with when ``system`` runs it outside
        the engine: ``source_output``, or for a history the engine's baseline (its input
        run twice), after which the earlier inputs are run, in order, as the engine does.
        Call it right before running ``system`` on :attr:`input`."""
        if not self.before:
            return source_output
        system(self.input)
        baseline = system(self.input)
        for earlier in self.before:
            system(earlier)
        return baseline

    @classmethod
    def not_applicable(cls, source: Any, reason: str) -> Followup:
        """No follow-up for ``source``: ``reason`` says why (shown in the report)."""
        if not isinstance(reason, str) or not reason:
            raise InvalidArgument(f"reason={reason!r} must be a non-empty string")
        return cls(source, {"not_applicable": reason}, skipped=reason)

    def __repr__(self) -> str:
        if self.skipped is not None:
            return f"Followup.not_applicable({self.skipped!r})"
        params = f", params={dict(self.params)!r}" if self.params else ""
        return f"Followup({self.input!r}{params})"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        # Hypothesis prints a failing case with this: a follow-up reads as its transform
        # parameters (the noise points, an angle), not as the strategy calls that drew it
        # (``make(expand([0, 0, ...]))``) nor as a whole point cloud.
        if self.skipped is not None:
            printer.text(repr(self))
        elif not self.params:
            printer.pretty(self.input)
        else:
            printer.text(
                f"Followup({describe_value(self.input)}, params={describe_params(self.params)})"
            )


@dataclass(frozen=True)
class MetamorphicRelation:
    """A named pair of an input transform and an output relation.

    Parameters
    ----------
    name : str
        Shown in failures and reports; unique within one test.
    followup : callable(source_input) -> SearchStrategy
        Draws follow-up inputs for a source input. The strategy may yield plain inputs or
        :class:`Followup` values carrying the transform parameters.
    relation : Relation
        How the follow-up output must relate to the source output.
    same_input : callable(source_input, followup_input) -> bool, optional
        Whether a follow-up input equals its source (a follow-up that changed nothing
        tests nothing; the report counts them). Without it, only the very same object
        counts as unchanged.
    coverage : callable(context, source_output, followup_output, verdict), optional
        The cells (strings) of the operating domain one checked follow-up reached
        (``"distance: 0-5 m"``, ``"pose: pitch 2-3°"``), counted per relation and
        reported, so that a run shows which cells it never reached (the LiDAR relations
        have one:
        :func:`~pytest_metamorphic.lidar.judging.coverage.domain_cells`).
    """

    name: str
    followup: Callable[[Any], SearchStrategy[Any]]
    relation: Relation
    same_input: Callable[[Any, Any], bool] | None = None
    coverage: Callable[[Any, Any, Any, Any], Iterable[str]] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidArgument(f"name={self.name!r} must be a non-empty string")
        _check_transform(self.followup, f"followup of relation {self.name!r}")
        if not isinstance(self.relation, Relation):
            raise InvalidArgument(
                f"relation={self.relation!r} of {self.name!r} must be a Relation "
                "(e.g. relations.equal()); did you forget the parentheses?"
                if callable(self.relation)
                else f"relation={self.relation!r} of {self.name!r} must be a Relation, "
                "e.g. relations.equal() or relations.predicate(fn)"
            )
        for hook in ("same_input", "coverage"):
            value = getattr(self, hook)
            if value is not None and not callable(value):
                raise InvalidArgument(f"{hook}={value!r} of {self.name!r} must be callable")

    def unchanged(self, source: Any, followup: Any) -> bool:
        """Whether ``followup`` is ``source`` or, by :attr:`same_input`, equal to it."""
        if followup is source:
            return True
        return bool(self.same_input(source, followup)) if self.same_input is not None else False


@dataclass(frozen=True)
class MetamorphicCase:
    """One drawn test case: a source input and its follow-ups per relation name."""

    source: Any
    followups: Mapping[str, tuple[Followup, ...]]

    def __repr__(self) -> str:
        parts = ", ".join(f"{name!r}: {list(items)!r}" for name, items in self.followups.items())
        return f"MetamorphicCase(source={self.source!r}, followups={{{parts}}})"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        # One follow-up per line: a LiDAR case is a frame and a few noise draws, each
        # readable on its own line of Hypothesis's "Failing test case: ...".
        printer.text("MetamorphicCase(")
        with printer.indent(4):
            printer.break_()
            printer.text("source=")
            printer.pretty(self.source)
            printer.text(",")
            printer.break_()
            printer.text("followups={")
            with printer.indent(4):
                for name, items in self.followups.items():
                    printer.break_()
                    printer.text(f"{name!r}: [")
                    with printer.indent(4):
                        for item in items:
                            printer.break_()
                            printer.pretty(item)
                            printer.text(",")
                    printer.break_()
                    printer.text("],")
            printer.break_()
            printer.text("},")
        printer.break_()
        printer.text(")")


def _check_transform(followup: Any, what: str) -> None:
    if isinstance(followup, SearchStrategy):
        raise InvalidArgument(
            f"{what} is a strategy; it must be a function of the source input returning a "
            f"strategy, e.g. lambda source: {followup!r}"
        )
    if not callable(followup):
        raise InvalidArgument(
            f"{what} must be callable(source_input) -> strategy, got {followup!r}"
        )
    try:
        signature = inspect.signature(followup)
    except (TypeError, ValueError):
        return  # builtins without signatures: trust them
    try:
        signature.bind(object())
    except TypeError:
        raise InvalidArgument(
            f"{what} must accept exactly one argument (the source input); its signature is "
            f"{signature}"
        ) from None


def _resolve_relations(
    followup: Any, relation: Any, relations: Any
) -> tuple[MetamorphicRelation, ...]:
    if relations is not None:
        if followup is not None or relation is not None:
            raise InvalidArgument("pass either followup= and relation=, or relations=, not both")
        if isinstance(relations, MetamorphicRelation):
            relations = [relations]
        if not isinstance(relations, Sequence) or not relations:
            raise InvalidArgument(
                f"relations={relations!r} must be a non-empty list of MetamorphicRelation"
            )
        for index, item in enumerate(relations):
            if not isinstance(item, MetamorphicRelation):
                raise InvalidArgument(
                    f"relations[{index}] is {item!r}; wrap transform and relation in "
                    "MetamorphicRelation(name, followup, relation)"
                )
        names = [item.name for item in relations]
        duplicates = sorted({name for name in names if names.count(name) > 1})
        if duplicates:
            raise InvalidArgument(f"relation names must be unique, repeated: {duplicates}")
        return tuple(relations)
    if followup is None or relation is None:
        raise InvalidArgument(
            "@metamorphic needs followup= and relation= (or relations=[MetamorphicRelation...])"
        )
    name = getattr(relation, "name", None) if isinstance(relation, Relation) else None
    return (MetamorphicRelation(name or "relation", followup, relation),)


def _validate_followups(followups: Any) -> int | None:
    if followups is None:
        return None
    if isinstance(followups, bool) or not isinstance(followups, int):
        raise InvalidArgument(
            f"followups={followups!r} must be an int between 1 and {_MAX_FOLLOWUPS}"
        )
    if not 1 <= followups <= _MAX_FOLLOWUPS:
        raise InvalidArgument(f"followups={followups} must be between 1 and {_MAX_FOLLOWUPS}")
    return followups


def _draw_followups(
    draw: Callable[[SearchStrategy[Any]], Any], mr: MetamorphicRelation, source: Any, count: int
) -> tuple[Followup, ...]:
    strategy = mr.followup(source)
    if not isinstance(strategy, SearchStrategy):
        raise InvalidArgument(
            f"followup of relation {mr.name!r} returned {describe_value(strategy)}, not a "
            "Hypothesis strategy; return e.g. st.just(value) or st.permutations(source)"
        )
    items = []
    for _ in range(count):
        value = draw(strategy)
        items.append(value if isinstance(value, Followup) else Followup(value))
    return tuple(items)


def _cases(
    source: SearchStrategy[Any], mrs: tuple[MetamorphicRelation, ...], followups: int | None
) -> SearchStrategy[MetamorphicCase]:
    @st.composite
    def cases(draw: Callable[[SearchStrategy[Any]], Any]) -> MetamorphicCase:
        # Resolved per draw so that --mt-followups applies to tests that did not fix it.
        recorder = current_recorder()
        count = followups or (recorder.followups if recorder else DEFAULT_FOLLOWUPS)
        value = draw(source)
        return MetamorphicCase(
            value, {mr.name: _draw_followups(draw, mr, value, count) for mr in mrs}
        )

    return cases()
