"""Per-call time limits for systems under test that may hang.

A detector stuck on a GPU or a deadlocked library must not hang the whole test run.
:func:`call_with_timeout` runs the call in a daemon thread and stops *waiting* for it
after ``seconds``, raising :class:`~pytest_metamorphic.core.errors.SystemTimeout`.
Python cannot stop a thread, so a call that never returns keeps running in the
background (it cannot block the interpreter's exit); at most :data:`MAX_ABANDONED` such
calls are left running at once, after which new calls are refused at once. A call stuck
in C code that holds the GIL (a catastrophic regular expression, some native libraries)
cannot even be waited for with a timer: :func:`call_isolated` runs each call in a forked
child process, killed at the limit (``@metamorphic(isolate=True)``). Systems in another
process (:class:`~pytest_metamorphic.lidar.systems.process.ProcessDetector`) are killed
on their own limit.
"""

from __future__ import annotations

import contextvars
import math
import multiprocessing
import os
import pickle
import threading
from collections.abc import Callable
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument, SystemTimeout

__all__ = ["MAX_ABANDONED", "call_isolated", "call_with_timeout", "check_timeout"]

MAX_ABANDONED = 16
"""Calls past their limit left running in background threads before new calls are refused."""

_abandoned: set[threading.Thread] = set()
_abandoned_lock = threading.Lock()


def check_timeout(value: Any, name: str = "timeout") -> float | None:
    """``value`` as seconds (None: no limit); anything but a positive number raises."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name}={value!r} must be a positive number of seconds or None")
    if not (math.isfinite(value) and value > 0):
        raise InvalidArgument(f"{name}={value!r} must be a positive number of seconds or None")
    return float(value)


def call_with_timeout(
    fn: Callable[..., Any], *args: Any, seconds: float | None, what: str = "", **kwargs: Any
) -> Any:
    """``fn(*args, **kwargs)``, or :class:`SystemTimeout` after ``seconds`` (None: wait).

    Exceptions of the call are re-raised as they are. Context variables (the plugin's
    recorder) are visible inside the call.
    """
    __tracebackhide__ = True  # a crash's traceback starts at the user's system
    if seconds is None:
        return fn(*args, **kwargs)
    with _abandoned_lock:
        _abandoned.difference_update([t for t in _abandoned if not t.is_alive()])
        if len(_abandoned) >= MAX_ABANDONED:
            raise SystemTimeout(
                f"{len(_abandoned)} earlier calls of the system are still running past their "
                f"time limit; {what or 'this call'} is not started (use isolate=True for a "
                "system that must be stopped, not abandoned)",
                seconds=seconds,
            )
    context = contextvars.copy_context()
    outcome: dict[str, Any] = {}

    def target() -> None:
        try:
            outcome["value"] = context.run(fn, *args, **kwargs)
        except BaseException as error:  # handed to the caller's thread
            outcome["error"] = error

    worker = threading.Thread(target=target, name=f"mt-call {what}"[:60], daemon=True)
    worker.start()
    worker.join(seconds)
    if worker.is_alive():
        with _abandoned_lock:
            _abandoned.add(worker)
        raise SystemTimeout(
            f"{what or 'the call'} did not return within {seconds:g} s (time limit); it keeps "
            "running in the background",
            seconds=seconds,
        )
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("value")


def call_isolated(
    fn: Callable[..., Any], *args: Any, seconds: float | None, what: str = "", **kwargs: Any
) -> Any:
    """``fn(*args, **kwargs)`` in a forked child process, killed after ``seconds``.

    For systems that hold the GIL or cannot be abandoned (a thread cannot be stopped, a
    process can). The output and any exception come back pickled, so they must pickle;
    the call sees a copy of this process (changes it makes to module state are lost).
    POSIX only (``fork``).

    Raises
    ------
    SystemTimeout
        Still running after ``seconds``: the child is killed.
    """
    if not hasattr(os, "fork"):  # pragma: no cover - Windows
        raise InvalidArgument("isolate=True needs fork (POSIX)")
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_isolated_child, args=(send, fn, args, kwargs), daemon=True)
    child.start()
    send.close()
    try:
        if not receive.poll(seconds):
            raise SystemTimeout(
                f"{what or 'the call'} did not return within {seconds:g} s (time limit); its "
                "process was killed",
                seconds=float(seconds or 0),
            )
        try:
            status, value = receive.recv()
        except EOFError:
            child.join(5)
            during = what or "the call"
            raise RuntimeError(
                f"the isolated process died (exit code {child.exitcode}) during {during}"
            ) from None
    finally:
        if child.is_alive():
            child.kill()
        child.join(5)
        receive.close()
    if status == "error":
        raise value
    return value


def _isolated_child(send: Any, fn: Callable[..., Any], args: Any, kwargs: Any) -> None:
    try:
        result: tuple[str, Any] = ("value", fn(*args, **kwargs))
    except BaseException as error:
        result = ("error", error)
    try:
        send.send(result)
    except (pickle.PicklingError, TypeError, AttributeError) as error:
        kind = "output" if result[0] == "value" else "exception"
        send.send(("error", RuntimeError(f"the isolated call's {kind} cannot be pickled: {error}")))
    send.close()
