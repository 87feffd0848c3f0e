"""Repository-wide test configuration.

Real third-party data lives beside the repository in ``../shared/data`` (never copied in,
for licence reasons; see its SOURCES.md). ``PYTEST_METAMORPHIC_DATA`` points elsewhere.
Tests that need a file use the ``shared_data`` fixture and skip, naming the path, when the
folder is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

ROOT = Path(__file__).resolve().parent
SHARED_DATA = Path(os.environ.get("PYTEST_METAMORPHIC_DATA", ROOT.parent / "shared" / "data"))

# Under CI Hypothesis's own "ci" profile (derandomized, no database) stays the base. Our
# suite keeps the deadline off: SUTs here render or cluster 100k-point clouds, and timing
# varies with load.
_base = settings.get_profile("ci") if os.environ.get("CI") else settings.get_profile("default")
settings.register_profile(
    "repo", parent=_base, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile("repo")


def _no_constants_from_loaded_modules() -> None:
    """Make derandomized searches independent of which test modules were imported.

    Hypothesis (6.13x and later) mixes literal constants found in the source of every
    *local* module loaded so far into what it generates, and caches them on first use. A
    derandomized test then draws different examples depending on which other test files
    the worker collected before it: ``test_mr1_catches_a_point_budget...`` found its bug
    alone and missed it after ``examples/test_sklearn_detector.py`` was merely imported.
    Tests that assert a bug is found must see the same examples in every selection, under
    xdist too, so the pool of local constants stays empty in this suite. Private API,
    read defensively: on a Hypothesis without it nothing changes.
    """
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:  # pragma: no cover
        return
    if hasattr(providers, "_get_local_constants") and hasattr(providers, "_local_constants"):
        empty = type(providers._local_constants)()

        providers._get_local_constants = lambda: empty


_no_constants_from_loaded_modules()


def shared_data_path(*parts: str) -> Path:
    """Path under the shared data folder; skips the calling test when it is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared test data not found: {path} (set PYTEST_METAMORPHIC_DATA)")
    return path


@pytest.fixture
def shared_data() -> Path:
    """The ``../shared/data`` folder; the test is skipped when it is absent."""
    return shared_data_path()


@pytest.fixture(autouse=True)
def _inner_runs_without_dash(
    request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """pytester's runs load every installed pytest plugin; Dash's (Open3D, of the
    ``components`` extra, brings it) warns under pytest 9, which changes the warning
    counts those tests check. ``-p no:dash`` is harmless where Dash is absent."""
    if "pytester" in request.fixturenames:
        request.getfixturevalue("pytester")  # it clears PYTEST_ADDOPTS when it starts
        monkeypatch.setenv("PYTEST_ADDOPTS", "-p no:dash")
