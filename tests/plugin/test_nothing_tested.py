"""A relation that tested nothing is never a silent pass: a warning by default, a failure
under ``--mt-strict-tested``, and a row in the summary, the JSON report and JUnit."""

from __future__ import annotations

import json

import numpy  # noqa: F401  (pinned: pytester runs must not re-import it)
import pytest

import pytest_metamorphic.core.campaign  # noqa: F401

BODY = """
from hypothesis import settings, strategies as st
from pytest_metamorphic import Followup, MetamorphicRelation, metamorphic, relations
from pytest_metamorphic.core.relations import Relation, Verdict


class JudgesNone(Relation):
    name = "judges none"

    def check(self, source_output, followup_output, context):
        return Verdict(True, self.name, details={"judged": 0})


class JudgesOne(Relation):
    name = "judges one"

    def check(self, source_output, followup_output, context):
        return Verdict(True, self.name, details={"judged": 1})


never = MetamorphicRelation(
    "never applies",
    lambda x: st.just(Followup.not_applicable(x, "no object to insert")),
    relations.equal(),
)
same = MetamorphicRelation("same input", lambda x: st.just(x), relations.equal())
empty = MetamorphicRelation("judges none", lambda x: st.just(x + 1), JudgesNone())
real = MetamorphicRelation("judges one", lambda x: st.just(x + 1), JudgesOne())


@settings(max_examples=5, database=None)
@metamorphic(source=st.integers(0, 10), relations=[never, same, empty, real])
def test_vacuous(x):
    return 0
"""


def test_vacuous_relations_warn_and_are_named_in_the_summary(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_mt=BODY)
    result = pytester.runpytest("--mt-report=report.json", "--junitxml=junit.xml")
    result.assert_outcomes(passed=1, warnings=1)
    result.stdout.fnmatch_lines(
        [
            "*NothingTestedWarning: relation 'never applies' tested nothing: no follow-up "
            "could be made (no object to insert)*",
            "*relation 'same input' tested nothing: every follow-up (*) equalled its source*",
            "*relation 'judges none' tested nothing: no obstacle (element) was judged*",
            "*NOTHING TESTED by 3 relation(s)*",
        ]
    )
    assert "relation 'judges one' tested nothing" not in result.stdout.str()
    report = json.loads((pytester.path / "report.json").read_text())
    relations = report["tests"][0]["relations"]
    assert relations["never applies"]["not_applicable"] == 10  # 5 sources x 2
    assert relations["never applies"]["followups"] == 0  # the system was not run on them
    assert relations["judges one"]["judged"] == relations["judges one"]["followups"] > 0
    assert relations["judges one"]["nothing_tested"] is None
    assert relations["same input"]["unchanged"] == relations["same input"]["followups"]
    junit = (pytester.path / "junit.xml").read_text()
    assert 'name="mt.never applies.nothing_tested"' in junit


def test_strict_fails_a_test_that_tested_nothing(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_mt=BODY)
    result = pytester.runpytest("--mt-strict-tested")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "relation 'never applies' tested nothing: no follow-up could be made*",
            "(--mt-strict-tested)",
        ]
    )


def test_strict_from_the_ini_file_and_a_test_that_tested_something(
    pytester: pytest.Pytester,
) -> None:
    pytester.makeini("[pytest]\nmt_strict_tested = true\n")
    pytester.makepyfile(
        test_mt=BODY.split("@settings")[0]
        + """
@settings(max_examples=5, database=None)
@metamorphic(source=st.integers(0, 10), relations=[real])
def test_real(x):
    return 0
"""
    )
    result = pytester.runpytest("-W", "error::UserWarning")
    result.assert_outcomes(passed=1)
