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
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from hypothesis import given, reject, settings
from hypothesis.errors import HypothesisException
from hypothesis.strategies import SearchStrategy

from pytest_metamorphic.core.batching import (
    FixturedBatch as _FixturedBatch,
)
from pytest_metamorphic.core.batching import (
    SingleOfBatch as _SingleOfBatch,
)
from pytest_metamorphic.core.batching import (
    SystemCalls,
)
from pytest_metamorphic.core.batching import (
    check_batch_request as _check_batch,
)
from pytest_metamorphic.core.cases import (
    CASE_ARGUMENT,
    Followup,
    MetamorphicCase,
    MetamorphicRelation,
    _cases,
    _resolve_relations,
    _validate_followups,
)
from pytest_metamorphic.core.comparison import first_difference, value_digest
from pytest_metamorphic.core.errors import (
    InvalidArgument,
    MetamorphicError,
    MetamorphicViolation,
    NondeterministicSystemError,
    SystemTimeout,
    SystemUnderTestCrash,
)
from pytest_metamorphic.core.reduction import Reduction, reduce_followup
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.core.search_phase import counts_as_new_case
from pytest_metamorphic.core.stats import (
    DEFAULT_MINIMIZE_BUDGET,
    DEFAULT_MINIMIZE_SECONDS,
    current_recorder,
)
from pytest_metamorphic.core.tested import count_tested
from pytest_metamorphic.core.timeout import call_isolated, call_with_timeout, check_timeout
from pytest_metamorphic.core.tracebacks import raise_at_definition
from pytest_metamorphic.core.violations import (
    ViolationRecord,
    _hypothesis_seed,
    _in_final_run,
    _save,
    _violation_error,
)

