"""Hypothesis strategies for metamorphic testing, in the style of ``hypothesis.strategies``.

Use as ``from pytest_metamorphic import strategies as mst``. The strategies live in private
submodules whose names never clash with a strategy's (so ``mst.frames`` is always the
function); they are imported on first use, so importing this package costs nothing until a
strategy is used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

# strategy name -> private submodule defining it
_LAZY: dict[str, str] = {
    "frames": "_frames",
    "junctions": "_roi",
    "road_corridors": "_roi",
    "rois": "_roi",
    "simple_polygons": "_roi",
    "scene_frames": "_scenes",
    "scenes": "_scenes",
    "dropped_points": "_noise",
    "duplicated_points": "_noise",
    "noise_inside_roi": "_noise",
    "noise_outside_roi": "_noise",
    "permuted_points": "_noise",
    "rotated_frames": "_noise",
    "dead_beams": "_faults",
    "lost_packets": "_faults",
    "quantized_ranges": "_faults",
    "weathered_frames": "_faults",
    "inserted_objects": "_edits",
    "relocated_objects": "_edits",
    "removed_objects": "_edits",
    "earlier_sweeps": "_history",
    "degraded_earlier_sweeps": "_history",
    "aeb_scenarios": "_driving",
    "ego_speed_changes": "_driving",
    "straight_roads": "_driving",
}

__all__ = [
    "aeb_scenarios",
    "dead_beams",
    "degraded_earlier_sweeps",
    "dropped_points",
    "duplicated_points",
    "earlier_sweeps",
    "ego_speed_changes",
    "frames",
    "inserted_objects",
    "junctions",
    "lost_packets",
    "noise_inside_roi",
    "noise_outside_roi",
    "permuted_points",
    "quantized_ranges",
    "relocated_objects",
    "removed_objects",
    "road_corridors",
    "rois",
    "rotated_frames",
    "scene_frames",
    "scenes",
    "simple_polygons",
    "straight_roads",
    "weathered_frames",
]

if TYPE_CHECKING:  # pragma: no cover
    from pytest_metamorphic.strategies._driving import (
        aeb_scenarios,
        ego_speed_changes,
        straight_roads,
    )
    from pytest_metamorphic.strategies._edits import (
        inserted_objects,
        relocated_objects,
        removed_objects,
    )
    from pytest_metamorphic.strategies._faults import (
        dead_beams,
        lost_packets,
        quantized_ranges,
        weathered_frames,
    )
    from pytest_metamorphic.strategies._frames import frames
    from pytest_metamorphic.strategies._history import degraded_earlier_sweeps, earlier_sweeps
    from pytest_metamorphic.strategies._noise import (
        dropped_points,
        duplicated_points,
        noise_inside_roi,
        noise_outside_roi,
        permuted_points,
        rotated_frames,
    )
    from pytest_metamorphic.strategies._roi import (
        junctions,
        road_corridors,
        rois,
        simple_polygons,
    )
    from pytest_metamorphic.strategies._scenes import scene_frames, scenes


def __getattr__(name: str) -> Any:
    try:
        module = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
