"""What runs on Dask workers: the campaign, installed by a worker plugin, and its tasks.

Imported only where Dask distributed is installed (by :mod:`.cluster`, and on workers).
"""

from __future__ import annotations

import os
import pickle
from typing import Any

from distributed import get_worker
from distributed.diagnostics.plugin import WorkerPlugin

from pytest_metamorphic.core.campaign.source import run_source
from pytest_metamorphic.core.campaign.spec import Campaign

# token -> the campaign, loaded once in this worker process (with the system it builds).
CAMPAIGNS: dict[str, Campaign] = {}


class CampaignPlugin(WorkerPlugin):
    """Installs a campaign on every worker, including workers that join or are restarted
    later (a scattered object dies with the last worker holding it; a plugin does not)."""

    idempotent = False

    def __init__(self, token: str, payload: bytes) -> None:
        self.token = token
        self.payload = payload
        self.name = token

    def setup(self, worker: Any) -> None:
        CAMPAIGNS[self.token] = pickle.loads(self.payload)

    def teardown(self, worker: Any) -> None:
        CAMPAIGNS.pop(self.token, None)


def preflight(payload: bytes, index: int) -> dict[str, Any]:
    """Can this worker load the campaign and its source ``index``? And is it tuned?"""
    campaign = pickle.loads(payload)
    campaign.source(campaign.source_rng(index), index)
    return {"trim": os.environ.get("MALLOC_TRIM_THRESHOLD_")}


def run_unit(token: str, indices: list[int], timeout: float | None) -> dict[str, Any]:
    """The records of some sources, and which worker ran them."""
    campaign = CAMPAIGNS[token]
    records = [run_source(campaign, index, timeout) for index in indices]
    return {"worker": get_worker().address, "records": records}


async def warm_up() -> None:
    """Import what campaigns run (numpy, scipy, the LiDAR domain) before the first task,
    in a thread: the worker keeps answering meanwhile (``Client.run(wait=False)`` needs a
    coroutine)."""
    import asyncio

    await asyncio.get_running_loop().run_in_executor(None, _import_domains)


def _import_domains() -> None:
    import contextlib
    import importlib

    for module in ("pytest_metamorphic.lidar.campaign", "pytest_metamorphic.driving.campaign"):
        # An optional extra missing: the campaign will say so itself.
        with contextlib.suppress(ImportError):
            importlib.import_module(module)
