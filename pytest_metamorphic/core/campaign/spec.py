"""What a campaign is: its sources, follow-ups, system, relation and seeds."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pytest_metamorphic.core.campaign.identity import system_identity
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import Relation

__all__ = ["Campaign", "CampaignInput", "campaign_inputs", "draw_followup"]

LOG_VERSION = 1


@dataclass(frozen=True)
class Campaign:
    """An i.i.d. violation-rate experiment on one system under test.

    Parameters
    ----------
    name : str
    source : callable(rng, index) -> source input
        Draws (or loads) source ``index`` using ``rng`` (a ``numpy.random.Generator``).
    followup : callable(source_input, size, rng) -> follow-up input
        Perturbs the source with ``size`` elements (e.g. injected points).
    system : callable(input) -> output
        The system under test; run once per source (the output is reused) and once per
        follow-up.
    relation : Relation
        The strict relation counted as a violation (e.g. ``subset`` for MR1).
    sizes : sequence of int
        Perturbation sizes, e.g. ``(10, 100, 1000)``.
    sources : int
        Number of sources S.
    followups : int
        Follow-ups per source and size F.
    seed : int
    category : callable(element) -> str, optional
        Category of an output element (e.g. a box's label) for per-category breakdowns.
    counted : callable(output, input) -> collection, optional
        The part of an output the table counts (``|O|`` vs ``|O'|``, categories): for a scoped
        relation, what it judges (e.g. obstacles inside the ROI). Default: all of it.
    size_label : str
        What a size is, as the reports name it (default ``"n"``, the paper's noise points;
        e.g. ``"dead lasers"``, ``"visibility m"``).
    system_name : str, optional
        What the log calls the system under test (default: its qualified name). With its
        fingerprint it keeps a resumed run from blending two systems' results
        (:mod:`pytest_metamorphic.core.campaign.identity`).
    fate : callable(source_output, followup_output, indices) -> sequence of str, optional
        What became of each violated source element (``indices``: those the relation's
        verdict blames), one word each, e.g. ``"lost"``, ``"merged"``, ``"split"``
        (:func:`pytest_metamorphic.lidar.judging.fates.obstacle_fates` for obstacles).
        The reports and the chart break violations down by it.
    """

    name: str
    source: Callable[[np.random.Generator, int], Any]
    followup: Callable[[Any, int, np.random.Generator], Any]
    system: Callable[[Any], Any]
    relation: Relation
    sizes: Sequence[int] = (10, 100, 1000)
    sources: int = 1000
    followups: int = 1
    seed: int = 0
    category: Callable[[Any], str] | None = None
    counted: Callable[[Any, Any], Any] | None = None
    size_label: str = "n"
    system_name: str | None = None
    fate: Callable[[Any, Any, Sequence[int]], Sequence[str]] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise InvalidArgument(f"name={self.name!r} must be a non-empty string")
        for argument in ("source", "followup", "system"):
            if not callable(getattr(self, argument)):
                raise InvalidArgument(f"{argument}={getattr(self, argument)!r} must be callable")
        for argument in ("category", "counted", "fate"):
            value = getattr(self, argument)
            if value is not None and not callable(value):
                raise InvalidArgument(f"{argument}={value!r} must be callable or None")
        if not isinstance(self.size_label, str) or not self.size_label.strip():
            raise InvalidArgument(f"size_label={self.size_label!r} must be a non-empty string")
        if self.system_name is not None and (
            not isinstance(self.system_name, str) or not self.system_name.strip()
        ):
            raise InvalidArgument(f"system_name={self.system_name!r} must be a non-empty string")
        if not isinstance(self.relation, Relation):
            raise InvalidArgument(f"relation={self.relation!r} must be a Relation")
        sizes = tuple(self.sizes)
        if not sizes or any(not isinstance(n, int) or n < 0 for n in sizes):
            raise InvalidArgument(f"sizes={self.sizes!r} must be a non-empty list of ints >= 0")
        object.__setattr__(self, "sizes", sizes)
        for argument in ("sources", "followups"):
            value = getattr(self, argument)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InvalidArgument(f"{argument}={value!r} must be an int >= 1")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidArgument(f"seed={self.seed!r} must be an int >= 0")

    def header(self) -> dict[str, Any]:
        """What identifies this campaign's results: a log is resumable only if it matches."""
        return {
            "version": LOG_VERSION,
            "campaign": self.name,
            "relation": self.relation.name,
            "seed": self.seed,
            "sources": self.sources,
            "sizes": list(self.sizes),
            "followups": self.followups,
            # Only when it says more than "n": logs written before it existed still resume.
            **({"size_label": self.size_label} if self.size_label != "n" else {}),
        }

    def system_identity(self) -> dict[str, str]:
        """The system under test's name and fingerprint, recorded in the log's header."""
        return system_identity(self.system, self.system_name)

    def source_rng(self, index: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, index])

    def followup_rng(self, index: int, size_index: int, followup: int) -> np.random.Generator:
        # A longer entropy tuple than source_rng's, so the streams never coincide.
        return np.random.default_rng([self.seed, index, 1 + size_index, followup])


def draw_followup(
    campaign: Campaign, source_input: Any, index: int, size_index: int, f: int
) -> tuple[Any, Mapping[str, Any]]:
    """Follow-up ``f`` of source ``index`` at ``sizes[size_index]``: (input, params)."""
    size = campaign.sizes[size_index]
    followup = campaign.followup(source_input, size, campaign.followup_rng(index, size_index, f))
    return getattr(followup, "input", followup), getattr(followup, "params", {})


@dataclass(frozen=True)
class CampaignInput:
    """One input a campaign runs its system on (see :func:`campaign_inputs`).

    ``size`` and ``followup`` are None for the source input itself.
    """

    source: int
    size: int | None
    followup: int | None
    input: Any
    params: Mapping[str, Any] = field(default_factory=dict)


def campaign_inputs(
    campaign: Campaign, sources: Iterable[int] | None = None
) -> Iterator[CampaignInput]:
    """Every input of the campaign (each source, then its follow-ups), as a run draws them.

    The same seeds as :func:`run_campaign`, so the inputs are exactly those a run gives
    its system: the basis of offline evaluation (export the inputs, run a detector over
    them anywhere, evaluate its predictions).
    """
    for index in range(campaign.sources) if sources is None else sources:
        source_input = campaign.source(campaign.source_rng(index), index)
        yield CampaignInput(index, None, None, source_input)
        for size_index, size in enumerate(campaign.sizes):
            for f in range(campaign.followups):
                value, params = draw_followup(campaign, source_input, index, size_index, f)
                yield CampaignInput(index, size, f, value, params)
