"""Modules pinned for in-process ``pytester`` runs.

pytester unloads every module a run imported. Two kinds must not be re-imported:
numpy/scipy extension modules (they cannot be loaded twice in one process) and the
engine, whose classes ``pytest_metamorphic`` caches on first lazy access (a test that
gets ``metamorphic`` from one import and ``MetamorphicRelation`` from a later one would
fail an isinstance check that no real session can fail). Importing them here, before any
pytester run, keeps one copy for the whole session whatever order the tests run in.
"""

import numpy  # noqa: F401
import pytest
from hypothesis import settings

import pytest_metamorphic.core.campaign
import pytest_metamorphic.core.engine
import pytest_metamorphic.relations  # noqa: F401

# What the inner runs of these tests assert (a violation found, its shrunk form, the
# artifacts written) depends on Hypothesis's search. Pinned here for every pytester run,
# in-process (the profile is process-wide) and in a subprocess (the conftest below), so
# the suite gives the same answer with and without CI's derandomized profile.
PINNED_PROFILE = "mt-pytester-pinned"
settings.register_profile(PINNED_PROFILE, derandomize=True, database=None, deadline=None)
PINNED_CONFTEST = f"""
from hypothesis import settings
settings.register_profile({PINNED_PROFILE!r}, derandomize=True, database=None, deadline=None)
settings.load_profile({PINNED_PROFILE!r})
"""


@pytest.fixture(autouse=True)
def _pinned_hypothesis_search(request: pytest.FixtureRequest):
    if "pytester" not in request.fixturenames:
        yield
        return
    pytester = request.getfixturevalue("pytester")
    pytester.makeconftest(PINNED_CONFTEST)
    settings.load_profile(PINNED_PROFILE)
    try:
        yield
    finally:
        settings.load_profile("repo")  # the repository conftest's profile
