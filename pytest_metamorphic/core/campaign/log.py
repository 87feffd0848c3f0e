"""The campaign log: a header line, then one JSON record per finished source.

Records are flushed and fsynced as they come, so an interrupted run loses at most the
sources in progress; a log is read back to resume or to report a partial run.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.campaign.results import CampaignResult, SizeCounts, tally
from pytest_metamorphic.core.campaign.spec import Campaign
from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["open_log", "read_campaign_log", "read_log", "set_aside", "shard_indices"]


def read_log(path: Path, header: dict[str, Any]) -> Iterator[dict[str, Any]]:
    with path.open(encoding="utf-8") as handle:
        lines = handle.read().splitlines()
    if not lines:
        return
    try:
        found = json.loads(lines[0])
    except json.JSONDecodeError:
        raise InvalidArgument(f"{path}: first line is not a campaign header") from None
    if found != header:
        raise InvalidArgument(
            f"{path} holds results of a different campaign ({found}); expected {header}. "
            "Use another log path or the same seed and parameters."
        )
    for number, line in enumerate(lines[1:], start=2):
        try:
            yield json.loads(line)
        except json.JSONDecodeError:
            if number == len(lines):
                return  # a line cut off by an interruption: that source is simply redone
            raise InvalidArgument(f"{path}:{number}: corrupt campaign record") from None


def set_aside(path: Path) -> None:
    """Keep an earlier log instead of overwriting it: nothing recorded is lost."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    target = path.with_name(f"{path.stem}.{stamp}{path.suffix}")
    counter = 1
    while target.exists():
        target = path.with_name(f"{path.stem}.{stamp}-{counter}{path.suffix}")
        counter += 1
    path.rename(target)


def read_campaign_log(
    campaign: Campaign,
    log: Path | str | None,
    *,
    shard: int = 0,
    shards: int = 1,
    keep_examples: int = 20,
) -> CampaignResult:
    """The result of the sources of one shard that ``log`` records as finished.

    Nothing runs: this is what an interrupted run had done (an empty result when the log
    is absent or empty). Raises InvalidArgument when the log belongs to another campaign.
    """
    header = campaign.header()
    result = CampaignResult(
        header, {size: SizeCounts() for size in campaign.sizes}, keep_examples=keep_examples
    )
    path = None if log is None else Path(log)
    if path is None or not path.exists() or not path.stat().st_size:
        return result
    indices = shard_indices(campaign.sources, shard, shards)
    for record in read_log(path, header):
        if record["source"] in indices and record["source"] not in result.sources_done:
            tally(result, record)
    result._trim_examples()
    return result


@contextmanager
def open_log(
    path: Path | None, header: dict[str, Any]
) -> Iterator[Callable[[dict[str, Any]], None]]:
    """Append records to ``path``, each flushed and fsynced before the next source runs."""
    if path is None:
        yield lambda record: None
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fresh = not path.exists() or path.stat().st_size == 0
    with path.open("a", encoding="utf-8") as handle:

        def write(record: dict[str, Any]) -> None:
            handle.write(json.dumps(record, separators=(",", ":")) + "\n")
            handle.flush()
            os.fsync(handle.fileno())

        if fresh:
            write(header)
        yield write


def shard_indices(sources: int, shard: int, shards: int) -> range:
    """Source indices of one shard: every ``shards``-th index starting at ``shard``."""
    if not 0 <= shard < shards:
        raise InvalidArgument(f"shard={shard} must be in [0, {shards})")
    return range(shard, sources, shards)
