"""docs/campaigns.md: detect() is the reference pipeline, the fault one of its mutants, the
KITTI folder the shared data's. The campaign tests are collected (their arguments checked)
and skipped, as without --mt-campaign."""

import os

import pytest

from pytest_metamorphic.lidar.systems.perception import ReferencePerception, mutant

SUBSTITUTE = {"data/kitti/training": f"{DATA}/kitti_openpcdet/training"}
if not os.path.exists(f"{DATA}/kitti_openpcdet/training"):
    pytest.skip(f"the KITTI sweeps are not in {DATA}", allow_module_level=True)
detect = ReferencePerception()
my_stack_with_fault = mutant("global_ground_plane")
