"""The outcome of checking one relation: its own module, importing nothing of the
package, so that the relations and the errors that carry a verdict can both use it
without an import circle (relations -> errors, errors -> verdict)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Verdict"]


@dataclass(frozen=True)
class Verdict:
    """The outcome of checking one relation on one source/follow-up pair.

    ``bool(verdict)`` is ``verdict.holds``. ``explanation`` says what differs, in words a
    failure message can show as is; ``details`` holds machine-readable facts (unmatched
    indices, counts) for reports and artifacts.
    """

    holds: bool
    relation: str
    explanation: str = ""
    details: Mapping[str, Any] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return self.holds
