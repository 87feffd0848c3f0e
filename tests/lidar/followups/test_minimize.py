"""The LiDAR reductions are found for every perturbation, whatever was imported before.

``lidar.followups.minimize`` registers its adapters when first needed (importing it with
the perturbations would load the matching code into every test). The minimisation
itself is tested in ``tests/core/test_hiding_sets.py`` and ``tests/reports``.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

# A fresh interpreter: in the test process some other test has usually imported the
# reductions already, which is how a broken lookup went unnoticed.
_FRESH = textwrap.dedent(
    """
    import sys

    import numpy as np

    from pytest_metamorphic.core.perturbation import as_reducible
    from pytest_metamorphic.lidar.followups.perturb import (
        DropPoints, DuplicatePoints, NoiseInsideROI, NoiseOutsideROI,
    )

    assert "pytest_metamorphic.lidar.followups.minimize" not in sys.modules


    class UsersNoise(NoiseOutsideROI):  # a subclass in a module of the user's
        pass


    points = np.zeros((3, 4), np.float32)
    values = [
        NoiseOutsideROI(points), NoiseInsideROI(points), UsersNoise(points),
        DropPoints([0, 2]), DuplicatePoints([1]),
    ]
    for value in values:
        reducible = as_reducible(value)
        print(type(reducible).__name__, len(reducible) if reducible is not None else -1)
    """
)


def test_every_lidar_perturbation_is_reducible_in_a_fresh_interpreter() -> None:
    # Regression: when ``perturb`` became a package (its classes moved to
    # ``perturb.noise`` and ``perturb.edits``), the lookup still keyed on the old module
    # name, and an MR1 violation was neither minimised nor saved with its perturbation
    # unless another import had loaded the reductions first.
    result = subprocess.run(
        [sys.executable, "-c", _FRESH], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == [
        "InjectedPointsReduction 3",
        "InjectedPointsReduction 3",
        "InjectedPointsReduction 3",
        "IndexEditReduction 2",
        "IndexEditReduction 1",
    ]
