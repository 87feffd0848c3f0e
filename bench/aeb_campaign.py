"""Iqbal's Table II campaign, as ``python -m pytest_metamorphic.reports.aeb_campaign`` runs it.

The default campaign: three CPNCO-50 sources at 20 km/h (the Euro NCAP 10 m test road,
8th Street and 7th Street in West Oakland from ``../shared/data/osm_osmnx``, placed by
their cross-section), the typical car, the reference AEB, the 3.6 m-lane mutant and the
TTC AEB, one follow-up per speed from 15 to 100 km/h with the pedestrian's own timing
kept: 9 x 85 = 765 follow-ups plus 9 source runs, each collision judged by the
independent judge (two standards) and each violation re-run with the pedestrian
re-timed (the paper's test). Target: under 30 s on one core.

Baseline, measured in the same run: the same campaign in highway-env (Farama, PyPI), a
general-purpose driving simulator, through ``HighwayEnvSimulator``; both must produce the
same violations (the bench exits 1 otherwise). ``ratio`` = highway-env time / built-in
time. Skipped (``highway_env_s=nan``) when the highway-env extra is not installed.

    python bench/aeb_campaign.py [--data ../shared/data] [--repeat N]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pytest_metamorphic.driving.campaign import (  # noqa: E402
    CampaignRow,
    default_sources,
    format_campaign,
    iqbal_campaign,
)

TARGET_S = 30.0


def timed(run: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Median wall time of ``repeat`` runs, and the last result."""
    seconds, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = run()
        seconds.append(time.perf_counter() - start)
    return statistics.median(seconds), result


def verdicts(rows: list[CampaignRow]) -> list[tuple[str, str, tuple[tuple[float, bool], ...]]]:
    return [
        (row.source, row.controller, tuple((c.speed_kmh, c.avoidable) for c in row.violations))
        for row in rows
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data",
        default=os.environ.get("PYTEST_METAMORPHIC_DATA", str(ROOT.parent / "shared" / "data")),
    )
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    if args.repeat < 1:
        parser.error("--repeat must be >= 1")

    # Loading the OSM streets is part of the command's wall time.
    builtin_s, rows = timed(lambda: iqbal_campaign(default_sources(args.data)), args.repeat)
    print(format_campaign(rows, title="CPNCO-50, source 20 km/h, pedestrian timing kept"))
    followups = sum(row.followups for row in rows)
    violations = sum(len(row.violations) for row in rows)
    avoidable = sum(len(row.avoidable_violations) for row in rows)

    highway_s = math.nan
    try:
        from pytest_metamorphic.driving.simulators.highway_env import HighwayEnvSimulator

        simulator = HighwayEnvSimulator()
    except Exception as error:  # the extra is missing: report the built-in time alone
        print(f"\nhighway-env baseline skipped: {error}")
    else:
        highway_s, highway_rows = timed(
            lambda: iqbal_campaign(default_sources(args.data), simulator=simulator), 1
        )
        if verdicts(highway_rows) != verdicts(rows):
            print(format_campaign(highway_rows, title="in highway-env"), file=sys.stderr)
            sys.exit("bench/aeb_campaign.py: highway-env finds other violations than ours")

    print(f"\n{'simulator':<28}{'wall s':>9}{'per run ms':>12}")
    runs = followups + len(rows)
    for name, seconds in (("built-in (median)", builtin_s), ("highway-env", highway_s)):
        print(f"{name:<28}{seconds:>9.2f}{1000 * seconds / runs:>12.2f}")
    ratio = highway_s / builtin_s
    print(
        f"\n{followups} follow-ups in {builtin_s:.1f} s (target < {TARGET_S:g} s); "
        f"highway-env takes {ratio:.1f}x as long for the same violations"
    )
    print(
        f"RESULT wall_s={builtin_s:.2f} target_s={TARGET_S:g} highway_env_s={highway_s:.2f} "
        f"ratio={ratio:.2f} followups={followups} violations={violations} avoidable={avoidable}"
    )


if __name__ == "__main__":
    main()
