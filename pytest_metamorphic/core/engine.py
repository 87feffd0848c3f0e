"""The ``@metamorphic`` decorator: source inputs, follow-ups, relation checks.

A metamorphic test is a Hypothesis test over :class:`MetamorphicCase` values: a source
input plus, for every :class:`MetamorphicRelation`, a few follow-up inputs drawn from the
relation's transform. Both are drawn through Hypothesis, so a failure shrinks the source
*and* the transform parameters. For each case the engine runs the system under test (the
decorated function) once on the source, reuses that output for every follow-up, and
checks each relation; a failed check raises :class:`MetamorphicViolation`.

When Hypothesis replays its shrunk failing example for the last time, and the
follow-up's transform is made of independent elements (injected points: see
:mod:`pytest_metamorphic.core.perturbation`), the engine reduces it further with ddmin to
a 1-minimal follow-up (:mod:`pytest_metamorphic.core.reduction`) and reports that one.
Every violation is handed to the recorder's ``on_violation`` (the plugin saves artifacts).
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.errors import HypothesisException
from hypothesis.strategies import SearchStrategy

from pytest_metamorphic.core.comparison import describe_value, first_difference
from pytest_metamorphic.core.errors import (
    InvalidArgument,
    MetamorphicViolation,
    NondeterministicSystemError,
    SystemTimeout,
    SystemUnderTestCrash,
)
from pytest_metamorphic.core.reduction import Reduction, reduce_followup
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict, unjudged_changes
from pytest_metamorphic.core.stats import (
    DEFAULT_FOLLOWUPS,
    DEFAULT_MINIMIZE_BUDGET,
    Recorder,
    current_recorder,
)
from pytest_metamorphic.core.timeout import call_with_timeout, check_timeout

__all__ = [
    "Followup",
    "MetamorphicCase",
    "MetamorphicRelation",
    "ViolationRecord",
    "metamorphic",
]

CASE_ARGUMENT = "case"
_MAX_FOLLOWUPS = 100


@dataclass(frozen=True)
class Followup:
    """A follow-up input together with the transform parameters that made it.

    Transforms may yield plain inputs; yield ``Followup(value, params={...})`` when the
    parameters (a rotation angle, the injected points) should appear in failure messages
    and reports.
    """

    input: Any
    params: Mapping[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        params = f", params={dict(self.params)!r}" if self.params else ""
        return f"Followup({self.input!r}{params})"


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
    """

    name: str
    followup: Callable[[Any], SearchStrategy[Any]]
    relation: Relation

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


@dataclass(frozen=True)
class MetamorphicCase:
    """One drawn test case: a source input and its follow-ups per relation name."""

    source: Any
    followups: Mapping[str, tuple[Followup, ...]]

    def __repr__(self) -> str:
        parts = ", ".join(f"{name!r}: {list(items)!r}" for name, items in self.followups.items())
        return f"MetamorphicCase(source={self.source!r}, followups={{{parts}}})"


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


def _input_parameter(fn: Callable[..., Any]) -> tuple[str, list[inspect.Parameter]]:
    signature = inspect.signature(fn)
    parameters = list(signature.parameters.values())
    if not parameters or parameters[0].kind not in (
        inspect.Parameter.POSITIONAL_ONLY,
        inspect.Parameter.POSITIONAL_OR_KEYWORD,
    ):
        raise InvalidArgument(
            f"{fn.__qualname__} must take the input as its first positional parameter "
            "(further parameters are pytest fixtures)"
        )
    fixtures = parameters[1:]
    for parameter in fixtures:
        if parameter.kind in (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD):
            raise InvalidArgument(f"{fn.__qualname__}: *args/**kwargs cannot be pytest fixtures")
        if parameter.name == CASE_ARGUMENT:
            raise InvalidArgument(
                f"{fn.__qualname__}: the parameter name {CASE_ARGUMENT!r} is used by "
                "@metamorphic for the drawn case; rename your fixture"
            )
    return parameters[0].name, fixtures


