"""End-to-end tests of ``@metamorphic`` and the plugin, through pytest's ``pytester``."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

# Loaded here so in-process pytester runs never re-import numpy/scipy extension modules
# (they cannot be loaded twice in one process, and pytester unloads what a run imported).
import numpy  # noqa: F401
import pytest

import pytest_metamorphic.core.campaign

HEADER = """
from hypothesis import settings, strategies as st
from pytest_metamorphic import MetamorphicRelation, Followup, metamorphic, relations
"""


def _write(pytester: pytest.Pytester, body: str) -> None:
    pytester.makepyfile(test_mt=HEADER + body)


def test_passing_relation_reports_counts(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
@settings(max_examples=20, database=None)
@metamorphic(source=st.lists(st.integers()), followup=lambda xs: st.permutations(xs),
             relation=relations.equal(), followups=3)
def test_sort(xs):
    return sorted(xs)
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(
        [
            "*= metamorphic relations =*",
            "test *relation*sources*follow-ups*SUT calls*violations*crashes",
            "test_mt.py::test_sort*equal*20*60*60*0*0",
        ]
    )


def test_violation_message_names_relation_and_difference(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
def broken_sort(xs):
    return sorted(xs) if len(xs) < 3 else list(xs)

@settings(database=None)
@metamorphic(source=st.lists(st.integers()), followup=lambda xs: st.permutations(xs),
             relation=relations.equal())
def test_sort(xs):
    return broken_sort(xs)
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*MetamorphicViolation: metamorphic relation 'equal' violated on follow-up *",
            "*follow-up * differs from the source output: output[[]*[]]: * != *",
            "*source output:*",
            "*follow-up output:*",
            "*Failing test case: test_sort(*",
        ]
    )


def test_planted_bug_shrinks_to_minimal_input(pytester: pytest.Pytester) -> None:
    # The bug: duplicates are dropped when the list has more than two elements. The
    # smallest source that exposes it under "appending an element keeps |O| growing" is a
    # list of two equal zeros with 0 appended.
    _write(
        pytester,
        """
def dedupe_sort(xs):
    return sorted(set(xs)) if len(xs) > 2 else sorted(xs)

@settings(database=None, max_examples=500)
@metamorphic(
    source=st.lists(st.integers()),
    followup=lambda xs: st.integers().map(lambda x: Followup(xs + [x], params={"appended": x})),
    relation=relations.cardinality("<"),
    followups=1,
)
def test_append_grows(xs):
    return dedupe_sort(xs)
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*transform parameters: {appended=0}*",
            "*the source output has 2 element(s), follow-up 0 has 1; expected |O| < |O'|*",
            "*source=[[]0, 0[]],*",
            "*Followup([[]0, 0, 0[]], params={appended=0}),*",
        ]
    )
    # The traceback names the user's test (its def line), not the plugin's wrapper.
    result.stdout.fnmatch_lines(
        ["*>   def test_append_grows(xs):", "test_mt.py:14: MetamorphicViolation"]
    )
    assert "core/engine.py" not in result.stdout.str()


def test_crash_on_source_is_reported_as_crash(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
@settings(database=None)
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal())
def test_div(x):
    return 10 // x
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*SystemUnderTestCrash: the system under test crashed on the source input: "
            "ZeroDivisionError*"
        ]
    )
    result.stdout.no_fnmatch_line("*MetamorphicViolation*")
    # The user's code first: the system's own line (the cause), then the test's def line;
    # no frame of the plugin, and the crashing source calls are counted.
    text = result.stdout.str()
    assert "return 10 // x" in text and ">   def test_div(x):" in text
    assert "pytest_metamorphic/core" not in text
    assert "call_with_timeout" not in text
    # The crashing call is a call: the (source) row counts it, beside its crash.
    (row,) = [line.split() for line in result.stdout.lines if "(source)" in line]
    assert row[0] == "test_mt.py::test_div" and int(row[2]) >= 1 and row[3] == "1"


def test_the_footer_adds_up(pytester: pytest.Pytester) -> None:
    # Source runs, follow-up runs, determinism re-checks, reductions and Hypothesis's
    # re-runs add up to the total; the table's column is the relation's own calls.
    _write(
        pytester,
        """
@settings(database=None, derandomize=True)
@metamorphic(source=st.lists(st.integers(0, 3), max_size=6),
             followup=lambda xs: st.just(xs + [0]), relation=relations.cardinality("<"))
def test_grows(xs):
    return sorted(set(xs)) if len(xs) > 2 else sorted(xs)
""",
    )
    result = pytester.runpytest("--mt-no-artifacts")
    result.assert_outcomes(failed=1)
    (line,) = [x for x in result.stdout.lines if x.startswith("1 metamorphic test(s), ")]
    total = int(line.split(", ")[1].split()[0])
    parts = [int(part.split()[0]) for part in line.split(": ", 1)[1].split(" + ")]
    assert sum(parts) == total and len(parts) >= 4, line
    assert "reducing violations" not in line or "re-running failing cases" in line


