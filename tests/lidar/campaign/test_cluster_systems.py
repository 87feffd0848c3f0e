"""Systems this project did not write, on a Dask LocalCluster: a scikit-learn detector
(from PyPI, via the example module) and a detector in a separate process. Each gives the
same campaign result as in one process."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

import conftest
from pytest_metamorphic.core.campaign import run_campaign
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.systems.process import ProcessDetector

pytest.importorskip("distributed", reason="the dask extra is not installed")
from pytest_metamorphic.core.campaign.cluster import connect

HERE = Path(__file__).resolve()
SCRIPT = str(HERE.parents[1] / "systems" / "external_detector.py")
ENV = {"PYTHONPATH": str(HERE.parents[3])}


@pytest.fixture(scope="module")
def client():
    with connect("local:2") as client:
        yield client


def catalog() -> FrameCatalog:
    return FrameCatalog(
        conftest.shared_data_path("kitti_openpcdet", "training"), roi=kitti_label_region()
    )


def test_a_scikit_learn_detector_gives_the_same_result_on_the_cluster(client) -> None:
    pytest.importorskip("sklearn")
    path = HERE.parents[3] / "examples" / "test_sklearn_detector.py"
    spec = importlib.util.spec_from_file_location(path.stem, path)
    example = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = example
    try:
        spec.loader.exec_module(example)
        # The example is not on the workers' path: Dask ships the file to every worker
        # (a user's test module that is not on a shared checkout goes the same way).
        client.upload_file(str(path))
        campaign = mr1_campaign(
            example.SklearnDetector(ground="sweep"), name="sk", frames=catalog(), sizes=(1000,)
        )
        alone = run_campaign(campaign)
        spread = run_campaign(campaign, cluster=client)
    finally:
        sys.modules.pop(spec.name, None)
    assert alone.complete and sum(c.pairs for c in alone.sizes.values()) == len(catalog())
    assert spread.outcome_json() == alone.outcome_json()
    assert spread.execution[0]["engine"] == "dask"


def test_a_detector_in_another_process_runs_once_per_worker(client) -> None:
    served = ProcessDetector([sys.executable, SCRIPT, "--serve"], persistent=True, env=ENV)
    campaign = mr1_campaign(served, name="proc", frames=catalog(), sources=4, sizes=(100,))
    alone = run_campaign(campaign)
    served.close()
    spread = run_campaign(campaign, cluster=client)
    assert spread.outcome_json() == alone.outcome_json()
    # Each worker started its own detector process (the pickled detector holds none).
    starts = client.run(lambda: None)
    assert len(spread.execution[0]["units_per_worker"]) == len(starts)
