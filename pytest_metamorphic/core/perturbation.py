"""Perturbations made of independent elements, so that a failing follow-up can be reduced.

A follow-up that adds 1000 noise points, drops 40 indices or repeats 12 points is a set of
*elements*; when it violates a relation, usually a handful of them are to blame. The
engine reduces such a follow-up to a 1-minimal one (:mod:`pytest_metamorphic.core.reduction`)
when one of its ``params`` values is :class:`Reducible`: it can be restricted to a subset of
its elements and applied to the source input again.

Classes that cannot implement the protocol themselves (they live in another package, or
predate it) get an adapter through :func:`register_reducible`. Adapters for the LiDAR
perturbations are registered lazily: the first time a value from
``pytest_metamorphic.lidar.followups.perturb`` is seen,
``pytest_metamorphic.lidar.followups.minimize`` is
imported, so the core never imports the LiDAR code itself.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["Reducible", "as_reducible", "find_reducible", "register_reducible"]


@runtime_checkable
class Reducible(Protocol):
    """A follow-up transform made of ``len(self)`` independent, ordered elements.

    Optional extras the engine uses when present:

    * ``ranking(source_input, source_output, followup_output) -> sequence of int``: the
      element indices, most suspect first. ddmin splits the elements into contiguous
      chunks, so putting the likely culprits together saves SUT calls; the proof of
      1-minimality does not depend on the order.
    * ``rankings(...)`` (same arguments) -> list of such orders: tried one after the
      other, each ddmin pass starting from the previous pass's set, when a pass runs out
      of its share of the budget (a fault may depend on where points are, or on how high).
    * ``describe_elements(limit) -> list of str``: one line per element for messages.
    * ``describe_effect(source_output, followup_output) -> list of str``: what the
      elements do to the output (e.g. "hidden: pedestrian at (14.2, 1.1), 60 m away").
    * ``to_json() -> dict``: a JSON-safe description for artifacts.
    """

    def __len__(self) -> int:
        """The number of elements."""
        ...

    def restrict(self, indices: Sequence[int]) -> Reducible:
        """The same kind of transform with only the elements at ``indices`` (in order)."""
        ...

    def apply(self, source: Any) -> Any:
        """The follow-up input this transform makes from the source input."""
        ...

    def params(self) -> dict[str, Any]:
        """The transform parameters to record with the follow-up."""
        ...


_ADAPTERS: dict[type, Callable[[Any], Reducible]] = {}
# package of perturbations (its modules and subpackages) -> module whose import registers
# adapters for them
_LAZY_ADAPTERS = {
    "pytest_metamorphic.lidar.followups.perturb": "pytest_metamorphic.lidar.followups.minimize"
}


def register_reducible(cls: type, adapter: Callable[[Any], Reducible]) -> None:
    """Make instances of ``cls`` (and its subclasses) reducible through ``adapter(value)``.

    Parameters
    ----------
    cls : type
        The perturbation class, e.g. one that only has ``apply`` and ``params``.
    adapter : callable(value) -> Reducible
        Wraps a ``cls`` instance in an object implementing :class:`Reducible`.
    """
    if not isinstance(cls, type):
        raise InvalidArgument(f"cls={cls!r} must be a class")
    if not callable(adapter):
        raise InvalidArgument(f"adapter={adapter!r} must be callable(value) -> Reducible")
    _ADAPTERS[cls] = adapter


def _adapter_for(cls: type) -> Callable[[Any], Reducible] | None:
    for base in cls.__mro__:
        if base in _ADAPTERS:
            return _ADAPTERS[base]
    return None


def _lazy_registrar(cls: type) -> str | None:
    """The module whose import registers an adapter for ``cls`` or one of its bases.

    Matched by package: perturbations live in the package's modules (``perturb.noise``,
    ``perturb.edits``), and a user's subclass in any module of theirs.
    """
    for base in cls.__mro__:
        module = base.__module__
        for package, registrar in _LAZY_ADAPTERS.items():
            if module == package or module.startswith(package + "."):
                return registrar
    return None


def as_reducible(value: Any) -> Reducible | None:
    """``value`` itself when it is :class:`Reducible`, its registered adapter, or None."""
    if isinstance(value, (str, bytes, Mapping)) or value is None:
        return None
    adapter = _adapter_for(type(value))
    if adapter is None:
        lazy = _lazy_registrar(type(value))
        if lazy is not None:
            importlib.import_module(lazy)
            adapter = _adapter_for(type(value))
    if adapter is not None:
        return adapter(value)
    if isinstance(value, Reducible):
        return value
    return None


def find_reducible(params: Mapping[str, Any]) -> tuple[str, Reducible] | None:
    """The first parameter whose value is reducible, as ``(key, reducible)``, or None."""
    for key, value in params.items():
        reducible = as_reducible(value)
        if reducible is not None and len(reducible) > 0:
            return key, reducible
    return None
