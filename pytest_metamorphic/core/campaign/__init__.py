"""Campaigns: violation rates from independent sampling.

Hypothesis searches for failures; it does not sample independently, so it cannot say how
*often* a relation fails. A :class:`Campaign` does: S sources, each perturbed at every size
in ``sizes`` ``followups`` times, all drawn from NumPy generators seeded by
``(seed, source index, ...)``. Every unit of work therefore has its own random stream, so
the result does not depend on the order, the process (pytest-xdist shards) or on resuming
an interrupted run.

Results are appended to a JSONL log as each source finishes (flushed and fsynced): an
interrupted campaign loses at most the source in progress and resumes where it stopped.

The package's modules follow that story: :mod:`.spec` (what a campaign is),
:mod:`.results` (tallies that merge exactly), :mod:`.log` (the JSONL log), :mod:`.source`
(one source's record), :mod:`.run` (this process), :mod:`.cluster` (a Dask cluster),
:mod:`.system` (systems built once per process), :mod:`.testing` (pytest tests),
:mod:`.gate` (when a campaign fails a build) and :mod:`.baseline` (another run's report
to compare with).
"""

from pytest_metamorphic.core.campaign.baseline import find_baseline, read_report
from pytest_metamorphic.core.campaign.gate import Gate, GateVerdict, judge_campaign
from pytest_metamorphic.core.campaign.log import (
    LogFile,
    ShardLogs,
    read_campaign_log,
    shard_indices,
)
from pytest_metamorphic.core.campaign.results import (
    CampaignResult,
    SizeCounts,
    merge_results,
    result_from_json,
)
from pytest_metamorphic.core.campaign.run import CampaignProgress, run_campaign
from pytest_metamorphic.core.campaign.spec import Campaign, CampaignInput, campaign_inputs
from pytest_metamorphic.core.campaign.system import SystemFactory
from pytest_metamorphic.core.campaign.testing import CampaignTest, campaign_test

__all__ = [
    "Campaign",
    "CampaignInput",
    "CampaignProgress",
    "CampaignResult",
    "CampaignTest",
    "Gate",
    "GateVerdict",
    "LogFile",
    "ShardLogs",
    "SizeCounts",
    "SystemFactory",
    "campaign_inputs",
    "campaign_test",
    "find_baseline",
    "judge_campaign",
    "merge_results",
    "read_campaign_log",
    "read_report",
    "result_from_json",
    "run_campaign",
    "shard_indices",
]
