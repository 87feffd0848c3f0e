"""Output relations: how a follow-up output must relate to its source output.

A :class:`Relation` looks at two outputs (and the inputs and transform parameters that
produced them, through :class:`CheckContext`) and returns a :class:`Verdict` that explains
itself. Relations compose with ``&``::

    relations.cardinality("<=") & relations.subset(matcher=IoUMatcher(min_iou=0.5))

Ready relations: :func:`equal`, :func:`subset`, :func:`superset`, :func:`cardinality`,
:func:`approx`, :func:`predicate`.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pytest_metamorphic.core.comparison import describe_value, first_difference
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import EqualityMatcher, Matcher, PredicateMatcher, one_to_one
from pytest_metamorphic.core.verdict import Verdict

__all__ = [
    "AllOf",
    "CheckContext",
    "Relation",
    "Verdict",
    "approx",
    "cardinality",
    "equal",
    "judged_count",
    "predicate",
    "subset",
    "superset",
    "unjudged_changes",
]


@dataclass(frozen=True)
class CheckContext:
    """What a relation may look at besides the two outputs.

    Attributes
    ----------
    source_input, followup_input
        The inputs the system under test was run on.
    params : mapping
        The transform parameters of this follow-up (empty when the transform records none).
    index : int
        Which follow-up of the source this is (0-based).
    """

    source_input: Any = None
    followup_input: Any = None
    params: Mapping[str, Any] = field(default_factory=dict)
    index: int = 0


def unjudged_changes(verdict: Verdict) -> int:
    """Changes a verdict saw outside what its relation judges (``details["unjudged_changes"]``).

    Scoped relations (the LiDAR ones judge obstacles inside the ROI) report how many
    elements outside their scope changed, as information; combined relations' parts are
    summed. 0 for relations that judge everything.
    """
    details = verdict.details
    value = details.get("unjudged_changes")
    if isinstance(value, int):
        return value
    return sum(
        part["unjudged_changes"]
        for part in details.values()
        if isinstance(part, Mapping) and isinstance(part.get("unjudged_changes"), int)
    )


def judged_count(verdict: Verdict) -> int | None:
    """How many elements (obstacles) a verdict judged (``details["judged"]``; combined
    relations' parts summed), or None when the relation does not say."""
    details = verdict.details
    value = details.get("judged")
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    parts = [
        part["judged"]
        for part in details.values()
        if isinstance(part, Mapping)
        and isinstance(part.get("judged"), int)
        and not isinstance(part.get("judged"), bool)
    ]
    return sum(parts) if parts else None


class Relation:
    """Base class of output relations. Subclasses set :attr:`name` and implement :meth:`check`."""

    name: str = "relation"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        raise NotImplementedError

    def __and__(self, other: Relation) -> AllOf:
        if not isinstance(other, Relation):
            return NotImplemented
        return AllOf((*_parts(self), *_parts(other)))

    def __repr__(self) -> str:
        return f"<relation {self.name}>"


def _parts(relation: Relation) -> tuple[Relation, ...]:
    return relation.relations if isinstance(relation, AllOf) else (relation,)


class AllOf(Relation):
    """Holds when every part holds; the verdict reports every failing part."""

    def __init__(self, relations: Sequence[Relation]) -> None:
        self.relations = tuple(relations)
        for index, relation in enumerate(self.relations):
            if not isinstance(relation, Relation):
                raise InvalidArgument(f"relations[{index}] is {relation!r}, not a Relation")
        self.name = " & ".join(relation.name for relation in self.relations)

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        verdicts = [r.check(source_output, followup_output, context) for r in self.relations]
        failed = [v for v in verdicts if not v.holds]
        return Verdict(
            holds=not failed,
            relation=self.name,
            explanation="; ".join(f"{v.relation}: {v.explanation}" for v in failed),
            details={v.relation: dict(v.details) for v in verdicts},
        )


class _Equal(Relation):
    def __init__(self, expected: Callable[[Any, CheckContext], Any] | None) -> None:
        self.expected = expected
        self.name = "equal" if expected is None else "equal(expected)"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        want = source_output if self.expected is None else self.expected(source_output, context)
        difference = first_difference(want, followup_output)
        if difference is None:
            return Verdict(True, self.name)
        return Verdict(
            False,
            self.name,
            f"follow-up {context.index} differs from the "
            f"{'source' if self.expected is None else 'expected'} output: {difference}",
            {"difference": difference},
        )


def equal(*, expected: Callable[[Any, CheckContext], Any] | None = None) -> Relation:
    """The follow-up output equals the source output (``O == O'``).

    Parameters
    ----------
    expected : callable(source_output, context) -> expected follow-up output, optional
        For relations like "rotating the input rotates the output": the follow-up output
        must equal ``expected(O, context)`` instead of ``O``. Equality is exact and
        numpy-aware; use :func:`approx` for tolerances.
    """
    if expected is not None and not callable(expected):
        raise InvalidArgument(f"expected={expected!r} must be callable(source_output, context)")
    return _Equal(expected)


def _as_matcher(matcher: Matcher | Callable[[Any, Any], bool] | None, argument: str) -> Matcher:
    if matcher is None:
        return EqualityMatcher()
    if isinstance(matcher, Matcher):
        return matcher
    if callable(matcher):
        return PredicateMatcher(matcher, getattr(matcher, "__name__", "predicate"))
    raise InvalidArgument(
        f"{argument}={matcher!r} must be a Matcher (with .pairwise) or callable(a, b) -> bool"
    )


def _as_sequence(value: Any, which: str, relation: str) -> Sequence[Any]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Iterable):
        raise InvalidArgument(
            f"{relation} needs collection outputs; the {which} output is {describe_value(value)}"
        )
    return value if isinstance(value, Sequence) else list(value)


