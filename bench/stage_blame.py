"""Stage blame on the reference pipeline's mutants: does it name the stage each changes?

Every mutant of :mod:`pytest_metamorphic.lidar.systems.perception.mutants` changes one
stage of the reference pipeline (the methods it overrides:
:data:`~pytest_metamorphic.lidar.systems.perception.trace.STAGE_METHODS`). For each, the
relations of ``lidar_relations(history=True)`` are run in order, each wrapped by
``with_stage_blame(..., reference_stages(mutant))``, on KITTI sweeps 0-2 and a rendered
street of ``bench/mutation_score.py`` (one sweep at a time, ``--examples`` derandomized
follow-ups each) until one finds a violation; the blamed stage of that (reduced) violation
is compared with the mutant's. Mutants no relation kills in the budget are listed, not
counted. Ends with
``RESULT mutants=<n> killed=<k> blamed_right=<r> share=<r/k>``.

    python bench/stage_blame.py [--examples 2] [--sweeps 3] [--streets 1] [--mutants a,b]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from mutation_score import KITTI, rendered_scenes  # noqa: E402

from pytest_metamorphic import MetamorphicViolation, metamorphic  # noqa: E402
from pytest_metamorphic.lidar.io.catalog import FrameCatalog  # noqa: E402
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.systems.perception import ReferencePerception  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.mutants import MUTANTS, mutant  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.trace import (  # noqa: E402
    STAGE_METHODS,
    reference_stages,
)
from pytest_metamorphic.relations.lidar import lidar_relations  # noqa: E402
from pytest_metamorphic.relations.lidar.blame import with_stage_blame  # noqa: E402


def expected_stages(name: str) -> set[str]:
    """The stages whose methods the mutant overrides."""
    cls = MUTANTS[name]
    return {
        stage
        for stage, methods in STAGE_METHODS.items()
        if any(getattr(cls, m) is not getattr(ReferencePerception, m) for m in methods)
    }


def first_violation(system: Any, frames: list[Any], examples: int) -> tuple[str, Any] | None:
    """(relation name, verdict) of the first relation that finds a violation on one of
    ``frames`` (each tried in turn), or None."""
    for relation in with_stage_blame(lidar_relations(history=True), reference_stages(system)):
        for frame in frames:

            @settings(
                max_examples=examples,
                database=None,
                derandomize=True,
                deadline=None,
                suppress_health_check=list(HealthCheck),
                print_blob=False,
                phases=[Phase.explicit, Phase.generate],  # the engine still reduces
            )
            @metamorphic(source=st.just(frame), relations=[relation], followups=1)
            def test(frame: Any) -> Any:
                return system(frame)

            try:
                test()
            except MetamorphicViolation as violation:
                return relation.name, violation.verdict
            except Exception as error:  # a crash or a flaky case is no kill
                print(f"    {relation.name}: {type(error).__name__}: {str(error)[:160]}")
    return None


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=2)
    parser.add_argument("--mutants", default="")
    parser.add_argument("--sweeps", type=int, default=3, help="KITTI sweeps 0..k-1")
    parser.add_argument("--streets", type=int, default=1, help="rendered streets")
    options = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    catalog = FrameCatalog(str(KITTI), roi=kitti_label_region())
    frames = [catalog[i] for i in range(options.sweeps)] + rendered_scenes()[: options.streets]
    names = [n.strip() for n in options.mutants.split(",") if n.strip()] or list(MUTANTS)
    started = time.perf_counter()
    killed = right = 0
    missed: list[str] = []
    for name in names:
        found = first_violation(mutant(name), frames, options.examples)
        want = expected_stages(name)
        if found is None:
            missed.append(name)
            print(f"{name:24s} not killed in the budget (its stage: {sorted(want)})", flush=True)
            continue
        relation, verdict = found
        details = verdict.details if verdict is not None else {}
        blamed = details.get("stage_blame")
        killed += 1
        ok = blamed in want
        right += ok
        print(
            f"{name:24s} {'ok ' if ok else 'BAD'} blamed {blamed!s:15s} its stage {sorted(want)}; "
            f"by {relation!r}: {details.get('stage_difference', '')}",
            flush=True,
        )
    share = right / killed if killed else 0.0
    print(f"{len(names)} mutants in {time.perf_counter() - started:.0f} s; not killed: {missed}")
    print(f"RESULT mutants={len(names)} killed={killed} blamed_right={right} share={share:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
