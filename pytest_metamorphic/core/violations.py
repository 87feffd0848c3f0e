"""What is known about a violation (:class:`ViolationRecord`) and the message it raises."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from hypothesis.errors import HypothesisException

from pytest_metamorphic.core.cases import Followup
from pytest_metamorphic.core.comparison import describe_outputs, describe_params
from pytest_metamorphic.core.errors import (
    MetamorphicViolation,
)
from pytest_metamorphic.core.reduction import Reduction
from pytest_metamorphic.core.relations import Verdict
from pytest_metamorphic.core.stats import (
    Recorder,
)

__all__ = ["ViolationRecord"]

_MAX_EXPLAINED = 3  # unmatched elements explained one per line; the rest counted


@dataclass(frozen=True)
class ViolationRecord:
    """Everything known about one violation, for the message and for artifacts.

    Attributes
    ----------
    nodeid : str
        The pytest node id ("" outside the plugin).
    relation, check : str
        The metamorphic relation's name and the output relation's name.
    index, total : int
        Which follow-up of how many.
    source, followup
        The source input and the violating follow-up as drawn (before reduction).
    source_output, followup_output, verdict
        The outputs and the relation's verdict on that follow-up.
    reduction : Reduction or None
        The 1-minimal follow-up, when the transform was reducible and this was the final run.
    reduction_note : str
        Why a reduction is missing although one was attempted.
    seed : dict
        Hypothesis' seed for the run (``{"seed": int or None, "derandomize": bool}``).
    """

    nodeid: str
    relation: str
    check: str
    index: int
    total: int
    source: Any
    followup: Followup
    source_output: Any
    followup_output: Any
    verdict: Verdict
    reduction: Reduction | None = None
    reduction_note: str = ""
    seed: Mapping[str, Any] = field(default_factory=dict)

    @property
    def minimal_followup(self) -> Followup:
        """The reduced follow-up when there is one, else the follow-up as drawn."""
        if self.reduction is None:
            return self.followup
        return Followup(self.reduction.followup_input, self.reduction.params)

    @property
    def minimal_output(self) -> Any:
        return self.followup_output if self.reduction is None else self.reduction.output

    @property
    def minimal_verdict(self) -> Verdict:
        return self.verdict if self.reduction is None else self.reduction.verdict


def _in_final_run() -> bool:
    """True in Hypothesis' last replay of a failing example, and outside Hypothesis."""
    from hypothesis.control import current_build_context

    try:
        return bool(current_build_context().is_final)
    except HypothesisException:  # no build context: called directly, e.g. by a replay
        return True


def _hypothesis_seed() -> dict[str, Any]:
    """The seed Hypothesis used for this test run (``@seed``, generated, or derandomized)."""
    from hypothesis.control import current_build_context

    try:
        wrapped = current_build_context().wrapped_test
    except HypothesisException:
        return {"seed": None, "derandomize": False}
    # Private attributes, read defensively: Hypothesis prints the same seed on failures.
    seed = getattr(wrapped, "_hypothesis_internal_use_seed", None)
    if seed is None:
        seed = getattr(wrapped, "_hypothesis_internal_use_generated_seed", None)
    chosen = getattr(wrapped, "_hypothesis_internal_use_settings", None)
    return {
        "seed": seed if isinstance(seed, int) else None,
        "derandomize": bool(getattr(chosen, "derandomize", False)),
    }


def _save(recorder: Recorder, record: ViolationRecord, final: bool) -> str | None:
    if recorder.on_violation is None:
        return None
    return recorder.on_violation(record, final)


def _violation_error(record: ViolationRecord, saved: str | None) -> MetamorphicViolation:
    reduction = record.reduction
    verdict = record.minimal_verdict
    item = record.minimal_followup
    lines = [
        f"metamorphic relation {record.relation!r} violated on follow-up {record.index} of "
        f"{record.total} (check: {verdict.relation})",
    ]
    if reduction is not None:
        lines.append(f"  minimal follow-up: {reduction.summary()}")
        lines.extend(f"    {line}" for line in reduction.element_lines())
        lines.extend(f"  {line}" for line in reduction.effect_lines(record.source_output))
    elif record.reduction_note:
        lines.append(f"  {record.reduction_note}")
    if item.params:
        lines.append(f"  transform parameters: {describe_params(item.params)}")
    # One line per unmatched element (a subset check may list several), the first few.
    parts = re.split(r"; (?=element #)", verdict.explanation)
    lines.extend(f"  {part}" for part in parts[:_MAX_EXPLAINED])
    if len(parts) > _MAX_EXPLAINED:
        lines.append(f"  ... and {len(parts) - _MAX_EXPLAINED} more element(s) without a match")
    if reduction is not None and record.verdict.explanation != verdict.explanation:
        lines.append(f"  with all {reduction.original_size} elements: {record.verdict.explanation}")
    lines.extend(
        f"  {line}" for line in describe_outputs(record.source_output, record.minimal_output)
    )
    if saved:
        lines.append(f"  artifacts: {saved}")
    error = MetamorphicViolation("\n".join(lines), relation=record.relation, verdict=verdict)
    error.followup = item
    error.source_output = record.source_output
    error.followup_output = record.minimal_output
    error.record = record
    return error
