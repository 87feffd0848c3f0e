"""Intersphinx inventories for numpy, Hypothesis and pytest, written at build time.

Sphinx's intersphinx downloads each project's ``objects.inv``; the docs build runs where
there is no network (CI), so this module writes small inventories of the objects this
reference names, each pointing at its page in the project's real documentation. An
object missing here is shown as plain text, not as a broken link.
"""

from __future__ import annotations

import tempfile
import zlib
from pathlib import Path

# project: (base URL, {object: (role, page#anchor)})
_OBJECTS: dict[str, tuple[str, dict[str, tuple[str, str]]]] = {
    "numpy": (
        "https://numpy.org/doc/stable/",
        {
            "numpy.ndarray": ("class", "reference/generated/numpy.ndarray.html#$"),
            "numpy.random.Generator": ("class", "reference/random/generator.html#$"),
            "numpy.random.default_rng": ("function", "reference/random/generator.html#$"),
            "numpy.typing.NDArray": ("data", "reference/typing.html#$"),
            "numpy.typing.ArrayLike": ("data", "reference/typing.html#$"),
            "numpy.float32": ("class", "reference/arrays.scalars.html#$"),
            "numpy.float64": ("class", "reference/arrays.scalars.html#$"),
            "numpy.int64": ("class", "reference/arrays.scalars.html#$"),
            "numpy.bool_": ("class", "reference/arrays.scalars.html#$"),
            "numpy.dtype": ("class", "reference/generated/numpy.dtype.html#$"),
        },
    ),
    "hypothesis": (
        "https://hypothesis.readthedocs.io/en/latest/",
        {
            "hypothesis.given": ("function", "reference/api.html#$"),
            "hypothesis.settings": ("class", "reference/api.html#$"),
            "hypothesis.HealthCheck": ("class", "reference/api.html#$"),
            "hypothesis.Phase": ("class", "reference/api.html#$"),
            "hypothesis.example": ("class", "reference/api.html#$"),
            "hypothesis.seed": ("function", "reference/api.html#$"),
            "hypothesis.assume": ("function", "reference/api.html#$"),
            "hypothesis.errors.InvalidArgument": ("exception", "reference/api.html#$"),
            "hypothesis.errors.HypothesisException": ("exception", "reference/api.html#$"),
            "hypothesis.strategies.SearchStrategy": ("class", "reference/strategies.html#$"),
            "hypothesis.strategies.DrawFn": ("class", "reference/strategies.html#$"),
            "hypothesis.strategies.composite": ("function", "reference/strategies.html#$"),
            "hypothesis.strategies.integers": ("function", "reference/strategies.html#$"),
            "hypothesis.strategies.lists": ("function", "reference/strategies.html#$"),
            "hypothesis.strategies.sampled_from": ("function", "reference/strategies.html#$"),
        },
    ),
    "pytest": (
        "https://docs.pytest.org/en/stable/",
        {
            "pytest.Config": ("class", "reference/reference.html#$"),
            "pytest.Item": ("class", "reference/reference.html#$"),
            "pytest.Function": ("class", "reference/reference.html#$"),
            "pytest.Session": ("class", "reference/reference.html#$"),
            "pytest.Parser": ("class", "reference/reference.html#$"),
            "pytest.TestReport": ("class", "reference/reference.html#$"),
            "pytest.CallInfo": ("class", "reference/reference.html#$"),
            "pytest.Metafunc": ("class", "reference/reference.html#$"),
            "pytest.Pytester": ("class", "reference/reference.html#$"),
            "pytest.UsageError": ("class", "reference/reference.html#$"),
            "pytest.fixture": ("function", "reference/reference.html#$"),
            "pytest.skip": ("function", "reference/reference.html#$"),
        },
    ),
}


def write_inventories(folder: Path | None = None) -> dict[str, tuple[str, str]]:
    """Write one ``objects.inv`` per project; the ``intersphinx_mapping`` for them."""
    folder = folder or Path(tempfile.mkdtemp(prefix="mt-inventories-"))
    mapping = {}
    for project, (base, objects) in _OBJECTS.items():
        lines = [f"{name} py:{role} 1 {uri} -" for name, (role, uri) in sorted(objects.items())]
        header = (
            "# Sphinx inventory version 2\n"
            f"# Project: {project}\n# Version: \n"
            "# The remainder of this file is compressed using zlib.\n"
        )
        path = folder / f"{project}.inv"
        path.write_bytes(header.encode() + zlib.compress("\n".join(lines).encode() + b"\n"))
        mapping[project] = (base, str(path))
    return mapping