__all__ = [
    "Followup",
    "MetamorphicCase",
    "MetamorphicRelation",
    "ViolationRecord",
    "metamorphic",
]


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
        batch: int = 0,
        isolate: bool = False,
    ) -> None:
        self.fn = fn if not batch else _SingleOfBatch(fn)
        self.definition = fn  # where failures are reported: the user's test
        self.call = call_isolated if isolate else call_with_timeout
        self.batch_fn = fn if batch else None
        self.batch = batch
        self.mrs = mrs
        self.check_determinism = check_determinism
        self.timeout = timeout
        # Outputs of the current case computed ahead in batches: id(input) -> outcome.
        self._ahead: dict[int, tuple[Any, BaseException | None]] = {}
        self._case: MetamorphicCase | None = None
        self._replay_timeout: BaseException | None = None
        self._new_case = True

    def _limit(self) -> float | None:
        """The per-call time limit: the decorator's, else ``--mt-timeout``'s, else none."""
        if self.timeout is not None:
            return self.timeout
        recorder = current_recorder()
        return recorder.timeout if recorder else None

    def __call__(self, case: MetamorphicCase, fixtures: dict[str, Any]) -> None:
        __tracebackhide__ = True  # failures should show the user's frames, not the engine's
        recorder = current_recorder()
        self._case = case
        # A variant or replay of a failing case Hypothesis already counted is not a new
        # source: its counts go to ``recorder.reruns`` (see core/search_phase.py).
        self._new_case = recorder is None or counts_as_new_case()
        if recorder is not None and recorder.timed_out is not None and not _in_final_run():
            # A system that hung once is not waited for again while Hypothesis shrinks
            # (before: each shrink step waited the full limit and left a thread behind):
            # the case that hung fails the same way at once, every other is invalid.
            digest, error = recorder.timed_out
            if digest != _case_digest(case):
                reject()
            self._replay_timeout = error
        self._ahead = self._run_ahead(case, fixtures) if self.batch else {}
        try:
            self._check_case(case, fixtures, recorder)
        except (MetamorphicViolation, MetamorphicError) as error:
            raise_at_definition(self.definition, error)  # the traceback names the test
        finally:
            self._ahead = {}
            self._replay_timeout = None

    def _run_ahead(
        self, case: MetamorphicCase, fixtures: dict[str, Any]
    ) -> dict[int, tuple[Any, BaseException | None]]:
        """Outputs of the source and every follow-up, computed in batches."""
        values = [case.source]
        whats = ["the source input"]
        for mr in self.mrs:
            for index, item in enumerate(case.followups.get(mr.name, ())):
                if item.skipped is not None or item.before:  # a history runs in order
                    continue
                values.append(item.input)
                whats.append(f"follow-up {index} of relation {mr.name!r}")
        calls = SystemCalls(_FixturedBatch(self.batch_fn, fixtures, self.batch), self._limit())
        ahead: dict[int, tuple[Any, BaseException | None]] = {}
        for start in range(0, len(values), self.batch):
            chunk = values[start : start + self.batch]
            outcomes = calls.run(chunk, whats[start : start + self.batch])
            for value, outcome in zip(chunk, outcomes, strict=True):
                ahead.setdefault(id(value), outcome)
        return ahead

    def _check_case(self, case: MetamorphicCase, fixtures: dict[str, Any], recorder: Any) -> None:
        __tracebackhide__ = True
        new = self._new_case
        reruns = recorder.reruns if recorder and not new else None
        try:
            source_output = self._run(case.source, fixtures, "the source input", "source", None)
        finally:  # a call that crashed is a call too
            if recorder and new:
                recorder.source_calls += 1
            if reruns:
                reruns.sources += 1
                reruns.sut_calls += 1
        for mr in self.mrs:
            stats = (recorder.relation(mr.name) if new else reruns) if recorder else None
            if stats and new:
                stats.sources += 1
            # .get: an explicit @example case may carry follow-ups for one relation only.
            items = case.followups.get(mr.name, ())
            for index, item in enumerate(items):
                if item.skipped is not None:
                    if stats:
                        stats.not_applicable += 1
                    if recorder is not None:
                        recorder.reasons.setdefault(mr.name, item.skipped)
                    continue
                what = f"follow-up {index} of relation {mr.name!r}"
                # A history's output is compared with its own input's right after itself.
                settled = self._run_history(case, item, fixtures, what, mr.name, stats)
                compared = source_output if settled is _NO_HISTORY else settled
                try:
                    output = self._run(
                        item.input, fixtures, what, "followup", mr.name, fresh=bool(item.before)
                    )
                finally:
                    if stats:
                        stats.followups += 1
                        stats.sut_calls += 1
                context = CheckContext(case.source, item.input, item.params, index)
                verdict = mr.relation.check(compared, output, context)
                if stats:
                    count_tested(stats, mr, item, verdict, recorder, context=context,
                                 outputs=(compared, output))  # fmt: skip
                if not verdict.holds:
                    if not item.before:  # a history's violation is itself a re-run's
                        self._confirm_deterministic(case, source_output, fixtures, mr, stats)
                    if stats:
                        stats.violations += 1  # in reruns: the same failure again
                    raise self._violation(
                        case, mr, item, index, len(items), fixtures, output, verdict, compared
                    )

    def _run_history(
        self,
        case: MetamorphicCase,
        item: Followup,
        fixtures: dict[str, Any],
        what: str,
        relation: str,
        stats: Any,
    ) -> Any:
        """A history's baseline: its input run twice (the source, or a degraded sweep), then
        the earlier inputs in order; ``_NO_HISTORY`` for any other follow-up."""
        __tracebackhide__ = True
        if not item.before:
            return _NO_HISTORY
        itself = "the source input" if item.input is case.source else f"the input of {what}"
        runs = [(item.input, f"{itself} (before a history)")] * 2
        runs += [
            (value, f"earlier input {step} of {what}") for step, value in enumerate(item.before)
        ]
        outputs = []
        for value, label in runs:
            try:
                outputs.append(self._run(value, fixtures, label, "followup", relation, fresh=True))
            finally:
                if stats:
                    stats.sut_calls += 1
                    stats.history_calls += 1
        return outputs[1]

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
            if final:  # the violation the user sees, once per failing case
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
            # The time limit holds while reducing too (a reduced input may hang).
            what = "a reduced follow-up"
            return self.call(self.fn, value, seconds=self._limit(), what=what, **fixtures)

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
                seconds=recorder.minimize_seconds if recorder else DEFAULT_MINIMIZE_SECONDS,
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
        self,
        value: Any,
        fixtures: dict[str, Any],
        what: str,
        stage: str,
        relation: str | None,
        fresh: bool = False,
    ) -> Any:
        __tracebackhide__ = True
        try:
            if self._replay_timeout is not None:
                # The same error object: Hypothesis sees the same failure as the first time.
                raise self._replay_timeout
            ahead = None if fresh else self._ahead.get(id(value))
            if ahead is not None:
                output, error = ahead
                if error is not None:
                    raise error
                return output
            return self.call(self.fn, value, seconds=self._limit(), what=what, **fixtures)
        except HypothesisException:
            raise  # assume(), reject(): Hypothesis control flow, not a crash
        except Exception as error:
            recorder = current_recorder()
            # A replayed time-out was counted when it happened.
            if recorder and error is not self._replay_timeout:
                if isinstance(error, SystemTimeout) and recorder.timed_out is None:
                    recorder.timed_out = (_case_digest(self._case), error)
                if not self._new_case:
                    recorder.reruns.crashes += 1
                elif relation is None:
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
        try:
            again = self._run(
                case.source, fixtures, "the source input (re-run)", "source", None, fresh=True
            )
        finally:
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


