"""Deterministic Hypothesis searches for tests that assert on *what* Hypothesis finds.

A user's shell has no ``CI`` variable, so Hypothesis searches randomly there, and
``find()`` may shrink to another, equally minimal, example than it does under CI's
derandomized profile. Tests that assert on the example found (its exact values, which of
several minimal examples it is) use :func:`find` from here: derandomized and without the
example database, so every machine and every run finds the same example.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import hypothesis
from hypothesis import HealthCheck, settings
from hypothesis.strategies import SearchStrategy

T = TypeVar("T")

DETERMINISTIC = settings(
    database=None,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
"""Settings for a test whose assertion depends on the examples Hypothesis draws."""


def find(
    strategy: SearchStrategy[T],
    condition: Callable[[T], Any],
    *,
    settings: settings | None = None,
) -> T:
    """``hypothesis.find`` with ``settings`` on top of :data:`DETERMINISTIC`.

    The result no longer depends on the run's seed, the ``CI`` variable or a database.
    """
    chosen = (
        DETERMINISTIC
        if settings is None
        else hypothesis.settings(settings, database=None, derandomize=True)
    )
    return hypothesis.find(strategy, condition, settings=chosen)