class _Runner:
    """Executes one drawn case against the system under test."""

    def __init__(
        self,
        fn: Callable[..., Any],
        mrs: tuple[MetamorphicRelation, ...],
        check_determinism: bool | None,
        timeout: float | None = None,
    ) -> None:
        self.fn = fn
        self.mrs = mrs
        self.check_determinism = check_determinism
        self.timeout = timeout

    def _limit(self) -> float | None:
        """The per-call time limit: the decorator's, else ``--mt-timeout``'s, else none."""
        if self.timeout is not None:
            return self.timeout
        recorder = current_recorder()
        return recorder.timeout if recorder else None

    def __call__(self, case: MetamorphicCase, fixtures: dict[str, Any]) -> None:
        __tracebackhide__ = True  # failures should show the user's frames, not the engine's
        recorder = current_recorder()
        source_output = self._run(case.source, fixtures, "the source input", "source", None)
        if recorder:
            recorder.source_calls += 1
        for mr in self.mrs:
            stats = recorder.relation(mr.name) if recorder else None
            if stats:
                stats.sources += 1
            # .get: an explicit @example case may carry follow-ups for one relation only.
            items = case.followups.get(mr.name, ())
            for index, item in enumerate(items):
                what = f"follow-up {index} of relation {mr.name!r}"
                try:
                    output = self._run(item.input, fixtures, what, "followup", mr.name)
                finally:
                    if stats:
                        stats.followups += 1
                        stats.sut_calls += 1
                context = CheckContext(case.source, item.input, item.params, index)
                verdict = mr.relation.check(source_output, output, context)
                if stats and unjudged_changes(verdict):
                    stats.unjudged_changes += 1
                if not verdict.holds:
                    self._confirm_deterministic(case, source_output, fixtures, mr, stats)
                    if stats:
                        stats.violations += 1
                    raise self._violation(
                        case, mr, item, index, len(items), fixtures, output, verdict, source_output
                    )

    def _violation(
        self,
        case: MetamorphicCase,
        mr: MetamorphicRelation,
        item: Followup,
        index: int,
        total: int,
        fixtures: dict[str, Any],
        output: Any,
        verdict: Verdict,
        source_output: Any,
    ) -> MetamorphicViolation:
        """Reduce (in the final run), record and save a confirmed violation; the error to raise."""
        recorder = current_recorder()
        final = _in_final_run()
        reduction, note = (
            self._reduce(case.source, source_output, output, item, index, mr, fixtures)
            if final
            else (None, "")
        )
        record = ViolationRecord(
            nodeid=recorder.nodeid if recorder else "",
            relation=mr.name,
            check=verdict.relation,
            index=index,
            total=total,
            source=case.source,
            followup=item,
            source_output=source_output,
            followup_output=output,
            verdict=verdict,
            reduction=reduction,
            reduction_note=note,
            seed=_hypothesis_seed(),
        )
        saved = None
        if recorder:
            summary = {"relation": mr.name, "index": index, "explanation": verdict.explanation}
            if reduction:
                summary.update(
                    minimal_size=reduction.size,
                    original_size=reduction.original_size,
                    proven_minimal=reduction.proven_minimal,
                    minimize_calls=reduction.calls,
                )
            recorder.violations.append(summary)
            saved = _save(recorder, record, final)
        return _violation_error(record, saved)

    def _reduce(
        self,
        source: Any,
        source_output: Any,
        followup_output: Any,
        item: Followup,
        index: int,
        mr: MetamorphicRelation,
        fixtures: dict[str, Any],
    ) -> tuple[Reduction | None, str]:
        """The 1-minimal follow-up (or None) and a note on why there is none."""
        recorder = current_recorder()
        budget = recorder.minimize_budget if recorder else DEFAULT_MINIMIZE_BUDGET
        if budget <= 0:
            return None, ""

        def run(value: Any) -> Any:
            return self.fn(value, **fixtures)

        try:
            reduction = reduce_followup(
                item.params,
                source=source,
                source_output=source_output,
                followup_output=followup_output,
                run=run,
                check=mr.relation.check,
                index=index,
                budget=budget,
            )
        except HypothesisException:
            raise
        except Exception as error:
            # The violation stands on its own; a failed reduction must not replace it
            # (Hypothesis would call the final replay flaky).
            return None, f"could not reduce the follow-up: {type(error).__name__}: {error}"
        if reduction is not None and recorder:
            stats = recorder.relation(mr.name)
            stats.sut_calls += reduction.calls
            stats.minimize_calls += reduction.calls
        return reduction, ""

    def _run(
        self, value: Any, fixtures: dict[str, Any], what: str, stage: str, relation: str | None
    ) -> Any:
        __tracebackhide__ = True
        try:
            return call_with_timeout(self.fn, value, seconds=self._limit(), what=what, **fixtures)
        except HypothesisException:
            raise  # assume(), reject(): Hypothesis control flow, not a crash
        except Exception as error:
            recorder = current_recorder()
            if recorder:
                if relation is None:
                    recorder.source_crashes += 1
                else:
                    recorder.relation(relation).crashes += 1
            verb = "timed out" if isinstance(error, SystemTimeout) else "crashed"
            raise SystemUnderTestCrash(
                f"the system under test {verb} on {what}: {type(error).__name__}: {error}",
                stage=stage,
                relation=relation,
            ) from error

    def _confirm_deterministic(
        self,
        case: MetamorphicCase,
        source_output: Any,
        fixtures: dict[str, Any],
        mr: MetamorphicRelation,
        stats: Any,
    ) -> None:
        recorder = current_recorder()
        enabled = self.check_determinism
        if enabled is None:
            enabled = recorder.check_determinism if recorder else True
        if not enabled:
            return
        again = self._run(case.source, fixtures, "the source input (re-run)", "source", None)
        if stats:
            stats.sut_calls += 1
        difference = first_difference(source_output, again)
        if difference is not None:
            if stats:
                stats.nondeterministic += 1
            raise NondeterministicSystemError(
                f"the system under test is nondeterministic: running it twice on the same "
                f"source input gave different outputs ({difference}), so relation "
                f"{mr.name!r} cannot be judged. Fix the seed or the order dependence, or pass "
                "check_determinism=False if you know what you are doing."
            )