def test_crash_on_followup_names_relation_and_index(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
@settings(database=None)
@metamorphic(source=st.integers(1, 100), followup=lambda x: st.just(-x),
             relation=relations.equal(), followups=1)
def test_sqrt(x):
    if x < 0:
        raise ValueError("negative input")
    return x
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*SystemUnderTestCrash: the system under test crashed on follow-up 0 of relation "
            "'equal': ValueError: negative input*"
        ]
    )
    result.stdout.re_match_lines([r"test_mt.py::test_sqrt\s+equal(\s+\d+){4}\s+[1-9]\d*$"])


def test_nondeterministic_system_is_not_blamed_on_followup(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
import itertools
counter = itertools.count()

@settings(database=None)
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal())
def test_counter(x):
    return next(counter)
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        ["*NondeterministicSystemError: the system under test is nondeterministic*"]
    )


def test_determinism_check_can_be_switched_off(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
import itertools
counter = itertools.count()

@settings(database=None)
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal())
def test_counter(x):
    return next(counter)
""",
    )
    result = pytester.runpytest("--mt-no-determinism-check")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*MetamorphicViolation*"])
    result.stdout.no_fnmatch_line("*Nondeterministic*")


def test_source_output_is_computed_once_per_case(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
calls = []

@settings(database=None, max_examples=30)
@metamorphic(
    source=st.lists(st.integers(), max_size=5),
    relations=[
        MetamorphicRelation("permute", lambda xs: st.permutations(xs), relations.equal()),
        MetamorphicRelation("reverse", lambda xs: st.just(xs[::-1]), relations.equal()),
    ],
    followups=3,
)
def test_sort(xs):
    calls.append(tuple(xs))
    return sorted(xs)

def test_zz_count():
    # 1 source run + 2 relations x 3 follow-ups per example, never the source twice.
    assert len(calls) == 30 * 7
""",
    )
    result = pytester.runpytest("-p", "no:randomly", "--mt-report", "report.json")
    result.assert_outcomes(passed=2)
    report = json.loads((pytester.path / "report.json").read_text())
    (test,) = report["tests"]
    assert test["source_calls"] == 30
    assert test["sut_calls"] == 30 * 7
    assert test["relations"]["permute"]["followups"] == 90


def test_counts_are_distinct_cases_not_shrinking_steps_or_the_final_replay(
    pytester: pytest.Pytester,
) -> None:
    # Every case fails, and Hypothesis stops generating at the first failure
    # (report_multiple_bugs=False): one source, one violation, whatever the seed. The
    # shrinking steps and the final replay are re-runs, counted apart (they used to read
    # as "violations 2" and more for one failure).
    _write(
        pytester,
        """
calls = []

@settings(database=None, max_examples=50, report_multiple_bugs=False)
@metamorphic(source=st.lists(st.integers()), followup=lambda xs: st.just([*xs, 0]),
             relation=relations.equal(), followups=2)
def test_broken(xs):
    calls.append(1)
    return len(xs)  # "appending changes nothing" is false for every list

def test_zz_calls():
    assert len(calls) > 3  # the failing case was shrunk and replayed
""",
    )
    result = pytester.runpytest("-p", "no:randomly", "--mt-report", "report.json")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(
        [
            "test_mt.py::test_broken*equal*1*1*2*1*0",
            "*re-running failing cases while Hypothesis shrank them*",
            "sources and violations are distinct cases*",
        ]
    )
    report = json.loads((pytester.path / "report.json").read_text())
    (test,) = report["tests"]
    counted = test["relations"]["equal"]
    assert (counted["sources"], counted["violations"]) == (1, 1)
    reruns = test["reruns"]
    assert reruns["sources"] >= 1 and reruns["violations"] >= 1  # at least the final replay
    # Every system call is still accounted for: distinct cases, re-runs, reduction.
    assert test["sut_calls"] == test["source_calls"] + counted["sut_calls"] + reruns["sut_calls"]