def metamorphic(
    *,
    source: SearchStrategy[Any],
    followup: Callable[[Any], SearchStrategy[Any]] | None = None,
    relation: Relation | None = None,
    relations: Sequence[MetamorphicRelation] | None = None,
    followups: int | None = None,
    check_determinism: bool | None = None,
    timeout: float | None = None,
    batch: bool | int = False,
    isolate: bool = False,
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
        violation, and Hypothesis saves the case for replay as for any failure. After a
        time-out the system is not called again while Hypothesis shrinks (only to replay
        the case that timed out), so a hanging system costs about twice the limit. An
        in-process call cannot be stopped: it is left running in a background thread (at
        most 16 at once), unless ``isolate``.
    isolate : bool
        Run each call in a forked child process that is killed at the time limit: for
        systems stuck in C code that holds the GIL (a thread-based limit cannot even
        fire then), or that must not be left running. Outputs must pickle; POSIX only;
        not with ``batch``.
    batch : bool or int
        True (or a batch size; True means 8): the decorated function takes a *list* of
        inputs and returns their outputs in order, so a model runs the source and its
        follow-ups in batches (:mod:`pytest_metamorphic.core.batching`). Each output must
        be what the function gives that input alone: the determinism re-check and the
        reduction of a violation call it with one input at a time. A batch that raises is
        run again one input at a time, so a crash names its input. ``timeout`` stays per
        input (a batch of k inputs may take k times as long).

    Notes
    -----
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
    batch_size = _check_batch(batch)
    if not isinstance(isolate, bool):
        raise InvalidArgument(f"isolate={isolate!r} must be a bool")
    if isolate and batch_size:
        raise InvalidArgument("isolate=True runs one input per process call; not with batch=")

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
        runner = _Runner(fn, mrs, check_determinism, limit, batch_size, isolate)

        @functools.wraps(fn)
        def test(**kwargs: Any) -> None:
            __tracebackhide__ = True
            case = kwargs.pop(CASE_ARGUMENT)
            runner(case, kwargs)

        del test.__wrapped__  # pytest and Hypothesis must see our signature, not fn's
        signed: Any = test  # function attributes are not in its static type
        signed.__signature__ = inspect.Signature(
            [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in fixtures]
            + [inspect.Parameter(CASE_ARGUMENT, inspect.Parameter.KEYWORD_ONLY)]
        )
        wrapped: Any = given(**{CASE_ARGUMENT: _cases(source, mrs, count)})(test)
        # One example runs the system 1 + followups x relations times, so Hypothesis's
        # per-example deadline would misfire on any real system. A user's @settings on top
        # replaces this default entirely, as it does for @given.
        wrapped._hypothesis_internal_use_settings = settings(
            wrapped._hypothesis_internal_use_settings, deadline=None
        )
        wrapped._metamorphic = MetamorphicSpec(
            source, mrs, count, check_determinism, fn, batch_size
        )
        return wrapped

    return decorate


_NO_HISTORY = object()  # a follow-up without earlier inputs


def _case_digest(case: MetamorphicCase | None) -> str:
    """Tells a case from every other: the one that timed out is recognised on replay."""
    return "" if case is None else value_digest((case.source, case.followups))


@dataclass(frozen=True)
class MetamorphicSpec:
    """What ``@metamorphic`` was given; the plugin and campaign mode read it."""

    source: SearchStrategy[Any]
    relations: tuple[MetamorphicRelation, ...]
    followups: int | None
    check_determinism: bool | None
    function: Callable[..., Any]
    batch: int = 0  # the function takes a list of inputs (``@metamorphic(batch=...)``)

    def call(self, value: Any, **fixtures: Any) -> Any:
        """The system's output for one input (through a batch of one for batch tests)."""
        if self.batch:
            return _SingleOfBatch(self.function)(value, **fixtures)
        return self.function(value, **fixtures)
