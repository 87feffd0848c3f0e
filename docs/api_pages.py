"""Pages of the API reference that autosummary cannot write: the strategies, which live in
private modules behind ``pytest_metamorphic.strategies`` (resolved lazily, like
``hypothesis.strategies``)."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

MISSING = object()
"""What :func:`resolve` returns for a dotted name that names nothing."""


def resolve(dotted: str) -> Any:
    """The object a dotted name names (the longest importable module, then attributes:
    ``pytest_metamorphic.lidar.roi.ROI.contains``), or :data:`MISSING`. Shared by the
    docs build (references into the package) and ``tests/test_documented_imports.py``."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            value: Any = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attribute in parts[cut:]:
            if not hasattr(value, attribute):
                return MISSING
            value = getattr(value, attribute)
        return value
    return MISSING


def write_strategies_page(folder: Path) -> None:
    """Start the generated ``api/`` folder afresh with the strategies' page, under the name
    autosummary would give it (``autosummary_generate_overwrite = False`` keeps it)."""
    import shutil

    from pytest_metamorphic import strategies

    shutil.rmtree(folder, ignore_errors=True)

    lines = [
        "pytest\\_metamorphic.strategies",
        "================================",
        "",
        ".. automodule:: pytest_metamorphic.strategies",
        "   :no-members:",
        "",
    ]
    for name in sorted(strategies.__all__):
        lines += [f".. autofunction:: pytest_metamorphic.strategies.{name}", ""]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "pytest_metamorphic.strategies.rst").write_text("\n".join(lines), encoding="utf-8")
