"""Offline campaigns: export, a detector run elsewhere over the files, the same report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import conftest
from pytest_metamorphic.core.campaign import run_campaign
from pytest_metamorphic.core.errors import ExternalSystemError, InvalidArgument
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.io import read_bin
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.systems.offline import (
    OfflinePredictions,
    export_dataset,
    frame_digest,
    offline_campaign,
)
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception

SCRIPT = str(Path(__file__).with_name("external_detector.py"))
ROOT = str(Path(__file__).resolve().parents[3])


def run_elsewhere(dataset: Path, out: Path, fmt: str) -> None:
    """The user's side: a separate process reads velodyne/*.bin, writes one file per id."""
    out.mkdir()
    ids = (dataset / "ImageSets" / "test.txt").read_text().split()
    suffix = "json" if fmt == "json" else "txt"
    requests = "".join(
        f"{dataset / 'velodyne' / f'{key}.bin'}\t{out / f'{key}.{suffix}'}\n" for key in ids
    )
    done = subprocess.run(
        [sys.executable, SCRIPT, "--serve", "--format", fmt],
        input=requests, capture_output=True, text=True, env={"PYTHONPATH": ROOT}, check=True,
    )  # fmt: skip
    assert done.stdout.count("done") == len(ids)


def test_offline_json_predictions_reproduce_the_online_report(tmp_path: Path) -> None:
    campaign = mr1_campaign(
        WholeScenePerception(), name="offline", sources=3, sizes=(10, 1000), followups=2
    )
    online = run_campaign(campaign)
    manifest = export_dataset(campaign, tmp_path / "dataset")
    document = json.loads(manifest.read_text())
    assert len(document["inputs"]) == 3 * (1 + 2 * 2)
    first = document["inputs"][1]
    assert (first["source"], first["size"], first["followup"]) == (0, 10, 0)
    assert first["params"]["n"] == 10
    cloud = read_bin(tmp_path / "dataset" / "velodyne" / f"{first['id']}.bin")
    assert frame_digest(cloud) == first["sha1"]
    run_elsewhere(tmp_path / "dataset", tmp_path / "predictions", "json")
    predictions = OfflinePredictions(tmp_path / "dataset", tmp_path / "predictions", format="json")
    offline = run_campaign(offline_campaign(campaign, predictions))
    assert offline.outcome_json() == online.outcome_json()
    assert offline.sizes[1000].unjudged_changes > 0  # the whole-scene detector saw the noise


def test_offline_kitti_predictions_on_recorded_frames(tmp_path: Path) -> None:
    catalog = FrameCatalog(
        conftest.shared_data_path("kitti_openpcdet", "training"), roi=kitti_label_region()
    )
    campaign = mr1_campaign(
        WholeScenePerception(), name="k", frames=catalog, sources=2, sizes=(100,), followups=2
    )
    online = run_campaign(campaign)
    export_dataset(campaign, tmp_path / "dataset")
    run_elsewhere(tmp_path / "dataset", tmp_path / "labels", "kitti")
    predictions = OfflinePredictions(tmp_path / "dataset", tmp_path / "labels")
    offline = run_campaign(offline_campaign(campaign, predictions))
    # KITTI label files round boxes to 6 decimals: the tallies are the same.
    for size, counts in online.sizes.items():
        assert offline.sizes[size].to_json() == counts.to_json()


def test_offline_errors_are_named(tmp_path: Path) -> None:
    campaign = mr1_campaign(WholeScenePerception(), name="e", sources=1, sizes=(10,))
    export_dataset(campaign, tmp_path / "d")
    with pytest.raises(InvalidArgument, match="exists"):
        export_dataset(campaign, tmp_path / "d")
    (tmp_path / "empty").mkdir()
    predictions = OfflinePredictions(tmp_path / "d", tmp_path / "empty")
    with pytest.raises(ExternalSystemError, match=r"no predictions for input 000000"):
        predictions(campaign.source(campaign.source_rng(0), 0))
    with pytest.raises(ExternalSystemError, match="not in the dataset"):
        predictions(np.zeros((5, 4), dtype=np.float32))
    other = mr1_campaign(WholeScenePerception(), name="e", sources=1, sizes=(10,), seed=1)
    with pytest.raises(InvalidArgument, match="was exported from campaign"):
        offline_campaign(other, predictions)
    with pytest.raises(Exception, match="manifest"):
        OfflinePredictions(tmp_path / "empty", tmp_path / "empty")
    with pytest.raises(InvalidArgument, match="format="):
        OfflinePredictions(tmp_path / "d", tmp_path / "empty", format="csv")  # type: ignore[arg-type]