def test_explicit_examples_count_as_sources(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
from hypothesis import Phase, example

from pytest_metamorphic.core.cases import MetamorphicCase

def case(xs):
    return MetamorphicCase(xs, {"equal": (Followup(xs[::-1]), Followup(sorted(xs)))})

@settings(database=None, phases=[Phase.explicit])
@example(case=case([3, 1, 2]))
@example(case=case([]))
@metamorphic(source=st.lists(st.integers()), followup=lambda xs: st.permutations(xs),
             relation=relations.equal(), followups=2)
def test_sort(xs):
    return sorted(xs)
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["test_mt.py::test_sort*equal*2*4*4*0*0"])


def test_followups_option_applies_when_decorator_does_not_fix_it(
    pytester: pytest.Pytester,
) -> None:
    _write(
        pytester,
        """
@settings(database=None, max_examples=10)
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal())
def test_identity(x):
    return x
""",
    )
    result = pytester.runpytest("--mt-followups", "5")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["test_mt.py::test_identity*equal*10*50*50*0*0"])


def test_fixtures_keep_working(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
import pytest

@pytest.fixture(scope="module")
def offset():
    return 7

@settings(database=None, max_examples=10)
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal())
def test_with_fixture(x, offset):
    return x + offset
""",
    )
    pytester.runpytest().assert_outcomes(passed=1)


def test_junit_properties(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
@settings(database=None, max_examples=10)
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal(),
             followups=2)
def test_identity(x):
    return x
""",
    )
    pytester.runpytest("--junitxml=junit.xml").assert_outcomes(passed=1)
    tree = ET.parse(pytester.path / "junit.xml")
    properties = {p.get("name"): p.get("value") for p in tree.iter("property")}
    assert properties["mt.equal.sources"] == "10"
    assert properties["mt.equal.followups"] == "20"
    assert properties["mt.equal.violations"] == "0"
    assert properties["mt.sut_calls"] == "30"


def test_xdist_aggregates_counts_from_workers(pytester: pytest.Pytester) -> None:
    pytest.importorskip("xdist")
    body = "".join(
        f"""
@settings(database=None, max_examples={10 + i})
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal(),
             followups=2)
def test_identity_{i}(x):
    return x
"""
        for i in range(4)
    )
    _write(pytester, body)
    result = pytester.runpytest_subprocess("-n", "2", "--mt-report", "report.json")
    result.assert_outcomes(passed=4)
    result.stdout.fnmatch_lines(["*= metamorphic relations =*", "4 metamorphic test(s), *"])
    report = json.loads((pytester.path / "report.json").read_text())
    sources = sorted(t["relations"]["equal"]["sources"] for t in report["tests"])
    assert sources == [10, 11, 12, 13]
    assert sum(t["sut_calls"] for t in report["tests"]) == 3 * (10 + 11 + 12 + 13)


@pytest.mark.parametrize(
    ("decorator", "message"),
    [
        (
            "source=[1, 2], followup=lambda x: st.just(x), relation=relations.equal()",
            "source=[[]1, 2[]] must be a Hypothesis strategy",
        ),
        (
            "source=st.integers(), followup=st.just(1), relation=relations.equal()",
            "followup of relation 'equal' is a strategy*",
        ),
        (
            "source=st.integers(), followup=lambda a, b: st.just(a), relation=relations.equal()",
            "*must accept exactly one argument*",
        ),
        (
            "source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal",
            "*did you forget the parentheses?*",
        ),
        (
            "source=st.integers(), followup=lambda x: st.just(x)",
            "@metamorphic needs followup= and relation=*",
        ),
        (
            "source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal(), "
            "followups=0",
            "followups=0 must be between 1 and 100",
        ),
    ],
)
def test_bad_decorator_arguments_fail_at_collection(
    pytester: pytest.Pytester, decorator: str, message: str
) -> None:
    _write(pytester, f"\n@metamorphic({decorator})\ndef test_x(x):\n    return x\n")
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines([f"*InvalidArgument: {message}"])


def test_transform_not_returning_a_strategy_is_a_clear_error(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
@metamorphic(source=st.integers(), followup=lambda x: [x], relation=relations.equal())
def test_x(x):
    return x
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*InvalidArgument: followup of relation 'equal' returned [[]0[]], not a Hypothesis "
            "strategy*"
        ]
    )


def test_given_and_metamorphic_together_is_an_error(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
from hypothesis import given

@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal())
@given(st.integers())
def test_x(x):
    return x
