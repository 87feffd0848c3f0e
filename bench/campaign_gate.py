"""Campaign gates on the Quickstart's campaign: does a fault fail the build, and does an
unchanged system pass against its own baseline, run after run?

The Quickstart's MR1 campaign (200 rendered HDL-64E streets, 10/100/1000 points outside
the ROI) under one name, "MR1 pipeline", as a CI job would run it on main and on a pull
request:

* **threshold** (``max_rate=0.05``): the reference pipeline must pass, the pipeline with
  the ``count_scaled_radius`` fault must fail;
* **baseline**: the reference's report (seed 0) is main's; the fault compared with it must
  fail;
* **no flaky gate**: the faulty pipeline's own report (seed 0) as the baseline, 20 runs
  with seeds 1-20 of the same faulty pipeline (its rate does not change) must all pass,
  and so must 20 runs of the reference against the reference's.

Sources run on two processes. Ends with
``RESULT reference_threshold=<pass|fail> mutant_threshold=... mutant_baseline=...
mutant_reruns_passed=<k>/<n> reference_reruns_passed=<k>/<n>``.

    python bench/campaign_gate.py [--sources 200] [--reruns 20]
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pytest_metamorphic.core.campaign import (  # noqa: E402
    CampaignResult,
    Gate,
    judge_campaign,
    run_campaign,
)
from pytest_metamorphic.lidar.campaign import mr1_campaign  # noqa: E402
from pytest_metamorphic.lidar.model.frame import Frame  # noqa: E402
from pytest_metamorphic.lidar.model.obstacles import Box  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.mutants import mutant  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.pipeline import ReferencePerception  # noqa: E402

_SYSTEMS = {
    "reference": ReferencePerception(),
    "count_scaled_radius": mutant("count_scaled_radius"),
}


class Pipeline:
    """The pipeline under test, by name (picklable for the worker processes)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __call__(self, frame: Frame) -> list[Box]:
        return _SYSTEMS[self.name](frame.cloud, frame.roi)

    def __repr__(self) -> str:
        return f"Pipeline({self.name!r})"


def run(system: str, seed: int, sources: int) -> CampaignResult:
    campaign = mr1_campaign(
        Pipeline(system), name="MR1 pipeline", sources=sources, seed=seed, scope="all"
    )
    return run_campaign(campaign)


def word(passed: bool) -> str:
    return "pass" if passed else "fail"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sources", type=int, default=200)
    parser.add_argument("--reruns", type=int, default=20)
    arguments = parser.parse_args()
    started = time.monotonic()
    jobs = [("reference", 0), ("count_scaled_radius", 0)]
    jobs += [(system, seed) for seed in range(1, arguments.reruns + 1)
             for system in ("reference", "count_scaled_radius")]  # fmt: skip
    with ProcessPoolExecutor(max_workers=2) as pool:
        futures = {job: pool.submit(run, *job, arguments.sources) for job in jobs}
        results = {job: future.result() for job, future in futures.items()}
    reference, faulty = results[("reference", 0)], results[("count_scaled_radius", 0)]
    threshold = Gate(max_rate=0.05)
    baseline_only = Gate(max_rate=None)
    verdicts = {
        "reference_threshold": judge_campaign(reference, threshold),
        "mutant_threshold": judge_campaign(faulty, threshold),
        "mutant_baseline": judge_campaign(
            faulty, baseline_only, baseline=reference, baseline_where="(the reference, seed 0)"
        ),
    }
    for name, verdict in verdicts.items():
        print(f"--- {name}")
        print("\n".join(verdict.lines()))
    reruns = {}
    for system, own in (("count_scaled_radius", faulty), ("reference", reference)):
        passed = [
            judge_campaign(results[(system, seed)], baseline_only, baseline=own).passed
            for seed in range(1, arguments.reruns + 1)
        ]
        rates = [results[(system, seed)].sizes[1000].violations for seed in range(1, 4)]
        print(f"--- {system} seeds 1-{arguments.reruns} against its seed 0: "
              f"{sum(passed)} passed (n=1000 violations, seeds 1-3: {rates} of "
              f"{arguments.sources})")  # fmt: skip
        reruns[system] = f"{sum(passed)}/{len(passed)}"
    print(f"{len(jobs)} campaigns of {arguments.sources} sources in "
          f"{time.monotonic() - started:.0f} s")  # fmt: skip
    print(
        "RESULT "
        + " ".join(f"{name}={word(verdict.passed)}" for name, verdict in verdicts.items())
        + f" mutant_reruns_passed={reruns['count_scaled_radius']}"
        + f" reference_reruns_passed={reruns['reference']}"
    )


if __name__ == "__main__":
    main()
