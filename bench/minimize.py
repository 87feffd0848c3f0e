"""Minimal hiding sets: ranked ddmin against Hypothesis' shrinker alone, on the same failures.

Failures: for every perception mutant that MR1 (O ⊆ O') catches, and n = 100 and 1000
noise points, the first KITTI sweep (``../shared/data/kitti_openpcdet/training``, ROI = the
camera wedge the labels cover) and numpy seed for which n points outside the ROI make the
mutant lose an obstacle. Each failure is then reduced twice, from the same n points:

* **ddmin** (:func:`pytest_metamorphic.core.reduction.reduce_followup`, what the engine
  runs): points ranked by distance to the lost obstacle, ddmin to a 1-minimal set within
  4/5 of ``--budget`` SUT calls, then (if not proven yet) a second ddmin pass with the
  points ordered by height. Its result is *proven* 1-minimal when a pass's last round
  (every one-point removal) completed.
* **Hypothesis alone**: the project's noise strategy (``noise_outside_roi(frame,
  min_size=1, max_size=n)``, one 32-bit seed per point) with the failing seed list put in
  an in-memory example database, so that Hypothesis replays exactly this failure and
  shrinks it (phases reuse + shrink, its normal shrinker and limits). At most
  ``--hypothesis-cap`` SUT calls; after that unseen examples count as passing (the shrinker
  then runs out quickly; the best failure found stays cached so the final replay agrees).

SUT calls are follow-up runs (the source output is computed once for both). The ratio is
the calls Hypothesis needed to first reach a failing set of ddmin's size k, over ddmin's
calls to its *proven* set. When Hypothesis never gets down to k, both are compared at the
smallest size Hypothesis reached (ddmin's calls until its set was first that small).
Uses a private Hypothesis function (``choices_to_bytes``) to fill the database.

Then the **count-driven** faults (a point budget, a voxel size or a clustering cell
that scales with the sweep's point count, a percentile of the whole sweep): which points
arrive does not matter, only how many, so the minimal set is large and every half of it
passes. At the engine's default budget (``--engine-budget``, 500 SUT calls) the reduction
the engine runs (bisection of the ranked prefix, one sweep of single removals, then ddmin)
is compared with ranked ddmin alone on the same failure: proven-minimal share and calls.

    python bench/minimize.py [--mutants a,b] [--sizes 100,1000] [--budget N]
                             [--hypothesis-cap N] [--seeds N] [--engine-budget N]
                             [--count-mutants a,b]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, Phase, Verbosity, given, settings
from hypothesis.database import InMemoryExampleDatabase, choices_to_bytes

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pytest_metamorphic.core.minimize import ddmin  # noqa: E402
from pytest_metamorphic.core.perturbation import as_reducible  # noqa: E402
from pytest_metamorphic.core.reduction import _orders, reduce_followup  # noqa: E402
from pytest_metamorphic.core.relations import CheckContext  # noqa: E402
from pytest_metamorphic.lidar.followups.perturb import SEED_BITS, NoiseOutsideROI  # noqa: E402
from pytest_metamorphic.lidar.io import read_bin  # noqa: E402
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.model.frame import Frame  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.mutants import mutant  # noqa: E402
from pytest_metamorphic.relations.lidar import mr1_subset  # noqa: E402
from pytest_metamorphic.strategies import noise_outside_roi  # noqa: E402

DATA = Path(os.environ.get("PYTEST_METAMORPHIC_DATA", ROOT.parent / "shared" / "data"))
KITTI = DATA / "kitti_openpcdet" / "training" / "velodyne"
# The mutants MR1 (subset) kills on KITTI sweeps (bench/mutation_score.py).
MUTANTS = (
    "full_cloud_ground",
    "full_cloud_height_cut",
    "random_point_budget",
    "voxel_budget",
    "global_ground_plane",
    "count_scaled_radius",
    "grid_anchored_at_sweep",
)
# Mutants whose MR1 failures depend on how many points arrive (see the docstring).
COUNT_DRIVEN = (
    "random_point_budget",
    "voxel_budget",
    "count_scaled_radius",
    "full_cloud_height_cut",
)
RELATION = mr1_subset().relation
KEY = b"bench-minimize"


@dataclass
class Trace:
    """SUT calls of one method, with the failing set sizes seen along the way."""

    calls: int = 0
    started: float = field(default_factory=time.perf_counter)
    # (calls so far, seconds so far, size) each time a smaller failing set was seen
    progress: list[tuple[int, float, int]] = field(default_factory=list)

    def record(self, size: int, fails: bool) -> None:
        self.calls += 1
        if fails and (not self.progress or size < self.progress[-1][2]):
            self.progress.append((self.calls, time.perf_counter() - self.started, size))

    def reached(self, size: int) -> tuple[int, float] | None:
        """(calls, seconds) when a failing set of at most ``size`` was first seen."""
        return next(((c, s) for c, s, k in self.progress if k <= size), None)

    @property
    def smallest(self) -> int:
        return self.progress[-1][2]


@dataclass
class Case:
    mutant: str
    frame: int
    n: int
    seed: int
    k: int = 0
    proven: bool = False
    ddmin: Trace = field(default_factory=Trace)
    ddmin_seconds: float = 0.0
    hypothesis: Trace = field(default_factory=Trace)
    hypothesis_seconds: float = 0.0

    def comparison(self) -> tuple[int, int, int, bool]:
        """(size compared at, ddmin calls, Hypothesis calls, Hypothesis reached k)."""
        reached = self.hypothesis.reached(self.k)
        if reached is not None:
            return self.k, self.ddmin.calls, reached[0], True
        size = self.hypothesis.smallest
        ours = self.ddmin.reached(size)
        calls = ours[0] if ours is not None else self.ddmin.calls
        theirs = self.hypothesis.reached(size)
        return size, calls, theirs[0] if theirs else self.hypothesis.calls, False

    @property
    def ratio(self) -> float:
        _, ours, theirs, _ = self.comparison()
        return theirs / max(ours, 1)


def kitti_frame(index: int) -> Frame:
    return Frame(read_bin(KITTI / f"{index:06d}.bin"), roi=kitti_label_region())


def violates(source_output: Any, output: Any, frame: Frame, followup: Frame) -> bool:
    """MR1 as the engine checks it: with both frames, so the ROI scope can judge."""
    return not RELATION.check(source_output, output, CheckContext(frame, followup)).holds


def seed_list(n: int, seed: int) -> list[int]:
    values = np.random.default_rng(seed).integers(0, 2**SEED_BITS, size=4 * n, dtype=np.int64)
    unique = list(dict.fromkeys(int(v) for v in values))[:n]  # the strategy's lists are unique
    return unique


def find_failure(
    system: Callable[[Frame], Any], n: int, frames: list[int], seeds: int
) -> tuple[int, int] | None:
    for index in frames:
        frame = kitti_frame(index)
        source_output = system(frame)
        for seed in range(seeds):
            noise = NoiseOutsideROI.from_seeds(frame, seed_list(n, seed))
            followup = noise.apply(frame)
            if violates(source_output, system(followup), frame, followup):
                return index, seed
    return None


def run_ddmin(case: Case, system: Any, frame: Frame, source_output: Any, budget: int) -> None:
    noise = NoiseOutsideROI.from_seeds(frame, seed_list(case.n, case.seed))
    followup_output = system(noise.apply(frame))
    trace = Trace()

    def run(value: Frame) -> Any:
        output = system(value)
        failed = violates(source_output, output, frame, value)
        trace.record(len(value.cloud) - len(frame.cloud), failed)
        return output

    started = time.perf_counter()
    result = reduce_followup(
        noise.params(),
        source=frame,
        source_output=source_output,
        followup_output=followup_output,
        run=run,
        check=RELATION.check,
        budget=budget,
    )
    case.ddmin_seconds = time.perf_counter() - started
    assert result is not None, "MR1 noise is reducible"
    case.ddmin, case.k, case.proven = trace, result.size, result.proven_minimal


def run_hypothesis(case: Case, system: Any, frame: Frame, source_output: Any, cap: int) -> None:
    seeds = seed_list(case.n, case.seed)
    database = InMemoryExampleDatabase()
    # The choice sequence of st.lists(...): "another element?" then the element, and a
    # final "no more" (drawn even at max_size). Saved as a *secondary* entry (a failure not
    # yet shrunk): Hypothesis does not shrink what it finds under the primary key again.
    choices = [c for s in seeds for c in (True, s)] + [False]
    database.save(KEY + b".secondary", choices_to_bytes(choices))
    trace = Trace()
    verdicts: dict[bytes, bool] = {}
    first: list[np.ndarray] = []

    @settings(
        database=database,
        phases=[Phase.reuse, Phase.shrink],
        deadline=None,
        verbosity=Verbosity.quiet,
        suppress_health_check=list(HealthCheck),
        report_multiple_bugs=False,
    )
    @given(noise_outside_roi(frame, min_size=1, max_size=case.n))
    def test(followup: Any) -> None:
        points = followup.params["noise_outside_roi"].points
        if not first:
            first.append(points)
        key = points.tobytes()
        if key not in verdicts:
            if trace.calls >= cap:
                return  # out of budget: unseen examples pass
            output = system(followup.input)
            verdicts[key] = violates(source_output, output, frame, followup.input)
            trace.record(len(points), verdicts[key])
        assert not verdicts[key]

    test._hypothesis_internal_database_key = KEY  # type: ignore[attr-defined]
    started = time.perf_counter()
    with contextlib.suppress(AssertionError):  # the failure itself is expected
        test()
    case.hypothesis_seconds = time.perf_counter() - started
    expected = NoiseOutsideROI.from_seeds(frame, seeds).points
    if not first or not np.array_equal(first[0], expected):
        raise RuntimeError("Hypothesis did not start from the failing seed list")
    case.hypothesis = trace


@dataclass
class CountCase:
    mutant: str
    n: int
    frame: int
    engine: tuple[int, bool, int, int | None]  # k, proven, calls, count bound
    alone: tuple[int, bool, int]  # k, proven, calls


def reduce_count_case(name: str, n: int, found: tuple[int, int], budget: int) -> CountCase:
    """The engine's reduction and ranked ddmin alone, each within ``budget`` SUT calls."""
    system = mutant(name)
    frame = kitti_frame(found[0])
    source_output = system(frame)
    noise = NoiseOutsideROI.from_seeds(frame, seed_list(n, found[1]))
    followup_output = system(noise.apply(frame))
    result = reduce_followup(
        noise.params(),
        source=frame,
        source_output=source_output,
        followup_output=followup_output,
        run=system,
        check=RELATION.check,
        budget=budget,
    )
    reducible = as_reducible(noise)
    assert result is not None and reducible is not None, "MR1 noise is reducible"
    order = _orders(reducible, frame, source_output, followup_output)[0]

    def fails(chosen: Sequence[int]) -> bool:
        subset = reducible.restrict(sorted(chosen))
        followup = subset.apply(frame)
        return violates(source_output, system(followup), frame, followup)

    alone = ddmin(order, fails, max_calls=budget)
    return CountCase(
        name,
        n,
        found[0],
        (result.size, result.proven_minimal, result.calls, result.count_bound),
        (len(alone), alone.proven_minimal, alone.calls),
    )