@dataclass(frozen=True)
class ViolationRecord:
    """Everything known about one violation, for the message and for artifacts.

    Attributes
    ----------
    nodeid : str
        The pytest node id ("" outside the plugin).
    relation, check : str
        The metamorphic relation's name and the output relation's name.
    index, total : int
        Which follow-up of how many.
    source, followup
        The source input and the violating follow-up as drawn (before reduction).
    source_output, followup_output, verdict
        The outputs and the relation's verdict on that follow-up.
    reduction : Reduction or None
        The 1-minimal follow-up, when the transform was reducible and this was the final run.
    reduction_note : str
        Why a reduction is missing although one was attempted.
    seed : dict
        Hypothesis' seed for the run (``{"seed": int or None, "derandomize": bool}``).
    """

    nodeid: str
    relation: str
    check: str
    index: int
    total: int
    source: Any
    followup: Followup
    source_output: Any
    followup_output: Any
    verdict: Verdict
    reduction: Reduction | None = None
    reduction_note: str = ""
    seed: Mapping[str, Any] = field(default_factory=dict)

    @property
    def minimal_followup(self) -> Followup:
        """The reduced follow-up when there is one, else the follow-up as drawn."""
        if self.reduction is None:
            return self.followup
        return Followup(self.reduction.followup_input, self.reduction.params)

    @property
    def minimal_output(self) -> Any:
        return self.followup_output if self.reduction is None else self.reduction.output

    @property
    def minimal_verdict(self) -> Verdict:
        return self.verdict if self.reduction is None else self.reduction.verdict


def _in_final_run() -> bool:
    """True in Hypothesis' last replay of a failing example, and outside Hypothesis."""
    from hypothesis.control import current_build_context

    try:
        return bool(current_build_context().is_final)
    except HypothesisException:  # no build context: called directly, e.g. by a replay
        return True


def _hypothesis_seed() -> dict[str, Any]:
    """The seed Hypothesis used for this test run (``@seed``, generated, or derandomized)."""
    from hypothesis.control import current_build_context

    try:
        wrapped = current_build_context().wrapped_test
    except HypothesisException:
        return {"seed": None, "derandomize": False}
    # Private attributes, read defensively: Hypothesis prints the same seed on failures.
    seed = getattr(wrapped, "_hypothesis_internal_use_seed", None)
    if seed is None:
        seed = getattr(wrapped, "_hypothesis_internal_use_generated_seed", None)
    chosen = getattr(wrapped, "_hypothesis_internal_use_settings", None)
    return {
        "seed": seed if isinstance(seed, int) else None,
        "derandomize": bool(getattr(chosen, "derandomize", False)),
    }


def _save(recorder: Recorder, record: ViolationRecord, final: bool) -> str | None:
    if recorder.on_violation is None:
        return None
    return recorder.on_violation(record, final)


def _violation_error(record: ViolationRecord, saved: str | None) -> MetamorphicViolation:
    reduction = record.reduction
    verdict = record.minimal_verdict
    item = record.minimal_followup
    lines = [
        f"metamorphic relation {record.relation!r} violated on follow-up {record.index} of "
        f"{record.total} (check: {verdict.relation})",
    ]
    if reduction is not None:
        lines.append(f"  minimal follow-up: {reduction.summary()}")
        lines.extend(f"    {line}" for line in reduction.element_lines())
        lines.extend(f"  {line}" for line in reduction.effect_lines(record.source_output))
    elif record.reduction_note:
        lines.append(f"  {record.reduction_note}")
    if item.params:
        lines.append(f"  transform parameters: {_short_params(item.params)}")
    lines.append(f"  {verdict.explanation}")
    if reduction is not None and record.verdict.explanation != verdict.explanation:
        lines.append(f"  with all {reduction.original_size} elements: {record.verdict.explanation}")
    lines.append(f"  source output:    {describe_value(record.source_output)}")
    lines.append(f"  follow-up output: {describe_value(record.minimal_output)}")
    if saved:
        lines.append(f"  artifacts: {saved}")
    error = MetamorphicViolation("\n".join(lines), relation=record.relation, verdict=verdict)
    error.followup = item
    error.source_output = record.source_output
    error.followup_output = record.minimal_output
    error.record = record
    return error


