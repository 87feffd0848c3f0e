"""Relations: the generic output relations, and ready relation libraries per domain.

``from pytest_metamorphic import relations`` gives the generic relations between a source
output ``O`` and a follow-up output ``O'`` (``equal``, ``subset``, ``superset``,
``cardinality``, ``approx``, ``predicate``; see :mod:`pytest_metamorphic.core.relations`).

The submodules are libraries of ready :class:`~pytest_metamorphic.MetamorphicRelation`
objects (a follow-up strategy plus an output relation) for ``@metamorphic(relations=...)``:

* :mod:`pytest_metamorphic.relations.lidar`: LiDAR obstacle perception (the paper's MR1 and
  its relatives);
* :mod:`pytest_metamorphic.relations.driving`: emergency braking (Iqbal's speed relation).

They build on the strategies, so they are imported only when asked for.
"""

from __future__ import annotations

from pytest_metamorphic.core.relations import *  # noqa: F403 - the generic relations
from pytest_metamorphic.core.relations import __all__ as __all__
