"""Which system a campaign log holds results of, so a resume cannot blend two systems.

A log's header names the campaign (name, relation, seed, sizes); since 0.5 it also records
the system under test: a name (``Campaign(system_name=...)``, else the system's qualified
name) and a fingerprint of what can be seen of it without running it (its type and its
parameters, from its ``repr`` with memory addresses removed). Each source's record keeps a
digest of the system's output on that source, so a resume can also re-run one logged
source and compare: a detector retrained in place, same class and parameters, is caught
by its outputs.
"""

from __future__ import annotations

import hashlib
import re
from typing import Any

from pytest_metamorphic.core.comparison import value_digest

__all__ = ["input_digest", "output_digest", "system_identity"]

# Outputs and inputs are digested like any value (equal values, equal digests across
# processes): a digest of a source input tells two sources that load the same frame apart
# from two that differ.
output_digest = value_digest
input_digest = value_digest

_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def _qualified_name(system: Any) -> str:
    target = system if callable(system) and hasattr(system, "__qualname__") else type(system)
    module = getattr(target, "__module__", "") or ""
    return f"{module}.{getattr(target, '__qualname__', type(system).__name__)}".lstrip(".")


def system_identity(system: Any, name: str | None = None) -> dict[str, str]:
    """``{"name", "type", "fingerprint"}`` of a system under test.

    Parameters
    ----------
    system : callable
        The system (a function, a detector object, a factory).
    name : str, optional
        What the user calls it; the default is its qualified name.
    """
    qualified = _qualified_name(system)
    seen = _ADDRESS.sub("", repr(system))
    fingerprint = hashlib.sha1(f"{qualified}\n{seen}".encode()).hexdigest()[:16]
    return {"name": name or qualified, "type": qualified, "fingerprint": fingerprint}
