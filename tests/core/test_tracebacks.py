"""A failure is reported at the user's test (core/tracebacks.py), and its case reads as what
it is (core/cases.py's pretty printing, as Hypothesis prints "Failing test case")."""

from __future__ import annotations

import traceback

import pytest
from hypothesis.vendor.pretty import pretty

from pytest_metamorphic.core.cases import Followup, MetamorphicCase
from pytest_metamorphic.core.errors import MetamorphicViolation
from pytest_metamorphic.core.tracebacks import raise_at_definition


def _decorated(function):  # stands for @metamorphic: the def line is below the decorator
    return function


@_decorated
def users_test(frame: object) -> object:
    return frame


def test_the_error_is_raised_at_the_def_line_of_the_users_test() -> None:
    error = MetamorphicViolation("relation violated")
    with pytest.raises(MetamorphicViolation) as caught:
        raise_at_definition(users_test, error)
    assert caught.value is error
    last = traceback.extract_tb(caught.value.__traceback__)[-1]
    assert last.filename == __file__
    assert last.lineno == users_test.__code__.co_firstlineno + 1  # the def, not the decorator
    assert last.name == "users_test"
    assert last.line == "def users_test(frame: object) -> object:"


def test_the_cause_of_a_crash_is_kept() -> None:
    try:
        raise ZeroDivisionError("in the system")
    except ZeroDivisionError as cause:
        error = MetamorphicViolation("crashed")
        error.__cause__ = cause
    with pytest.raises(MetamorphicViolation) as caught:
        raise_at_definition(users_test, error)
    assert isinstance(caught.value.__cause__, ZeroDivisionError)


def test_without_source_the_error_is_raised_plainly() -> None:
    error = MetamorphicViolation("no source")
    with pytest.raises(MetamorphicViolation) as caught:
        raise_at_definition(len, error)  # a builtin: no file to point at
    assert caught.value is error


def test_a_case_prints_its_source_and_each_followup_by_its_parameters() -> None:
    followups = (Followup([1, 2, 3], params={"added": 3}), Followup([1, 2, 4], params={"added": 4}))
    case = MetamorphicCase(source=[1, 2], followups={"grows": followups})
    assert pretty(case).splitlines() == [
        "MetamorphicCase(",
        "    source=[1, 2],",
        "    followups={",
        "        'grows': [",
        "            Followup([1, 2, 3], params={added=3}),",
        "            Followup([1, 2, 4], params={added=4}),",
        "        ],",
        "    },",
        ")",
    ]


def test_a_followup_without_parameters_prints_its_input() -> None:
    assert pretty(Followup((3, 1, 2))) == "(3, 1, 2)"
    skipped = Followup.not_applicable([1], "no object to insert")
    assert pretty(skipped) == "Followup.not_applicable('no object to insert')"
