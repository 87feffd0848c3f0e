"""The strategies package: every strategy reachable by name, none shadowed by a module."""

from __future__ import annotations

import importlib
import pkgutil
import types

import pytest

import pytest_metamorphic.strategies as mst


def test_lazy_names_match_the_submodules_exports() -> None:
    exported = {}
    for info in pkgutil.iter_modules(mst.__path__):
        module = importlib.import_module(f"{mst.__name__}.{info.name}")
        assert info.name.startswith("_"), f"{info.name} would shadow a strategy of that name"
        exported.update(dict.fromkeys(module.__all__, info.name))
    assert exported == mst._LAZY
    assert sorted(dir(mst)) == sorted(exported)


@pytest.mark.parametrize("name", sorted(mst._LAZY))
def test_every_strategy_is_a_function_after_its_module_is_imported(name: str) -> None:
    importlib.import_module(f"{mst.__name__}.{mst._LAZY[name]}")
    value = getattr(mst, name)
    assert isinstance(value, types.FunctionType) and value.__name__ == name


def test_unknown_names_raise_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        mst.nothing  # noqa: B018
