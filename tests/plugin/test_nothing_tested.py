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


UNKNOWN_ONLY = """
import numpy as np
from hypothesis import HealthCheck, settings, strategies as st
from pytest_metamorphic import metamorphic
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.relations.lidar import mirror_symmetry, rotation_equivariance

ROAD = ROI.from_polygons([[(-30, -10), (30, -10), (30, 10), (-30, 10)]])
CLOUD = PointCloud(np.random.default_rng(0).uniform(-20, 20, size=(2000, 3)))


@settings(max_examples=2, database=None, deadline=None, suppress_health_check=list(HealthCheck))
@metamorphic(source=st.just(Frame(CLOUD, roi=ROAD)),
             relations=[rotation_equivariance(), mirror_symmetry()])
def test_unknown_only(frame):
    return [Box((5.0, 1.0, 0.0), (1.0, 1.0, 1.5), 0.0, "unknown")]
"""


def test_a_detector_of_unknown_obstacles_is_told_why_turns_judged_nothing(
    pytester: pytest.Pytester,
) -> None:
    # First contact: a detector that labels everything "unknown" was told "no obstacle was
    # judged" by rotation and mirror, not why (they judge road-user classes only).
    pytester.makepyfile(test_mt=UNKNOWN_ONLY)
    result = pytester.runpytest("-p", "no:cacheprovider", "--mt-report=report.json")
    result.assert_outcomes(passed=1, warnings=1)
    result.stdout.fnmatch_lines(
        ["*no obstacle (element) was judged in * follow-up(s): every obstacle in scope (2) "
         "was 'unknown', and this relation judges only cars, pedestrians and cyclists*"]
    )  # fmt: skip
    report = json.loads((pytester.path / "report.json").read_text())
    reasons = [r["nothing_tested"] for r in report["tests"][0]["relations"].values()]
    assert all("'unknown'" in reason for reason in reasons), reasons
