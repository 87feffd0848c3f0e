"""The import paths of modules that moved when ``lidar/`` was grouped by concept (0.9).

``pytest_metamorphic.lidar.obstacles`` and the other flat paths of earlier releases still
import, and give the very module object of the new path (same classes, so ``isinstance``,
pickles and ``mypy``-free code keep working); new code and the documentation use the new
paths. Type checkers do not see these aliases.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
from types import ModuleType

__all__ = ["MOVED", "install"]

PACKAGE = "pytest_metamorphic.lidar"

# old path below ``lidar`` -> new path below ``lidar``; a moved package's submodules follow it
MOVED = {
    "cloud": "model.cloud",
    "frame": "model.frame",
    "obstacles": "model.obstacles",
    "hdl64": "model.hdl64",
    "scene": "synthetic",
    "layout": "synthetic.layout",
    "perturb": "followups.perturb",
    "faults": "followups.faults",
    "weather": "followups.weather",
    "symmetry": "followups.symmetry",
    "edit": "followups.edit",
    "insert": "followups.insert",
    "minimize": "followups.minimize",
    "scope": "judging.scope",
    "equivariance": "judging.equivariance",
    "evaluation": "judging.evaluation",
    "tolerance": "judging.tolerance",
    "perception": "systems.perception",
    "process": "systems.process",
    "detectors": "systems.detectors",
    "offline": "systems.offline",
}


def new_name(fullname: str) -> str | None:
    """The current module path for an old one, or None if ``fullname`` did not move."""
    prefix = PACKAGE + "."
    if not fullname.startswith(prefix):
        return None
    first, _, rest = fullname[len(prefix) :].partition(".")
    if first not in MOVED:
        return None
    return f"{prefix}{MOVED[first]}" + (f".{rest}" if rest else "")


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Answers an old path with the module already imported (or imported now) at its new
    path, so both names are one module object."""

    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        new = new_name(fullname)
        if new is None or importlib.util.find_spec(new) is None:
            return None
        parent, _, child = new.rpartition(".")
        shadowed = getattr(sys.modules.get(parent), child, None)
        if shadowed is not None and not isinstance(shadowed, ModuleType):
            # The import system would set the old name's last part on the (shared) parent
            # package, replacing what the package exports under it (``synthetic.render``
            # the function, not the module).
            raise ModuleNotFoundError(f"{fullname} moved to {new}; import it from there")
        return importlib.util.spec_from_loader(fullname, self, is_package=False)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> None:
        """The default (empty) module; :meth:`exec_module` replaces it."""

    def exec_module(self, module: ModuleType) -> None:
        # The import system returns whatever sys.modules holds under the name after this
        # call, so the real module is used without touching its attributes (its
        # ``__spec__`` keeps the new path).
        new = new_name(module.__name__)
        assert new is not None  # find_spec answered only for moved names
        sys.modules[module.__name__] = importlib.import_module(new)


def install() -> None:
    """Put the finder on ``sys.meta_path`` once per interpreter."""
    if not any(isinstance(finder, _MovedFinder) for finder in sys.meta_path):
        # first, so a stale folder of an old install (a namespace package) cannot shadow it
        sys.meta_path.insert(0, _MovedFinder())