def count_driven_section(args: argparse.Namespace, frames: list[int]) -> list[CountCase]:
    cases = []
    print(f"\ncount-driven faults, {args.engine_budget} SUT calls each (the engine's default):")
    header = (
        f"{'mutant':24} {'n':>5} {'fr':>2} | {'k':>4} {'proof':>6} {'calls':>6} {'bound':>6} | "
        f"{'ddmin k':>7} {'proof':>6} {'calls':>6}"
    )
    print(header)
    print("-" * len(header))
    for name in [m for m in args.count_mutants.split(",") if m]:
        for n in (int(v) for v in args.sizes.split(",")):
            found = find_failure(mutant(name), n, frames, args.seeds)
            if found is None:
                print(f"{name:24} {n:>5}    no failure found")
                continue
            case = reduce_count_case(name, n, found, args.engine_budget)
            cases.append(case)
            k, proven, calls, bound = case.engine
            k0, proven0, calls0 = case.alone
            print(
                f"{name:24} {n:>5} {case.frame:>2} | {k:>4} {'yes' if proven else 'NO':>6} "
                f"{calls:>6} {bound if bound is not None else '-':>6} | {k0:>7} "
                f"{'yes' if proven0 else 'NO':>6} {calls0:>6}",
                flush=True,
            )
    print(
        "k, proof, calls: the engine's reduction (prefix bisection + one sweep + ddmin); "
        "bound: the first\nk ranked points fail and the first k - 1 do not. ddmin: ranked "
        "ddmin alone, same budget."
    )
    return cases