""",
    )
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*already a Hypothesis test; use @metamorphic instead of @given*"])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--mt-followups", "0"], "--mt-followups=0 must be between 1 and 100"),
        (["-o", "mt_followups=many"], "ini mt_followups='many' must be an integer"),
    ],
)
def test_bad_configuration_is_a_usage_error(
    pytester: pytest.Pytester, args: list[str], message: str
) -> None:
    pytester.makepyfile(test_x="def test_x():\n    pass\n")
    result = pytester.runpytest(*args)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"*{message}*"])


def test_report_path_that_is_a_directory_is_a_usage_error(pytester: pytest.Pytester) -> None:
    pytester.mkdir("out")
    pytester.makepyfile(test_x="def test_x():\n    pass\n")
    result = pytester.runpytest("--mt-report", "out")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--mt-report=out is a directory*"])


def test_marker_is_added_and_selectable(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
@settings(database=None, max_examples=5)
@metamorphic(source=st.integers(), followup=lambda x: st.just(x), relation=relations.equal())
def test_mt(x):
    return x

def test_plain():
    pass
""",
    )
    result = pytester.runpytest("-m", "metamorphic")
    result.assert_outcomes(passed=1, deselected=1)


CAMPAIGN = """
import numpy as np
from pytest_metamorphic import relations
from pytest_metamorphic.core.campaign import Campaign, campaign_test

def source(rng, index):
    return tuple(int(x) for x in rng.integers(0, 5, size=int(rng.integers(1, 6))))

def followup(xs, size, rng):
    return xs + tuple(int(x) for x in rng.integers(0, 5, size=size))

def system(xs):
    # Bug: more than 6 elements and the first distinct value is lost.
    values = sorted(set(xs))
    return values[1:] if len(xs) > 6 else values

test_dedupe = campaign_test(
    Campaign("dedupe", source, followup, system, relations.subset(), sizes=(1, 3),
             sources=40, followups=2, seed=3),
    shards=4,
    max_rate=None,  # these tests are about shards and logs; tests/plugin/test_campaign_gate.py
)
"""


def test_campaign_tests_are_skipped_without_the_option(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_c=CAMPAIGN)
    result = pytester.runpytest("-rs")
    result.assert_outcomes(skipped=4)
    result.stdout.fnmatch_lines(["*campaign: run with --mt-campaign*"])


def _campaign_report(pytester: pytest.Pytester, *args: str) -> dict:
    result = pytester.runpytest_subprocess("--mt-campaign", *args)
    result.assert_outcomes(passed=4)
    result.stdout.fnmatch_lines(
        [
            "*= campaign dedupe =*",
            "campaign 'dedupe', seed 3, 40 sources (35 distinct source inputs) x 2 sizes*"
            "(complete)*",
        ]
    )
    folder = pytester.path / "mt-campaigns" / "dedupe"
    assert (folder / "report.md").exists() and (folder / "campaign.png").exists()
    return outcome(json.loads((folder / "report.json").read_text()))


def outcome(report: dict) -> dict:
    """A campaign report without how it ran (engine, workers, seconds)."""
    assert report["execution"], "the report records how the campaign ran"
    return {key: value for key, value in report.items() if key != "execution"}


def test_campaign_under_xdist_equals_single_process(pytester: pytest.Pytester) -> None:
    pytest.importorskip("xdist")
    pytester.makepyfile(test_c=CAMPAIGN)
    single = _campaign_report(pytester)
    distributed = _campaign_report(pytester, "-n", "2")
    assert single == distributed
    assert single["sizes"]["3"]["violations"] > 0
    assert single["sut_calls"] == 40 * (1 + 2 * 2)


def test_interrupted_campaign_resumes(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_c=CAMPAIGN)
    # Only shards 0 and 1 run: the merged report says it is partial.
    # Subprocesses: the reports import matplotlib, which cannot be re-imported in-process.
    result = pytester.runpytest_subprocess("--mt-campaign", "-k", "shard0 or shard1")
    result.stdout.fnmatch_lines(["*PARTIAL: 20 of 40 sources*"])
    logs = sorted((pytester.path / "mt-campaigns" / "dedupe").glob("shard-*.jsonl"))
    assert [p.name for p in logs] == ["shard-0-of-4.jsonl", "shard-1-of-4.jsonl"]
    before = logs[0].read_text()
    result = pytester.runpytest_subprocess("--mt-campaign", "--mt-resume")
    result.stdout.fnmatch_lines(["*(complete)*"])
    assert logs[0].read_text() == before  # finished work was read back, not redone


def test_resume_without_campaign_is_a_usage_error(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_x="def test_x():\n    pass\n")
    result = pytester.runpytest("--mt-resume")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--mt-resume only makes sense with --mt-campaign*"])