class _Contained(Relation):
    """Every element of ``inner`` has its own distinct match in ``outer``."""

    def __init__(self, matcher: Matcher, *, source_inside: bool) -> None:
        self.matcher = matcher
        self.source_inside = source_inside
        kind = "subset" if source_inside else "superset"
        self.name = f"{kind}[{matcher.name}]"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source = _as_sequence(source_output, "source", self.name)
        followup = _as_sequence(followup_output, "follow-up", self.name)
        inner, outer = (source, followup) if self.source_inside else (followup, source)
        compatible, cost = self.matcher.pairwise(inner, outer)
        pairs = one_to_one(compatible, cost)
        unmatched = sorted(set(range(len(inner))) - {i for i, _ in pairs})
        details = {
            "matched": [list(pair) for pair in pairs],
            "unmatched": unmatched,
            "source_size": len(source),
            "followup_size": len(followup),
        }
        if not unmatched:
            return Verdict(True, self.name, details=details)
        inner_name, outer_name = (
            ("the source", f"follow-up {context.index}")
            if self.source_inside
            else (f"follow-up {context.index}", "the source")
        )
        lines = [
            f"element #{i} ({describe_value(inner[i])}) of {inner_name} "
            f"has no match in {outer_name}"
            for i in unmatched[:10]
        ]
        if len(unmatched) > 10:
            lines.append(f"... and {len(unmatched) - 10} more")
        return Verdict(False, self.name, "; ".join(lines), details)


def subset(*, matcher: Matcher | Callable[[Any, Any], bool] | None = None) -> Relation:
    """Every source element has its own match in the follow-up output (``O ⊆ O'``).

    Matching is one-to-one (two source cars need two follow-up cars), found as a
    maximum-cardinality assignment, so counting alone never passes a lost element.

    Parameters
    ----------
    matcher : Matcher or callable(a, b) -> bool, optional
        Which elements may match; exact equality by default. For obstacles use
        ``pytest_metamorphic.lidar.model.obstacles.IoUMatcher`` or a centre-distance matcher.
    """
    return _Contained(_as_matcher(matcher, "matcher"), source_inside=True)


def superset(*, matcher: Matcher | Callable[[Any, Any], bool] | None = None) -> Relation:
    """Every follow-up element has its own match in the source output (``O ⊇ O'``)."""
    return _Contained(_as_matcher(matcher, "matcher"), source_inside=False)


_COMPARISONS: dict[str, Callable[[int, int], bool]] = {
    "<=": operator.le,
    "<": operator.lt,
    "==": operator.eq,
    ">=": operator.ge,
    ">": operator.gt,
}