def hypothesis_section(args: argparse.Namespace, frames: list[int]) -> str:
    """Ranked reduction against Hypothesis' shrinker; returns the RESULT keys."""
    cases: list[Case] = []
    missing: list[str] = []
    began = time.perf_counter()
    for name in [m for m in args.mutants.split(",") if m]:
        system = mutant(name)
        for n in (int(v) for v in args.sizes.split(",")):
            found = find_failure(system, n, frames, args.seeds)
            if found is None:
                missing.append(f"{name} n={n}")
                print(f"{name:24} n={n:<5} no failure in frames {frames} x {args.seeds} seeds")
                continue
            case = Case(name, found[0], n, found[1])
            frame = kitti_frame(case.frame)
            source_output = system(frame)
            run_ddmin(case, system, frame, source_output, args.budget)
            run_hypothesis(case, system, frame, source_output, args.hypothesis_cap)
            cases.append(case)
            size, ours, theirs, reached = case.comparison()
            print(
                f"{name:24} n={n:<5} frame {case.frame} seed {case.seed}: ddmin k={case.k} "
                f"{'proven' if case.proven else 'NOT proven'} in {case.ddmin.calls} calls; "
                f"Hypothesis down to {case.hypothesis.smallest} in {case.hypothesis.calls} "
                f"calls; at size {size}: {theirs} vs {ours} calls ({case.ratio:.1f}x)",
                flush=True,
            )
    print()
    header = (
        f"{'mutant':24} {'n':>5} {'fr':>2} {'k':>4} {'proof':>6} {'calls':>6} {'s':>6} | "
        f"{'H size':>6} {'H calls':>7} {'H s':>6} | {'at k':>5} {'H->k':>6} {'ratio':>6}"
    )
    print(header)
    print("-" * len(header))
    for case in cases:
        size, ours, theirs, reached = case.comparison()
        at = str(size) if reached else f"{size}*"
        print(
            f"{case.mutant:24} {case.n:>5} {case.frame:>2} {case.k:>4} "
            f"{'yes' if case.proven else 'NO':>6} {case.ddmin.calls:>6} "
            f"{case.ddmin_seconds:>6.1f} | {case.hypothesis.smallest:>6} "
            f"{case.hypothesis.calls:>7} {case.hypothesis_seconds:>6.1f} | {at:>5} "
            f"{theirs:>6} {case.ratio:>6.1f}"
        )
    print(
        "\nk, calls, s: ddmin's set size, SUT calls and seconds to the proven set. H size, "
        "H calls, H s:\nHypothesis' smallest failing set, its SUT calls and seconds. at k: "
        "the size compared\n(* = Hypothesis never got down to k: compared at its smallest "
        "size); H->k: Hypothesis'\ncalls to first reach it; ratio = H->k / ddmin's calls "
        "(to its proven set, or to that size)."
    )
    if missing:
        print(f"no MR1 failure found for: {', '.join(missing)}")
    if not cases:
        sys.exit("no failures to reduce")
    proven_share = sum(case.proven for case in cases) / len(cases)
    ratios = [case.ratio for case in cases]
    reached_share = sum(case.comparison()[3] for case in cases) / len(cases)
    elapsed = time.perf_counter() - began
    print(
        f"\n{len(cases)} failures: proven 1-minimal {proven_share:.0%}, median call ratio "
        f"{statistics.median(ratios):.1f}x (min {min(ratios):.1f}x), median k "
        f"{statistics.median(case.k for case in cases):g}, Hypothesis reached k in "
        f"{reached_share:.0%}, {elapsed:.0f} s"
    )
    return (
        f"proven_minimal={proven_share:.3f} call_ratio={statistics.median(ratios):.2f} "
        f"median_k={statistics.median(case.k for case in cases):g} "
        f"call_ratio_min={min(ratios):.2f} hypothesis_reached_k={reached_share:.3f} "
        f"cases={len(cases)} "
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mutants", default=",".join(MUTANTS))
    parser.add_argument("--sizes", default="100,1000")
    parser.add_argument("--frames", default="0,1,2,3,4,5")
    parser.add_argument("--seeds", type=int, default=10, help="numpy seeds tried per frame")
    parser.add_argument("--budget", type=int, default=10000, help="ddmin SUT-call budget")
    parser.add_argument("--hypothesis-cap", type=int, default=2000)
    parser.add_argument("--engine-budget", type=int, default=500)
    parser.add_argument("--count-mutants", default=",".join(COUNT_DRIVEN))
    parser.add_argument(
        "--count-only", action="store_true", help="only the count-driven section (no Hypothesis)"
    )
    args = parser.parse_args()
    if not KITTI.is_dir():
        sys.exit(f"KITTI frames not found at {KITTI} (set PYTEST_METAMORPHIC_DATA)")
    frames = [int(v) for v in args.frames.split(",")]
    began = time.perf_counter()
    keys = "" if args.count_only else hypothesis_section(args, frames)
    counted = count_driven_section(args, frames)
    if not counted:
        sys.exit("no count-driven failures to reduce")
    count_proven = sum(c.engine[1] for c in counted) / len(counted)
    alone_proven = sum(c.alone[1] for c in counted) / len(counted)
    count_calls = statistics.median(c.engine[2] for c in counted)
    alone_calls = statistics.median(c.alone[2] for c in counted)
    elapsed = time.perf_counter() - began
    print(
        f"\ncount-driven: proven 1-minimal {count_proven:.0%} (ddmin alone {alone_proven:.0%}), "
        f"median calls {count_calls:g} (ddmin alone {alone_calls:g}); {elapsed:.0f} s in all"
    )
    print(
        f"RESULT {keys}count_proven={count_proven:.3f} "
        f"count_proven_ddmin_alone={alone_proven:.3f} count_calls={count_calls:g} "
        f"count_calls_ddmin_alone={alone_calls:g} count_cases={len(counted)} "
        f"seconds={elapsed:.0f}"
    )


if __name__ == "__main__":
    main()
