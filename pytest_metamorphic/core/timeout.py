"""Per-call time limits for systems under test that may hang.

A detector stuck on a GPU or a deadlocked library must not hang the whole test run.
:func:`call_with_timeout` runs the call in a daemon thread and stops *waiting* for it
after ``seconds``, raising :class:`~pytest_metamorphic.core.errors.SystemTimeout`.
Python cannot stop a thread, so a call that never returns keeps running in the
background (it cannot block the interpreter's exit); systems in another process
(:class:`~pytest_metamorphic.lidar.systems.process.ProcessDetector`) are killed instead.
"""

from __future__ import annotations

import contextvars
import math
import threading
from collections.abc import Callable
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument, SystemTimeout

__all__ = ["call_with_timeout", "check_timeout"]


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
    if seconds is None:
        return fn(*args, **kwargs)
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
        raise SystemTimeout(
            f"{what or 'the call'} did not return within {seconds:g} s (time limit); it keeps "
            "running in the background",
            seconds=seconds,
        )
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("value")
