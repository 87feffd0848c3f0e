"""Campaigns as pytest tests: fixed shards that pytest-xdist spreads over its workers."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pytest_metamorphic.core.campaign.spec import Campaign
from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["campaign_test"]


def campaign_test(campaign: Campaign, *, shards: int = 8) -> Callable[..., None]:
    """A pytest test that runs ``campaign`` under ``--mt-campaign`` (skipped otherwise).

    The test is parametrized over ``shards`` fixed shards of the sources, so pytest-xdist
    spreads them over workers; the plugin merges the shards into one result, identical to
    a one-process run. Assign it to a module-level name starting with ``test_``.
    """
    import pytest

    if not isinstance(campaign, Campaign):
        raise InvalidArgument(f"campaign={campaign!r} must be a Campaign")
    if isinstance(shards, bool) or not isinstance(shards, int) or not 1 <= shards <= 1000:
        raise InvalidArgument(f"shards={shards!r} must be an int between 1 and 1000")

    @pytest.mark.parametrize("mt_shard", range(shards), ids=[f"shard{i}" for i in range(shards)])
    def test(mt_shard: int) -> None:
        """Body intentionally empty: the plugin runs the shard around this call."""

    marked: Any = test  # the plugin finds campaign tests by this attribute
    marked._metamorphic_campaign = (campaign, shards)
    test.__name__ = test.__qualname__ = f"test_campaign_{_identifier(campaign.name)}"
    return test


def _identifier(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name).strip("_").lower() or "campaign"
