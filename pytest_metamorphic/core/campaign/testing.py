"""Campaigns as pytest tests: shards that pytest-xdist spreads over its workers, and a
gate that turns the merged result into a verdict."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from pytest_metamorphic.core.campaign.gate import DEFAULT_CONFIDENCE, Gate
from pytest_metamorphic.core.campaign.spec import Campaign
from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["CampaignTest", "campaign_test"]


@dataclass(frozen=True)
class CampaignTest:
    """What :func:`campaign_test` attaches to its test for the plugin.

    ``shards`` None: one shard per pytest-xdist worker (one without xdist); ``cases``
    None: the ``--mt-campaign-cases`` option.
    """

    campaign: Campaign
    gate: Gate
    shards: int | None = None
    cases: int | None = None

    def shard_count(self, workers: int) -> int:
        """Shards for ``workers`` processes: never more than there are sources, so no
        shard test is empty."""
        return max(1, min(self.shards or workers, self.campaign.sources))


def campaign_test(
    campaign: Campaign,
    *,
    max_rate: float | Mapping[int, float] | None = 0.0,
    expect_violations: bool = False,
    confidence: float = DEFAULT_CONFIDENCE,
    allow_crashes: bool = False,
    baseline_margin: float = 0.0,
    shards: int | None = None,
    cases: int | None = None,
) -> Callable[..., None]:
    """A pytest test that runs ``campaign`` under ``--mt-campaign`` (skipped otherwise).

    The test passes or fails by the campaign's gate
    (:mod:`pytest_metamorphic.core.campaign.gate`), judged on the result merged over all
    its shards. By default one violating pair fails it, as a ``@metamorphic`` test fails.
    Assign it to a module-level name starting with ``test_``.

    Parameters
    ----------
    campaign : Campaign
    max_rate : float, mapping of size -> float, or None
        Fail where the violation rate is significantly above this (the Wilson lower
        bound exceeds it); 0 fails on one violation; None: no threshold.
    expect_violations : bool
        The system has a fault the relation must detect (a mutant): fail when no pair
        violates, pass (and say so) when some do.
    confidence : float
        Family-wise confidence of the threshold and baseline tests over the sizes.
    allow_crashes : bool
        Pairs or sources that crash the system do not fail the campaign.
    baseline_margin : float
        Under ``--mt-baseline``: how much higher than the baseline's a rate may be.
    shards : int, optional
        Shard tests, for pytest-xdist; default: one per xdist worker (one without it),
        never more than the campaign has sources. The merged result is the same.
    cases : int, optional
        Violations per size saved as replayable artifacts (default: ``--mt-campaign-cases``).
    """
    if not isinstance(campaign, Campaign):
        raise InvalidArgument(f"campaign={campaign!r} must be a Campaign")
    if shards is not None and (
        isinstance(shards, bool) or not isinstance(shards, int) or not 1 <= shards <= 1000
    ):
        raise InvalidArgument(f"shards={shards!r} must be an int between 1 and 1000, or None")
    if cases is not None and (isinstance(cases, bool) or not isinstance(cases, int) or cases < 0):
        raise InvalidArgument(f"cases={cases!r} must be an int >= 0, or None")
    gate = Gate(
        max_rate=None if expect_violations and max_rate == 0.0 else max_rate,
        expect_violations=expect_violations,
        confidence=confidence,
        allow_crashes=allow_crashes,
        margin=baseline_margin,
    )

    def test(mt_shard: int) -> None:
        """Body intentionally empty: the plugin parametrizes the shards and runs each
        around this call."""

    marked: Any = test  # the plugin finds campaign tests by this attribute
    marked._metamorphic_campaign = CampaignTest(campaign, gate, shards, cases)
    test.__name__ = test.__qualname__ = f"test_campaign_{_identifier(campaign.name)}"
    return test


def _identifier(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name).strip("_").lower() or "campaign"
