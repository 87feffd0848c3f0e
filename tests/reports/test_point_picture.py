"""A component's violation is saved with a picture of its returns: coloured by label or
cluster, the changed ones marked, the minimal noise as stars."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import Phase, settings
from hypothesis import strategies as st

from pytest_metamorphic import metamorphic
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import GROUND, PointLabels
from pytest_metamorphic.relations.lidar.components import noise_locality
from tests.core.lidar_cases import kitti
from tests.reports.test_artifacts import run_saving


def test_a_ground_segmenter_that_reads_the_whole_sweep_gets_a_picture(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")

    def whole_sweep_ground(frame: Frame) -> PointLabels:
        # A ground height from the lowest 1 % of the whole sweep: noise far outside the
        # ROI moves it, and returns everywhere change label.
        z = frame.cloud.xyz[:, 2]
        floor = np.percentile(z, 1) + 0.3
        return PointLabels((z < floor).astype(np.int64) * GROUND)

    @settings(database=None, derandomize=True, max_examples=3, phases=[Phase.generate])
    @metamorphic(source=st.just(kitti(1)), relations=[noise_locality("labels", radius=6.0)])
    def test_ground(frame):
        return whole_sweep_ground(frame)

    writer, violation = run_saving(test_ground, tmp_path)
    folder = writer.written[-1]
    (tmp_path / "copy.png").write_bytes((folder / "points.png").read_bytes())
    record = json.loads((folder / "record.json").read_text())
    assert record["picture"] == "points.png"
    assert (folder / "points.png").stat().st_size > 10_000
    assert "returns changed" in str(violation)
