"""Modules pinned for in-process ``pytester`` runs.

pytester unloads every module a run imported. Two kinds must not be re-imported:
numpy/scipy extension modules (they cannot be loaded twice in one process) and the
engine, whose classes ``pytest_metamorphic`` caches on first lazy access (a test that
gets ``metamorphic`` from one import and ``MetamorphicRelation`` from a later one would
fail an isinstance check that no real session can fail). Importing them here, before any
pytester run, keeps one copy for the whole session whatever order the tests run in.
"""

import numpy  # noqa: F401

import pytest_metamorphic.core.campaign
import pytest_metamorphic.core.engine
import pytest_metamorphic.relations  # noqa: F401
