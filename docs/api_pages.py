"""Pages of the API reference that autosummary cannot write: the strategies, which live in
private modules behind ``pytest_metamorphic.strategies`` (resolved lazily, like
``hypothesis.strategies``)."""

from __future__ import annotations

from pathlib import Path


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
