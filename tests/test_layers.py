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


# Inside ``lidar``: each concept group imports only from the groups before it (the order a
# metamorphic test runs through them); ``_moved`` (old import paths) is outside the order.
LIDAR_GROUPS = (
    "model",
    "io",
    "roi",
    "synthetic",
    "judging",
    "systems",
    "followups",
    "campaign",
)
LIDAR = PACKAGE / "lidar"
# A module past this many lines holds several concepts (the project's rule).
MAX_LINES = 600


def _lidar_group(module: str) -> str | None:
    parts = module.split(".")
    if parts[:2] != ["pytest_metamorphic", "lidar"] or len(parts) < 3:
        return None
    return parts[2]


@pytest.mark.parametrize(
    "path",
    sorted(LIDAR.rglob("*.py")),
    ids=lambda p: str(p.relative_to(LIDAR)),
)
def test_lidar_groups_import_only_earlier_groups(path: Path) -> None:
    relative = path.relative_to(LIDAR)
    group = relative.parts[0].removesuffix(".py")
    if group in ("__init__", "_moved"):
        return
    assert group in LIDAR_GROUPS, f"lidar/{group} is not in LIDAR_GROUPS: place it in the order"
    for line, module in _imports(path):
        target = _lidar_group(module)
        if target is None or target == group:
            continue
        assert target in LIDAR_GROUPS, f"lidar/{relative}:{line} imports {module}"
        assert LIDAR_GROUPS.index(target) < LIDAR_GROUPS.index(group), (
            f"lidar/{relative}:{line} imports {module}: {target} comes after {group}"
        )


def test_lidar_is_concept_groups_with_few_loose_modules() -> None:
    loose = sorted(p.name for p in LIDAR.glob("*.py"))
    assert loose == ["__init__.py", "_moved.py"]
    groups = sorted(p.name for p in LIDAR.iterdir() if (p / "__init__.py").exists())
    assert groups == sorted(LIDAR_GROUPS)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _package_imports(path: Path, modules: set[str]) -> set[str]:
    """Package modules ``path`` imports, anywhere in it: at the top, inside functions and
    in ``TYPE_CHECKING`` blocks (a type-only import is a dependency too: it closes a
    circle for the type checker and for a reader). ``from package import name`` counts as
    importing the submodule when ``name`` is one."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name in modules}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                name = f"{node.module}.{alias.name}"
                if name in modules:
                    found.add(name)
                elif node.module in modules:
                    found.add(node.module)
    return found


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), or a module that
    imports itself."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph.get(node, ())):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1 or node in graph.get(node, ()):
                circles.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return circles


def test_no_import_circle_anywhere_in_the_package() -> None:
    paths = {_module_name(path): path for path in PACKAGE.rglob("*.py")}
    graph = {name: _package_imports(path, set(paths)) for name, path in paths.items()}
    assert _circles(graph) == []


def test_the_circle_check_finds_a_circle() -> None:
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


@pytest.mark.parametrize(
    "path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE))
)
def test_modules_hold_one_concept(path: Path) -> None:
    lines = len(path.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{path.relative_to(PACKAGE)}: {lines} lines; split it"