class _Cardinality(Relation):
    def __init__(self, op: str) -> None:
        self.op = op
        self.name = f"cardinality(|O| {op} |O'|)"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        n = len(_as_sequence(source_output, "source", self.name))
        m = len(_as_sequence(followup_output, "follow-up", self.name))
        details = {"source_size": n, "followup_size": m}
        if _COMPARISONS[self.op](n, m):
            return Verdict(True, self.name, details=details)
        return Verdict(
            False,
            self.name,
            f"the source output has {n} element(s), follow-up {context.index} has {m}; "
            f"expected |O| {self.op} |O'|",
            details,
        )


def cardinality(op: str = "<=") -> Relation:
    """Compare output sizes: ``len(O) <op> len(O')``; ``"<="`` is the paper's MR1 check."""
    if op not in _COMPARISONS:
        raise InvalidArgument(f"op={op!r} must be one of {sorted(_COMPARISONS)}")
    return _Cardinality(op)


class _Approx(Relation):
    def __init__(
        self, rel: float, abs_: float, expected: Callable[[Any, CheckContext], Any] | None
    ):
        self.rel, self.abs, self.expected = rel, abs_, expected
        self.name = f"approx(rel={rel:g}, abs={abs_:g})"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        import numpy as np

        want = source_output if self.expected is None else self.expected(source_output, context)
        try:
            a = np.asarray(want, dtype=float)
            b = np.asarray(followup_output, dtype=float)
        except (TypeError, ValueError):
            raise InvalidArgument(
                f"{self.name} needs numeric outputs; got {describe_value(want)} and "
                f"{describe_value(followup_output)}"
            ) from None
        if a.shape != b.shape:
            return Verdict(False, self.name, f"shape {a.shape} != {b.shape}")
        close = np.isclose(a, b, rtol=self.rel, atol=self.abs, equal_nan=True)
        if close.all():
            return Verdict(True, self.name)
        index = tuple(int(i) for i in np.argwhere(~np.atleast_1d(close))[0])
        a1, b1 = np.atleast_1d(a), np.atleast_1d(b)
        gap = abs(float(a1[index]) - float(b1[index]))
        return Verdict(
            False,
            self.name,
            f"follow-up {context.index}: {a1[index]!r} vs {b1[index]!r} at {list(index)} "
            f"(difference {gap:.6g}; {int((~close).sum())} value(s) outside tolerance)",
            {"max_abs_difference": float(np.nanmax(np.abs(a - b))) if a.size else 0.0},
        )


def approx(
    *,
    rel: float = 1e-9,
    abs: float = 0.0,
    expected: Callable[[Any, CheckContext], Any] | None = None,
) -> Relation:
    """Numeric outputs (scalars or arrays) are equal within ``rel``/``abs`` tolerances."""
    for argument, value in (("rel", rel), ("abs", abs)):
        if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise InvalidArgument(f"{argument}={value!r} must be a finite number >= 0")
    if expected is not None and not callable(expected):
        raise InvalidArgument(f"expected={expected!r} must be callable(source_output, context)")
    return _Approx(float(rel), float(abs), expected)


class _Predicate(Relation):
    def __init__(self, fn: Callable[..., Any], name: str) -> None:
        self.fn, self.name = fn, name

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        result = self.fn(source_output, followup_output, context)
        if isinstance(result, Verdict):
            return result
        if not isinstance(result, (bool, type(None))) and type(result).__name__ != "bool_":
            raise InvalidArgument(
                f"predicate {self.name!r} returned {describe_value(result)}; "
                "it must return a bool or a Verdict"
            )
        if result:
            return Verdict(True, self.name)
        return Verdict(
            False,
            self.name,
            f"{self.name} is false for source output {describe_value(source_output)} and "
            f"follow-up {context.index} output {describe_value(followup_output)}",
        )


def predicate(fn: Callable[[Any, Any, CheckContext], Any], *, name: str | None = None) -> Relation:
    """A user relation: ``fn(source_output, followup_output, context)`` -> bool or Verdict."""
    if not callable(fn):
        raise InvalidArgument(
            f"fn={fn!r} must be callable(source_output, followup_output, context)"
        )
    return _Predicate(fn, name or str(getattr(fn, "__name__", "predicate")))
