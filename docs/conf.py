"""Sphinx configuration: the user guide (Markdown, MyST) and the API reference generated
from the package's numpydoc docstrings. Built in CI with warnings as errors:

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, TypeVar

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import pytest_metamorphic  # noqa: E402

project = "pytest-metamorphic"
author = "The pytest-metamorphic Authors"
copyright = "2026, The pytest-metamorphic Authors"
release = version = pytest_metamorphic.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "api/generated/*.tmp"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

# numpydoc-style docstrings, read by napoleon
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True  # an "Attributes" section as fields: dataclass fields are documented once
autosummary_generate = True
autosummary_generate_overwrite = False  # api_pages.py wrote the strategies' page
autosummary_ignore_module_all = True  # list what autodoc documents: what a module defines
# Each object is documented once, in the module that defines it; a reference through a
# package that re-exports it (pytest_metamorphic.lidar.roi.ROI) is resolved to that place
# below. The strategies, defined in private modules, get their own page (api_pages.py).
autodoc_default_options = {
    "members": True,
    "undoc-members": True,  # what autosummary lists: every public name a module defines
    "show-inheritance": True,
    "ignore-module-all": True,
}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# Optional extras the reference mentions but a docs build need not install.
autodoc_mock_imports = [
    "embreex",
    "lzf",
    "onnxruntime",
    "onnx",
    "torch",
    "highway_env",
    "gymnasium",
    "scenariogeneration",
    "distributed",
    "dask",
    "sklearn",
]
html_theme = "furo"
html_title = f"pytest-metamorphic {release}"
html_static_path = ["_static"]
exclude_patterns += ["_snippets"]

# Links into numpy's, Hypothesis's and pytest's documentation. The build must not need
# the network (CI has none), so the inventories are written here from the objects this
# reference names (inventories.py), each pointing at its page on the real site.
from inventories import write_inventories  # noqa: E402

intersphinx_mapping = write_inventories()
intersphinx_disabled_reftypes = ["*"]  # only explicit domain references, never std:doc

# Every Python block of the guide runs during the build (snippets.py); a failing block
# or an output the run does not print is a warning, an error under -W. Off with
# ``-D mt_run_snippets=0`` for a quick local build.
mt_run_snippets = True

# Types in numpydoc fields ("callable(source_input, size, rng)") become cross-references
# word by word; a word that names attributes of several classes ("size") is ambiguous and
# harmless. Unresolved references are not reported by Sphinx unless nitpicky, which would
# flag every "float" and "(n, 3) array" in a type field; instead, a reference into this
# package that does not resolve is a warning (and so an error in CI): a renamed or moved
# module, class or function breaks the build.
suppress_warnings = ["ref.python"]


def _canonical(target: str) -> str | None:
    """Where the object ``target`` names is defined (``module.qualname``), following
    re-exports (``pytest_metamorphic.lidar.roi.ROI.contains``); None if it does not exist."""
    from api_pages import MISSING, resolve

    value = resolve(target)
    if value is MISSING:
        return None
    if isinstance(value, type(sys)):
        return value.__name__
    if isinstance(value, TypeVar):
        return ""  # a type variable in a signature: nothing to link to
    module = getattr(value, "__module__", None)
    qualname = getattr(value, "__qualname__", None)
    return f"{module}.{qualname}" if module and qualname else target


def _resolve_own_reference(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    from sphinx.util import logging

    target = str(node.get("reftarget", ""))
    if node.get("refdomain") != "py" or not target.startswith(("pytest_metamorphic", ".")):
        return None
    if any(part.startswith("_") for part in target.split(".")):
        return None  # a private base class or helper named in a signature: not documented
    canonical = _canonical(target) if target.startswith("pytest_metamorphic") else None
    if canonical == "":
        return None
    if canonical and canonical != target:
        domain = env.get_domain("py")
        for role in (node.get("reftype"), "obj", "mod"):
            found = domain.resolve_xref(
                env, node["refdoc"], app.builder, role, canonical, node, contnode
            )
            if found is not None:
                return found
    logging.getLogger(__name__).warning(
        "unresolved reference to %s", target, location=node, type="mt", subtype="ref"
    )
    return None


def _run_snippets(app: Any) -> None:
    from snippets import pages, run_page
    from sphinx.util import logging

    if not app.config.mt_run_snippets or str(app.config.mt_run_snippets) == "0":
        return
    logger = logging.getLogger(__name__)
    for page in pages():
        run = run_page(page)
        for line, message in run.problems:
            logger.warning(message, location=f"{page}:{line}", type="mt", subtype="snippet")


def setup(app: Any) -> None:
    from api_pages import write_strategies_page

    write_strategies_page(Path(__file__).resolve().parent / "api")
    app.add_config_value("mt_run_snippets", True, "env")
    app.connect("builder-inited", _run_snippets)
    app.connect("missing-reference", _resolve_own_reference)
