"""Every import path the documentation shows works, and so do the paths of earlier
releases that moved (the README before ``lidar/`` was grouped by concept)."""

from __future__ import annotations

import ast
import functools
import importlib
import importlib.util
import re
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")])
FENCE = re.compile(r"```python\n(.*?)```", re.S)
INLINE_IMPORT = re.compile(r"`(from pytest_metamorphic[\w.]* import [\w, ]+)`")
DOTTED = re.compile(r"\bpytest_metamorphic(?:\.\w+)+")


def _statements(text: str) -> list[str]:
    """Import statements of the package in the document's Python blocks and inline code."""
    found = []
    for block in FENCE.findall(text):
        try:
            tree = ast.parse(block)
        except SyntaxError:  # a snippet with "..." or a prompt: take its import lines
            tree = ast.parse("\n".join(_import_lines(block)))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                found.append(ast.unparse(node))
    found += INLINE_IMPORT.findall(text)
    return [s for s in found if "pytest_metamorphic" in s]


def _import_lines(block: str) -> list[str]:
    lines, statement = [], ""
    for line in block.splitlines():
        if statement or re.match(r"\s*(from|import) pytest_metamorphic", line):
            statement += line.strip() + " "
            if "(" not in statement or ")" in statement:
                lines.append(statement.strip().split("#")[0])
                statement = ""
    return lines


CASES = sorted(
    {
        (doc.relative_to(ROOT).as_posix(), s)
        for doc in DOCUMENTS
        for s in _statements(doc.read_text())
    }
)
NAMES = sorted(
    {
        (doc.relative_to(ROOT).as_posix(), n)
        for doc in DOCUMENTS
        for n in DOTTED.findall(doc.read_text())
    }
)


def test_the_documentation_shows_imports() -> None:
    assert len(CASES) > 10 and len(NAMES) > 20


@pytest.mark.parametrize(("document", "statement"), CASES)
def test_a_documented_import_works(document: str, statement: str) -> None:
    exec(compile(statement, document, "exec"), {})


@functools.cache
def _api_pages() -> Any:
    spec = importlib.util.spec_from_file_location("api_pages", ROOT / "docs" / "api_pages.py")
    assert spec is not None and spec.loader is not None
    pages = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(pages)
    return pages


def _resolves(dotted: str) -> bool:
    """The docs build's own resolution (``docs/api_pages.py``), so both agree."""
    pages = _api_pages()
    return pages.resolve(dotted) is not pages.MISSING


@pytest.mark.parametrize(("document", "dotted"), NAMES)
def test_a_documented_name_exists(document: str, dotted: str) -> None:
    assert _resolves(dotted), f"{document} names {dotted}, which does not exist"


# The lidar modules of 0.1-0.4 (flat paths) -> where they live now.
MOVED = {
    "obstacles": "model.obstacles",
    "frame": "model.frame",
    "cloud": "model.cloud",
    "hdl64": "model.hdl64",
    "evaluation": "judging.evaluation",
    "tolerance": "judging.tolerance",
    "scope": "judging.scope",
    "equivariance": "judging.equivariance",
    "perception": "systems.perception",
    "perception.pipeline": "systems.perception.pipeline",
    "perception.mutants": "systems.perception.mutants",
    "perception.cnnseg": "systems.perception.cnnseg",
    "perception.cnnseg.data": "systems.perception.cnnseg.data",
    "detectors": "systems.detectors",
    "process": "systems.process",
    "offline": "systems.offline",
    "perturb": "followups.perturb",
    "faults": "followups.faults",
    "weather": "followups.weather",
    "symmetry": "followups.symmetry",
    "edit": "followups.edit",
    "insert": "followups.insert",
    "minimize": "followups.minimize",
    "scene": "synthetic",
    "scene.description": "synthetic.description",
    "layout": "synthetic.layout",
}


@pytest.mark.parametrize(("old", "new"), sorted(MOVED.items()))
def test_an_old_path_is_the_new_module(old: str, new: str) -> None:
    before = importlib.import_module(f"pytest_metamorphic.lidar.{old}")
    assert before is importlib.import_module(f"pytest_metamorphic.lidar.{new}")


def test_old_from_imports_give_the_same_objects() -> None:
    from pytest_metamorphic.lidar.obstacles import Box as OldBox
    from pytest_metamorphic.lidar.scene import render

    from pytest_metamorphic.lidar.model.obstacles import Box
    from pytest_metamorphic.lidar.synthetic.render import render as new_render

    assert OldBox is Box and render is new_render


def test_an_old_path_that_would_shadow_an_export_names_the_new_one() -> None:
    # lidar.scene.render was a module; lidar.synthetic exports the function render.
    with pytest.raises(ModuleNotFoundError, match=r"moved to pytest_metamorphic\.lidar\.synthetic"):
        importlib.import_module("pytest_metamorphic.lidar.scene.render")
    from pytest_metamorphic.lidar import synthetic

    assert callable(synthetic.render) and not isinstance(synthetic.render, type(synthetic))


def test_an_unknown_lidar_module_is_still_not_found() -> None:
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("pytest_metamorphic.lidar.no_such_module")
