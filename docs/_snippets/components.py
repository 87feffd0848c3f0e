"""docs/components.md runs on the VLP-16 recording of the shared data (the page's
"recordings/*.pcd")."""

import os

import pytest

SUBSTITUTE = {"recordings/*.pcd": f"{DATA}/nebula_velodyne/vlp16/*.pcd"}
if not os.path.exists(f"{DATA}/nebula_velodyne/vlp16"):
    pytest.skip(f"the VLP-16 recording is not in {DATA}", allow_module_level=True)
pytest.importorskip("sklearn", reason="scikit-learn is not installed")
