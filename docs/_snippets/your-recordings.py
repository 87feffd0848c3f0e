"""docs/your-recordings.md runs on the Ouster OS1-64 bag and the VLP-16 PCD of the shared
data (the page's "recordings/drive.bag" and "recordings/*.pcd")."""

import os

import pytest

SUBSTITUTE = {
    '"recordings/drive.bag", topic="/points_raw"': (
        f'"{DATA}/pointcloudset_ouster/test_converted.bag", topic="/os1_cloud_node/points"'
    ),
    "recordings/*.pcd": f"{DATA}/nebula_velodyne/vlp16/*.pcd",
}
if not os.path.exists(f"{DATA}/pointcloudset_ouster") or not os.path.exists(
    f"{DATA}/nebula_velodyne/vlp16"
):
    pytest.skip(f"the Ouster and VLP-16 recordings are not in {DATA}", allow_module_level=True)
