"""Systems built where they run: once per process, not once per call or per task."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["SystemFactory"]


class SystemFactory:
    """A system under test that builds itself on its first call, once per process.

    A detector that loads a model (weights, a GPU context, a socket to a server) cannot
    be pickled to another process, and loading it per call would dominate the campaign.
    Give the campaign what *builds* it instead: the factory and its arguments travel
    (pytest-xdist workers, Dask workers), and each process builds the system once, on
    its first call, then reuses it.

    Parameters
    ----------
    factory : callable
        ``factory(*args, **kwargs)`` builds the system, a ``callable(input) -> output``.
        Importable by the workers (a module-level function or class).
    *args, **kwargs
        Passed to ``factory``; they must be picklable (paths, numbers, not open files).

    Examples
    --------
    >>> system = SystemFactory(load_detector, "weights.pth", device="cuda")  # doctest: +SKIP
    >>> campaign = mr1_campaign(system, name="MR1 my detector")  # doctest: +SKIP
    """

    def __init__(self, factory: Callable[..., Callable[[Any], Any]], *args: Any, **kwargs: Any):
        if not callable(factory):
            raise InvalidArgument(f"factory={factory!r} must be callable")
        self.factory = factory
        self.args = args
        self.kwargs = kwargs
        self._system: Callable[[Any], Any] | None = None
        self._lock = threading.Lock()
        self.builds = 0  # in this process: 1 after the first call

    def __call__(self, value: Any) -> Any:
        return self.system()(value)

    def system(self) -> Callable[[Any], Any]:
        """The built system (built now if this process has not built it yet)."""
        if self._system is None:
            with self._lock:
                if self._system is None:
                    built = self.factory(*self.args, **self.kwargs)
                    if not callable(built):
                        raise InvalidArgument(
                            f"{self!r} built {built!r}, which is not callable; the factory "
                            "must return the system under test (input -> output)"
                        )
                    self.builds += 1
                    self._system = built
        return self._system

    def __getstate__(self) -> dict[str, Any]:
        # What builds the system travels; the built system stays in its process.
        return {"factory": self.factory, "args": self.args, "kwargs": self.kwargs}

    def __setstate__(self, state: dict[str, Any]) -> None:
        SystemFactory.__init__(self, state["factory"], *state["args"], **state["kwargs"])

    def __repr__(self) -> str:
        name = getattr(self.factory, "__qualname__", repr(self.factory))
        arguments = [repr(a) for a in self.args] + [f"{k}={v!r}" for k, v in self.kwargs.items()]
        return f"SystemFactory({name}, {', '.join(arguments)})".replace(", )", ")")