def test_ctrl_c_keeps_the_interrupted_shards_finished_sources(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Source 13 (shard 1's fourth) presses Ctrl-C on the first run.
    interrupting = CAMPAIGN.replace(
        "def source(rng, index):\n",
        "def source(rng, index):\n"
        "    import os\n"
        "    if index == 13 and os.environ.get('MT_PRESS_CTRL_C'):\n"
        "        raise KeyboardInterrupt\n",
    )
    pytester.makepyfile(test_c=interrupting)
    monkeypatch.setenv("MT_PRESS_CTRL_C", "1")
    result = pytester.runpytest_subprocess("--mt-campaign", "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.INTERRUPTED
    # Shard 0 (10 sources) and sources 1, 5, 9 of shard 1.
    result.stdout.fnmatch_lines(["*PARTIAL: 13 of 40 sources*"])
    folder = pytester.path / "mt-campaigns" / "dedupe"
    report = json.loads((folder / "report.json").read_text())
    assert sorted(report["source_indices"]) == sorted([*range(0, 40, 4), 1, 5, 9])
    assert not report["complete"]
    monkeypatch.delenv("MT_PRESS_CTRL_C")
    resumed = pytester.runpytest_subprocess(
        "--mt-campaign", "--mt-resume", "-p", "no:cacheprovider"
    )
    resumed.stdout.fnmatch_lines(["*(complete)*"])
    after_resume = outcome(json.loads((folder / "report.json").read_text()))
    assert after_resume == _campaign_report(pytester)  # a fresh, uninterrupted run


def test_two_campaigns_with_one_name_are_a_usage_error(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_c=CAMPAIGN
        + "\ntest_again = campaign_test(test_dedupe._metamorphic_campaign.campaign)\n"
    )
    result = pytester.runpytest("--mt-campaign")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(
        [
            "*campaign name 'dedupe' is used by both test_c.py::test_dedupe and "
            "test_c.py::test_again*"
        ]
    )


def test_mt_timeout_turns_a_hanging_system_into_a_crash(pytester: pytest.Pytester) -> None:
    _write(
        pytester,
        """
import time

@settings(database=None, max_examples=3)
@metamorphic(source=st.integers(1, 9), followup=lambda x: st.just(-x),
             relation=relations.equal(), followups=1)
def test_hangs(x):
    if x < 0:
        time.sleep(3)
    return abs(x)
""",
    )
    result = pytester.runpytest("--mt-timeout", "0.3", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*SystemTimeout: follow-up 0 of relation 'equal' did not return within 0.3 s*",
            "*SystemUnderTestCrash: the system under test timed out on follow-up 0 of relation*",
        ]
    )
    assert "MetamorphicViolation" not in result.stdout.str()
    pytester.makeini("[pytest]\nmt_timeout = 0.3\n")
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(failed=1)


@pytest.mark.parametrize("value", ["0", "-2", "soon", "inf"])
def test_bad_mt_timeout_is_a_usage_error(pytester: pytest.Pytester, value: str) -> None:
    pytester.makepyfile(test_x="def test_x():\n    pass\n")
    result = pytester.runpytest(f"--mt-timeout={value}")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--mt-timeout*seconds*"])


def test_failure_output_is_about_the_users_code(pytester: pytest.Pytester) -> None:
    """A crash's traceback starts at the user's test (the library's call_with_timeout is
    not printed), and Hypothesis's explanation lists no line of the plugin's own code."""
    _write(
        pytester,
        """
@settings(max_examples=20, database=None)
@metamorphic(source=st.lists(st.integers(), min_size=1), followup=lambda xs: st.permutations(xs),
             relation=relations.equal(), followups=2)
def test_sort(xs):
    return my_sort(xs)

def my_sort(xs):
    if len(xs) > 2 and xs[0] > xs[-1]:
        return list(xs)
    return sorted(xs)

@settings(max_examples=20, database=None)
@metamorphic(source=st.lists(st.integers(), min_size=1), followup=lambda xs: st.permutations(xs),
             relation=relations.equal(), followups=2)
def test_crash(xs):
    return crashy(xs)

def crashy(xs):
    if len(xs) > 3:
        raise ValueError("boom")
    return sorted(xs)
""",
    )
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(failed=2)
    output = result.stdout.str()
    assert "def call_with_timeout" not in output  # before: its source and docstring
    result.stdout.fnmatch_lines(["*return crashy(xs)*", '*raise ValueError("boom")*'])
    package = str(Path(pytest_metamorphic.__file__).resolve().parent)
    explained = [line for line in output.splitlines() if line.startswith("E           /")]
    assert not [line for line in explained if package in line], explained
