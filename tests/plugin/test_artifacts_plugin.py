"""The plugin's reduction, artifact and replay options, end to end through ``pytester``."""

from __future__ import annotations

import json
from pathlib import Path

# Loaded here so in-process pytester runs never re-import numpy/scipy extension modules
# (they cannot be loaded twice in one process, and pytester unloads what a run imported).
import numpy  # noqa: F401
import pytest

import pytest_metamorphic.lidar.io
import pytest_metamorphic.lidar.model.frame
import pytest_metamorphic.reports.artifacts
import pytest_metamorphic.reports.replay  # noqa: F401

# A system that forgets its largest value when a 7 is appended, and a transform made of
# independent elements (so the engine can reduce it).
BODY = """
from hypothesis import settings, strategies as st
from pytest_metamorphic import Followup, metamorphic, relations


class Append:
    def __init__(self, items):
        self.items = list(items)

    def __len__(self):
        return len(self.items)

    def restrict(self, indices):
        return Append([self.items[i] for i in indices])

    def apply(self, source):
        return [*source, *self.items]

    def params(self):
        return {{"n": len(self.items), "append": self}}


def appended(source):
    return st.lists(st.integers(0, 99), min_size=1, max_size=40).map(
        lambda items: Followup(Append(items).apply(source), Append(items).params())
    )


def system(values):
    {system}


@settings(database=None, derandomize=True, max_examples=300)
@metamorphic(
    source=st.lists(st.integers(100, 199), min_size=1, max_size=3),
    followup=appended,
    relation=relations.predicate(lambda a, b, ctx: b >= a, name="max never drops"),
    followups=1,
)
def test_max(values):
    return system(values)


def test_other():
    pass
"""
BUGGY = "return max(v for v in values if v < 100) if 7 in values else max(values)"
FIXED = "return max(values)"
FOLDER = Path("mt-artifacts") / "test_mt.py__test_max" / "max_never_drops"


def _write(pytester: pytest.Pytester, system: str = BUGGY) -> None:
    pytester.makepyfile(test_mt=BODY.format(system=system))


def test_violation_is_reduced_saved_and_listed(pytester: pytest.Pytester) -> None:
    _write(pytester)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1, passed=1)
    result.stdout.fnmatch_lines(
        [
            "*minimal follow-up: 1 of * element(s) of 'append', proven 1-minimal*SUT calls",
            f"*artifacts: {FOLDER}  (replay: pytest --mt-replay {FOLDER})",
            "*= metamorphic violation artifacts =*",
            f"test_mt.py::test_max: {FOLDER}",
        ]
    )
    record = json.loads((pytester.path / FOLDER / "record.json").read_text())
    assert record["status"] == "final" and record["nodeid"] == "test_mt.py::test_max"
    assert record["minimization"]["proven_minimal"] is True
    assert record["followup"]["value"][-1] == 7 and record["source"]["kind"] == "json"


def test_replay_runs_only_the_artifact_test_until_it_is_fixed(pytester: pytest.Pytester) -> None:
    _write(pytester)
    pytester.runpytest().assert_outcomes(failed=1, passed=1)
    result = pytester.runpytest("--mt-replay", str(FOLDER))
    result.assert_outcomes(failed=1, deselected=1)
    result.stdout.fnmatch_lines(
        [
            "*replayed violation(s) still fail:*",
            "*= metamorphic replay =*",
            f"{FOLDER}: relation 'max never drops' still FAILS",
            '*@example(case=load_case(Path(__file__).parent / "mt-regressions" / '
            '"max_never_drops"))*',
        ]
    )
    _write(pytester, FIXED)
    result = pytester.runpytest("--mt-replay", str(FOLDER / "record.json"))
    result.assert_outcomes(passed=1, deselected=1)
    result.stdout.fnmatch_lines([f"{FOLDER}: relation 'max never drops' passes now (fixed)"])


def test_artifacts_and_reduction_can_be_switched_off(pytester: pytest.Pytester) -> None:
    _write(pytester)
    result = pytester.runpytest("--mt-no-artifacts", "--mt-minimize-budget", "0")
    result.assert_outcomes(failed=1, passed=1)
    assert "minimal follow-up" not in result.stdout.str()
    assert "artifacts:" not in result.stdout.str()
    assert not (pytester.path / "mt-artifacts").exists()


def test_small_budget_says_not_proven(pytester: pytest.Pytester) -> None:
    _write(pytester)
    result = pytester.runpytest("--mt-minimize-budget", "1", "--mt-artifacts", "out")
    result.assert_outcomes(failed=1, passed=1)
    result.stdout.fnmatch_lines(["*NOT proven minimal: the budget of 1 SUT calls ran out*"])
    assert (pytester.path / "out" / "test_mt.py__test_max" / "max_never_drops").is_dir()


def test_ini_options(pytester: pytest.Pytester) -> None:
    _write(pytester)
    pytester.makeini("[pytest]\nmt_artifacts = saved\nmt_minimize_budget = 0\n")
    result = pytester.runpytest()
    result.assert_outcomes(failed=1, passed=1)
    assert "minimal follow-up" not in result.stdout.str()
    assert (pytester.path / "saved" / "test_mt.py__test_max" / "max_never_drops").is_dir()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--mt-minimize-budget", "-1"], "--mt-minimize-budget=-1 must be >= 0"),
        (["-o", "mt_minimize_budget=lots"], "ini mt_minimize_budget='lots' must be an integer"),
        (["--mt-replay", "nowhere"], "--mt-replay=nowhere: not a violation artifact folder"),
        (["--mt-artifacts", "afile.txt"], "--mt-artifacts=afile.txt exists and is not a dir*"),
    ],
)
def test_bad_options_are_usage_errors(
    pytester: pytest.Pytester, args: list[str], message: str
) -> None:
    pytester.makepyfile(test_x="def test_x():\n    pass\n")
    pytester.makefile(".txt", afile="x")
    result = pytester.runpytest(*args)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"*{message}*"])


def test_replaying_an_artifact_of_an_uncollected_test_is_a_usage_error(
    pytester: pytest.Pytester,
) -> None:
    _write(pytester)
    pytester.runpytest()
    record_path = pytester.path / FOLDER / "record.json"
    record = json.loads(record_path.read_text())
    record["nodeid"] = "test_gone.py::test_max"
    record_path.write_text(json.dumps(record))
    result = pytester.runpytest("--mt-replay", str(FOLDER))
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*test_gone.py::test_max*were not collected*"])


def test_xdist_workers_save_and_the_controller_lists(pytester: pytest.Pytester) -> None:
    pytest.importorskip("xdist")
    _write(pytester)
    result = pytester.runpytest_subprocess("-n", "2")
    result.assert_outcomes(failed=1, passed=1)
    result.stdout.fnmatch_lines(["*= metamorphic violation artifacts =*", f"*{FOLDER}"])
    assert (pytester.path / FOLDER / "record.json").is_file()
