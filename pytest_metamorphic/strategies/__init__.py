"""Hypothesis strategies for metamorphic testing, in the style of ``hypothesis.strategies``.

Use as ``from pytest_metamorphic import strategies as mst``. Names are looked up lazily in
the submodules listed in ``_SUBMODULES`` (each defines ``__all__``), so importing this
package costs nothing until a strategy is used.
"""

from __future__ import annotations

import importlib
from typing import Any

_SUBMODULES = ("frames", "roi", "scenes", "noise", "driving")


def _modules() -> list[Any]:
    modules = []
    for name in _SUBMODULES:
        try:
            modules.append(importlib.import_module(f"{__name__}.{name}"))
        except ModuleNotFoundError as error:
            if error.name != f"{__name__}.{name}":
                raise
    return modules


def __getattr__(name: str) -> Any:
    for module in _modules():
        if name in getattr(module, "__all__", ()):
            value = getattr(module, name)
            globals()[name] = value
            return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({name for module in _modules() for name in getattr(module, "__all__", ())})
