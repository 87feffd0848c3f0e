"""docs/lidar.md: its KITTI folder is the shared data's; my_stack is the reference pipeline."""

import os

import pytest

from pytest_metamorphic.lidar.systems.perception import ReferencePerception

SUBSTITUTE = {"data/kitti/training": f"{DATA}/kitti_openpcdet/training"}
if not os.path.exists(f"{DATA}/kitti_openpcdet/training"):
    pytest.skip(f"the KITTI sweeps are not in {DATA}", allow_module_level=True)
my_stack = ReferencePerception()
