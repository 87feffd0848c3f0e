"""pytest-metamorphic: Hypothesis-based metamorphic testing for pytest.

Public API (imported lazily, so that loading the pytest plugin stays cheap)::

    from pytest_metamorphic import metamorphic, relations, MetamorphicRelation, Followup
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.5.0"  # the only place; pyproject.toml reads it

# name -> (module, attribute or None for the module itself)
_LAZY: dict[str, tuple[str, str | None]] = {
    "metamorphic": ("pytest_metamorphic.core.engine", "metamorphic"),
    "MetamorphicRelation": ("pytest_metamorphic.core.engine", "MetamorphicRelation"),
    "Followup": ("pytest_metamorphic.core.engine", "Followup"),
    "MetamorphicCase": ("pytest_metamorphic.core.engine", "MetamorphicCase"),
    "relations": ("pytest_metamorphic.relations", None),
    "Verdict": ("pytest_metamorphic.core.relations", "Verdict"),
    "Relation": ("pytest_metamorphic.core.relations", "Relation"),
    "DataError": ("pytest_metamorphic.core.errors", "DataError"),
    "InvalidArgument": ("pytest_metamorphic.core.errors", "InvalidArgument"),
    "MetamorphicError": ("pytest_metamorphic.core.errors", "MetamorphicError"),
    "MetamorphicViolation": ("pytest_metamorphic.core.errors", "MetamorphicViolation"),
    "NondeterministicSystemError": (
        "pytest_metamorphic.core.errors",
        "NondeterministicSystemError",
    ),
    "SystemUnderTestCrash": ("pytest_metamorphic.core.errors", "SystemUnderTestCrash"),
    "NothingTestedWarning": ("pytest_metamorphic.core.errors", "NothingTestedWarning"),
    "ProtocolWarning": ("pytest_metamorphic.core.errors", "ProtocolWarning"),
}

__all__ = [  # noqa: RUF022 - grouped: API, relations, errors
    "Followup",
    "MetamorphicCase",
    "MetamorphicRelation",
    "metamorphic",
    "Relation",
    "Verdict",
    "relations",
    "DataError",
    "InvalidArgument",
    "MetamorphicError",
    "MetamorphicViolation",
    "NondeterministicSystemError",
    "NothingTestedWarning",
    "ProtocolWarning",
    "SystemUnderTestCrash",
    "__version__",
]

if TYPE_CHECKING:  # pragma: no cover
    from pytest_metamorphic import relations
    from pytest_metamorphic.core.engine import (
        Followup,
        MetamorphicCase,
        MetamorphicRelation,
        metamorphic,
    )
    from pytest_metamorphic.core.errors import (
        DataError,
        InvalidArgument,
        MetamorphicError,
        MetamorphicViolation,
        NondeterministicSystemError,
        NothingTestedWarning,
        ProtocolWarning,
        SystemUnderTestCrash,
    )
    from pytest_metamorphic.core.relations import Relation, Verdict


def __getattr__(name: str) -> Any:
    try:
        module_name, attribute = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'pytest_metamorphic' has no attribute {name!r}") from None
    module = importlib.import_module(module_name)
    value = module if attribute is None else getattr(module, attribute)
    globals()[name] = value
    return value