def _short_params(params: Mapping[str, Any]) -> str:
    return "{" + ", ".join(f"{key}={describe_value(value)}" for key, value in params.items()) + "}"


def metamorphic(
    *,
    source: SearchStrategy[Any],
    followup: Callable[[Any], SearchStrategy[Any]] | None = None,
    relation: Relation | None = None,
    relations: Sequence[MetamorphicRelation] | None = None,
    followups: int | None = None,
    check_determinism: bool | None = None,
    timeout: float | None = None,
) -> Callable[[Callable[..., Any]], Callable[..., None]]:
    """Turn a function that runs the system under test into a metamorphic Hypothesis test.

    Parameters
    ----------
    source : SearchStrategy
        Draws source inputs.
    followup : callable(source_input) -> SearchStrategy, optional
        The input transform of a single relation (use with ``relation``).
    relation : Relation, optional
        The output relation of that single relation.
    relations : sequence of MetamorphicRelation, optional
        Several relations sharing one system under test (instead of followup/relation).
    followups : int, optional
        Follow-ups per source and relation, 1..100; default ``--mt-followups`` (2).
    check_determinism : bool, optional
        Before reporting a violation, re-run the system on the source and raise
        :class:`NondeterministicSystemError` if the output changed. On by default;
        ``--mt-no-determinism-check`` switches the default off.
    timeout : float, optional
        Seconds one call of the system may take (default: ``--mt-timeout``, else no
        limit). A call that takes longer is reported as a crash of that call
        (:class:`~pytest_metamorphic.core.errors.SystemTimeout` chained), never as a
        violation, and Hypothesis saves the case for replay as for any failure. An
        in-process call cannot be stopped: it is left running in a background thread.

    The decorated function takes the input as its first parameter (more parameters are
    pytest fixtures) and returns the system's output. Stack ``@settings(...)`` on top as
    with ``@given``.
    """
    if not isinstance(source, SearchStrategy):
        raise InvalidArgument(f"source={source!r} must be a Hypothesis strategy")
    mrs = _resolve_relations(followup, relation, relations)
    count = _validate_followups(followups)
    if check_determinism is not None and not isinstance(check_determinism, bool):
        raise InvalidArgument(f"check_determinism={check_determinism!r} must be a bool")
    limit = check_timeout(timeout)

    def decorate(fn: Callable[..., Any]) -> Callable[..., None]:
        if not callable(fn):
            raise InvalidArgument(f"@metamorphic must decorate a function, got {fn!r}")
        if getattr(fn, "is_hypothesis_test", False):
            raise InvalidArgument(
                f"{fn.__qualname__} is already a Hypothesis test; use @metamorphic instead of "
                "@given, not both"
            )
        if inspect.iscoroutinefunction(fn):
            raise InvalidArgument(
                f"{fn.__qualname__} is async; @metamorphic needs a plain function"
            )
        _, fixtures = _input_parameter(fn)
        runner = _Runner(fn, mrs, check_determinism, limit)

        @functools.wraps(fn)
        def test(**kwargs: Any) -> None:
            __tracebackhide__ = True
            case = kwargs.pop(CASE_ARGUMENT)
            runner(case, kwargs)

        del test.__wrapped__  # pytest and Hypothesis must see our signature, not fn's
        test.__signature__ = inspect.Signature(
            [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in fixtures]
            + [inspect.Parameter(CASE_ARGUMENT, inspect.Parameter.KEYWORD_ONLY)]
        )
        wrapped = given(**{CASE_ARGUMENT: _cases(source, mrs, count)})(test)
        # One example runs the system 1 + followups x relations times, so Hypothesis's
        # per-example deadline would misfire on any real system. A user's @settings on top
        # replaces this default entirely, as it does for @given.
        wrapped._hypothesis_internal_use_settings = settings(
            wrapped._hypothesis_internal_use_settings, deadline=None
        )
        wrapped._metamorphic = MetamorphicSpec(source, mrs, count, check_determinism, fn)
        return wrapped

    return decorate


@dataclass(frozen=True)
class MetamorphicSpec:
    """What ``@metamorphic`` was given; the plugin and campaign mode read it."""

    source: SearchStrategy[Any]
    relations: tuple[MetamorphicRelation, ...]
    followups: int | None
    check_determinism: bool | None
    function: Callable[..., Any]
