"""Whether an object put into a sweep was found, and as what."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.lidar.judging.found import accepted_labels, check_class_rule, found_as
from pytest_metamorphic.lidar.model.obstacles import Box

# A 1 m cube of returns standing at x = 10.
POINTS = np.array(
    [(10.0 + dx, dy, dz) for dx in (-0.4, 0.4) for dy in (-0.4, 0.4) for dz in (0.2, 0.8)]
)


def test_the_class_rules_name_what_counts_as_the_objects_class() -> None:
    assert accepted_labels("pedestrian", "own") == {"pedestrian"}
    assert accepted_labels("pedestrian", "own_or_unknown") == {"pedestrian", "unknown"}
    assert accepted_labels("pedestrian", "any") is None
    with pytest.raises(InvalidArgument, match="classes='best'"):
        check_class_rule("best")


def test_found_as_separates_found_from_found_with_its_class() -> None:
    car = Box((10.0, 0.0, 0.5), (1.2, 1.2, 1.2), 0.0, "car")
    found = found_as(POINTS, [car], accepted_labels("pedestrian", "own_or_unknown"))
    assert found.share == 1.0 and found.share_as == 0.0 and found.main_label() == "car"
    unknown = Box((10.0, 0.0, 0.5), (1.2, 1.2, 1.2), 0.0, "unknown")
    assert (
        found_as(POINTS, [unknown], accepted_labels("pedestrian", "own_or_unknown")).share_as == 1
    )
    assert found_as(POINTS, [unknown], accepted_labels("pedestrian", "own")).share_as == 0
    # Half the object in a box of its class, half in none.
    half = Box((9.6, 0.0, 0.5), (0.4, 1.2, 1.2), 0.0, "pedestrian")
    found = found_as(POINTS, [half], accepted_labels("pedestrian", "own"))
    assert found.share == found.share_as == 0.5
    assert found_as(np.empty((0, 3)), [car], None).main_label() is None
