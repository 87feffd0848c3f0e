"""Baselines: a campaign's report from another run (main's), read back to compare with.

A baseline is what a campaign run writes anyway: ``<campaign dir>/<name>/report.json``.
CI keeps the folder from main and restores it for a pull request; ``--mt-baseline DIR``
(or one ``report.json``) then compares each campaign with its namesake there
(:mod:`pytest_metamorphic.core.campaign.gate`). Only the counts are read (pairs and
violations per size, the relation, the campaign's name), each checked; the file is
size-limited and a malformed one is an error naming the file and the field.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.campaign.results import CampaignResult, SizeCounts
from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.core.files import field, read_json

__all__ = ["REPORT_NAME", "find_baseline", "read_report", "slug"]

REPORT_NAME = "report.json"
_MAX_REPORT_BYTES = 64 << 20


def slug(name: str) -> str:
    """A campaign's folder name: its name with everything but letters, digits, ``-`` and
    ``_`` replaced by ``_``."""
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name) or "campaign"


def _count(data: Any, key: str, where: str, path: Path) -> int:
    value = field(data, key, int, where=where, path=path, default=0)
    if value < 0:
        raise DataError(f"{where}'s {key} is {value}; counts are >= 0", path=path)
    return int(value)


def read_report(path: str | os.PathLike[str]) -> CampaignResult:
    """The counts of a campaign ``report.json``, as a result to compare with.

    Raises
    ------
    DataError
        Not a readable campaign report: the message names the file and the field.
    """
    file = Path(path)
    data = read_json(file, what="campaign report", limit=_MAX_REPORT_BYTES)
    header = field(data, "header", dict, where="the report", path=file)
    for key in ("campaign", "relation"):
        field(header, key, str, where="the report's header", path=file)
    _count(header, "sources", "the report's header", file)
    sizes = field(data, "sizes", dict, where="the report", path=file)
    counts: dict[int, SizeCounts] = {}
    for key, entry in sizes.items():
        where = f"the report's size {key!r}"
        try:
            size = int(key)
        except ValueError:
            raise DataError(f"{where} is not an integer size", path=file) from None
        field(entry, "pairs", int, where=where, path=file)
        pairs = _count(entry, "pairs", where, file)
        violations = _count(entry, "violations", where, file)
        if violations > pairs:
            raise DataError(f"{where} has {violations} violations in {pairs} pairs", path=file)
        counts[size] = SizeCounts(
            pairs=pairs, violations=violations, crashes=_count(entry, "crashes", where, file)
        )
    done = field(data, "sources_done", int, where="the report", path=file, default=0)
    result = CampaignResult(header=dict(header), sizes=counts)
    result.sources_done = set(range(max(0, min(int(done), int(header.get("sources", 0))))))
    return result


def find_baseline(
    where: str | os.PathLike[str], campaign: str
) -> tuple[CampaignResult | None, str, str]:
    """The baseline of campaign ``campaign`` at ``where``: (result, its file, why none).

    ``where`` is a campaign folder root (``<where>/<slug>/report.json``, or any
    ``*/report.json`` there that names the campaign) or one ``report.json``.
    """
    root = Path(where)
    candidates = [root] if root.is_file() else [root / slug(campaign) / REPORT_NAME]
    if root.is_dir():
        candidates += sorted(p for p in root.glob(f"*/{REPORT_NAME}") if p not in candidates)
    for number, path in enumerate(candidates):
        if not path.is_file():
            continue
        try:
            report = read_report(path)
        except DataError:
            if number == 0:  # the campaign's own report (or the file given) must be sound
                raise
            continue  # another campaign's report, looked at only for a renamed folder
        if report.header["campaign"] == campaign:
            return report, str(path), ""
    return None, "", f"no baseline report of campaign {campaign!r} in {root}"
