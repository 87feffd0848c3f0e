"""Systems that take a batch of inputs in one call (an opt-in protocol).

A learned model is fast in batches and slow one input at a time. A system under test may
therefore offer, next to its plain call ``system(x) -> y``, a method
``system.run_batch(xs) -> ys``: one output per input, in order, each the output
``system(x)`` would give. Campaigns (in this process and on Dask workers) then run a
source together with its follow-ups in batches of up to ``system.batch_size`` inputs
(default :data:`DEFAULT_BATCH_SIZE`); ``@metamorphic(batch=True)`` does the same for
Hypothesis tests, whose decorated function then takes a list of inputs.

:func:`batched` makes such a system out of two functions, or out of one batch function.
When a batch call raises, its inputs are run again one at a time, so a crash is blamed
on the input that causes it, as without batches.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol, runtime_checkable

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = [
    "DEFAULT_BATCH_SIZE",
    "BatchSystem",
    "FixturedBatch",
    "SingleOfBatch",
    "batch_size_of",
    "batched",
    "check_batch_outputs",
    "check_batch_request",
    "supports_batches",
]

DEFAULT_BATCH_SIZE = 8


@runtime_checkable
class BatchSystem(Protocol):
    """A system under test that also runs many inputs in one call."""

    def __call__(self, value: Any, /) -> Any: ...

    def run_batch(self, values: Sequence[Any], /) -> Sequence[Any]: ...


def supports_batches(system: Any) -> bool:
    """Whether ``system`` offers ``run_batch`` (the opt-in batch protocol); a
    ``batch_size`` of None says it does not (e.g. a process that takes one frame)."""
    return (
        callable(getattr(system, "run_batch", None))
        and getattr(system, "batch_size", DEFAULT_BATCH_SIZE) is not None
    )


def batch_size_of(system: Any) -> int:
    """How many inputs ``system`` takes per batch call (its ``batch_size``, else 8)."""
    size = getattr(system, "batch_size", DEFAULT_BATCH_SIZE)
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise InvalidArgument(f"{system!r} has batch_size={size!r}; it must be an int >= 1")
    return size


def check_batch_outputs(outputs: Any, count: int, system: Any) -> list[Any]:
    """``outputs`` of a batch call of ``count`` inputs as a list; a clear error otherwise."""
    if isinstance(outputs, (str, bytes)) or not isinstance(outputs, Sequence):
        raise InvalidArgument(
            f"{system!r}.run_batch returned {type(outputs).__name__}; it must return a "
            f"sequence of {count} outputs, one per input"
        )
    if len(outputs) != count:
        raise InvalidArgument(
            f"{system!r}.run_batch returned {len(outputs)} outputs for {count} inputs"
        )
    return list(outputs)


class _Batched:
    """What :func:`batched` returns (picklable when its functions are)."""

    def __init__(
        self,
        single: Callable[[Any], Any] | None,
        batch: Callable[[Sequence[Any]], Sequence[Any]],
        batch_size: int,
    ) -> None:
        self.single = single
        self.batch = batch
        self.batch_size = batch_size

    def __call__(self, value: Any) -> Any:
        if self.single is not None:
            return self.single(value)
        return check_batch_outputs(self.batch([value]), 1, self)[0]

    def run_batch(self, values: Sequence[Any]) -> list[Any]:
        return check_batch_outputs(self.batch(list(values)), len(values), self)

    def __repr__(self) -> str:
        name = getattr(self.batch, "__qualname__", repr(self.batch))
        return f"batched({name}, batch_size={self.batch_size})"


def batched(
    batch: Callable[[Sequence[Any]], Sequence[Any]],
    *,
    single: Callable[[Any], Any] | None = None,
    batch_size: int = DEFAULT_BATCH_SIZE,
) -> BatchSystem:
    """A system under test that runs batches with ``batch``.

    Parameters
    ----------
    batch : callable(list of inputs) -> sequence of outputs
        One output per input, in order.
    single : callable(input) -> output, optional
        The plain call; by default ``batch([x])[0]``.
    batch_size : int
        Most inputs per batch call.

    Example: ``mr1_campaign(batched(detector.detect_batch), name=...)``.
    """
    if not callable(batch):
        raise InvalidArgument(f"batch={batch!r} must be callable (list of inputs -> outputs)")
    if single is not None and not callable(single):
        raise InvalidArgument(f"single={single!r} must be callable or None")
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise InvalidArgument(f"batch_size={batch_size!r} must be an int >= 1")
    return _Batched(single, batch, batch_size)


class SystemCalls:
    """Runs a system under test on lists of inputs: in batches when it offers them.

    Parameters
    ----------
    system : callable, optionally with ``run_batch``
    timeout : float or None
        Seconds per input; a batch of k inputs may take ``k * timeout``.
    """

    def __init__(self, system: Callable[[Any], Any], timeout: float | None) -> None:
        self.system = system
        self.timeout = timeout
        self.batches = supports_batches(system)
        self.batch_size = batch_size_of(system) if self.batches else 1

    def run(
        self, values: Sequence[Any], whats: Sequence[str]
    ) -> list[tuple[Any, BaseException | None]]:
        """``(output, None)`` or ``(None, error)`` for every input, in order."""
        from pytest_metamorphic.core.timeout import call_with_timeout

        if self.batches and len(values) > 1:
            seconds = None if self.timeout is None else self.timeout * len(values)
            try:
                outputs = call_with_timeout(
                    self.system.run_batch,  # type: ignore[attr-defined]
                    list(values),
                    seconds=seconds,
                    what=f"a batch of {len(values)} inputs ({whats[0]}, ...)",
                )
                return [
                    (value, None)
                    for value in check_batch_outputs(outputs, len(values), self.system)
                ]
            except Exception:
                pass  # run them one by one: the crash is then blamed on its own input
        results: list[tuple[Any, BaseException | None]] = []
        for value, what in zip(values, whats, strict=True):
            try:
                results.append(
                    (call_with_timeout(self.system, value, seconds=self.timeout, what=what), None)
                )
            except Exception as error:
                results.append((None, error))
        return results


# -- what @metamorphic(batch=...) calls ------------------------------------------------------


def check_batch_request(batch: Any) -> int:
    """The batch size ``batch=`` asks for (0: no batches)."""
    if batch is False:
        return 0
    if batch is True:
        return DEFAULT_BATCH_SIZE
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise InvalidArgument(f"batch={batch!r} must be True, False or a batch size >= 1")
    return batch


class SingleOfBatch:
    """A batch function called with one input: ``fn([x], **fixtures)[0]``."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.fn = fn

    def __call__(self, value: Any, **fixtures: Any) -> Any:
        return check_batch_outputs(self.fn([value], **fixtures), 1, self.fn)[0]


class FixturedBatch:
    """The decorated batch function with the test's fixtures bound, as a batch system."""

    def __init__(self, fn: Any, fixtures: dict[str, Any], batch_size: int) -> None:
        self.fn, self.fixtures, self.batch_size = fn, fixtures, batch_size

    def __call__(self, value: Any) -> Any:
        return SingleOfBatch(self.fn)(value, **self.fixtures)

    def run_batch(self, values: Sequence[Any]) -> Any:
        return self.fn(list(values), **self.fixtures)

    def __repr__(self) -> str:
        return getattr(self.fn, "__qualname__", repr(self.fn))
