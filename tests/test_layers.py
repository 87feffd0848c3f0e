"""The package's dependency direction: core <- domain <- strategies <- relation libraries
<- plugin/reports. Checked on every import statement, including imports inside functions."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "pytest_metamorphic"

# layer of each top-level part; a module may import only from its own layer or lower ones
LAYERS = {
    "core": 0,
    "lidar": 1,
    "driving": 1,
    "strategies": 2,
    "relations": 3,
    "reports": 4,
    "plugin": 4,
}
# Third-party imports a layer must not use (domain code works without Hypothesis).
FORBIDDEN = {"lidar": ("hypothesis",), "driving": ("hypothesis",)}
# pytest_metamorphic.relations re-exports core's generic relations; its library submodules
# (lidar, driving) are the layer above strategies.
ROOT_MODULES = {"relations/__init__.py": 0}


def _part(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "pytest_metamorphic" or len(parts) < 2:
        return None
    return parts[1]


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
            if node.module == "pytest_metamorphic":
                found += [(node.lineno, f"pytest_metamorphic.{a.name}") for a in node.names]
    return found


MODULES = sorted(
    path
    for path in PACKAGE.rglob("*.py")
    if path.relative_to(PACKAGE).parts[0].removesuffix(".py") in LAYERS
)


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_point_down_the_layers(path: Path) -> None:
    relative = path.relative_to(PACKAGE)
    part = relative.parts[0].removesuffix(".py")
    layer = ROOT_MODULES.get(relative.as_posix(), LAYERS[part])
    for line, module in _imports(path):
        target = _part(module)
        if target in LAYERS and target != part:
            target_layer = 0 if module == "pytest_metamorphic.relations" else LAYERS[target]
            assert target_layer <= layer, f"{relative}:{line} imports {module} (a higher layer)"
        for banned in FORBIDDEN.get(part, ()):
            assert module.split(".")[0] != banned, f"{relative}:{line} imports {module}"


def test_the_check_sees_every_part() -> None:
    parts = {path.relative_to(PACKAGE).parts[0].removesuffix(".py") for path in MODULES}
    assert parts == set(LAYERS)
