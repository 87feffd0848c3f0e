"""Artifacts from another machine are outside data: a record never reads files outside
its folder, never echoes what it read, and bad structure is a DataError naming the field
(issue: inputs from outside)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.lidar.io import write_pcd
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.reports import artifacts
from pytest_metamorphic.reports.artifacts import load_artifact, load_case

SECRET = "root:x:0:0:the first line of a file outside the folder"


BOX = {"center": [1, 2, 3], "size": [1, 1, 1], "yaw": 0, "label": "car", "score": None}


def frame_spec(cloud: str = "source.pcd", **extra: Any) -> dict[str, Any]:
    return {"kind": "frame", "cloud": cloud, **extra}


def make(folder: Path, **changes: Any) -> Path:
    """A small valid artifact folder, with ``changes`` applied to its record."""
    folder.mkdir(parents=True, exist_ok=True)
    write_pcd(PointCloud(np.ones((5, 4), np.float32)), folder / "source.pcd", overwrite=True)
    record = {
        "format": artifacts.FORMAT,
        "version": artifacts.VERSION,
        "nodeid": "tests/test_x.py::test_x",
        "relation": "MR1",
        "source": frame_spec(),
        "followup": frame_spec(),
        "params": {},
        **changes,
    }
    (folder / "record.json").write_text(json.dumps(record))
    return folder


def test_a_valid_record_loads(tmp_path: Path) -> None:
    case = load_case(make(tmp_path / "a"))
    assert len(case.source.cloud) == 5


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    secret = tmp_path / "outside" / "secret.pcd"
    secret.parent.mkdir()
    secret.write_text(SECRET + "\n")
    return secret


@pytest.mark.parametrize("how", ["relative", "absolute", "symlink"])
def test_a_cloud_path_cannot_leave_the_folder(tmp_path: Path, outside: Path, how: str) -> None:
    folder = tmp_path / "artifacts" / "a"
    if how == "relative":
        cloud = os.path.relpath(outside, folder)
    elif how == "absolute":
        cloud = str(outside)
    else:
        folder.mkdir(parents=True)
        (folder / "link").symlink_to(outside.parent)
        cloud = "link/secret.pcd"
    artifact = load_artifact(make(folder, source=frame_spec(cloud)))
    with pytest.raises(DataError, match=r"source\.cloud .* leaves the folder") as info:
        artifact.source()
    assert "root:x" not in str(info.value)  # before: the first line was echoed


def test_a_missing_cloud_file_names_the_record_and_the_field(tmp_path: Path) -> None:
    # found by the outside-data fuzz test: the error named only the missing file, so a
    # user with many artifacts could not tell which record pointed at it
    folder = make(tmp_path / "a", source=frame_spec("0"))
    with pytest.raises(DataError) as info:
        load_case(folder)
    message = str(info.value)
    assert "record.json" in message and "source.cloud (0)" in message
    assert "No such file" in message or "does not exist" in message


def test_a_record_nested_too_deeply_is_a_data_error(tmp_path: Path) -> None:
    folder = make(tmp_path / "a")
    (folder / "record.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(DataError, match="nested too deeply"):  # before: RecursionError
        load_artifact(folder)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"nodeid": 5}, "'nodeid' must be a string"),
        ({"source": []}, "'source' must be an object, not an array"),
        ({"params": "noise"}, "'params' must be an object or null"),
        ({"source": {"kind": 3}}, "'kind' must be a string"),
        ({"source": frame_spec(cloud=None)}, r"source\.cloud must be a file name"),
        ({"source": frame_spec(boxes={"a": 1})}, "'boxes' must be an array"),
        ({"source": frame_spec(boxes=[{"center": [1, 2, 3]}])}, r"boxes\[0\] has no 'size'"),
        ({"source": frame_spec(boxes=[{**BOX, "center": [1, "a", 3]}])}, "cannot be rebuilt"),
        ({"source": frame_spec(roi={"polygons": 3})}, "'polygons' must be an array"),
        ({"source": frame_spec(index="7")}, "'index' must be an integer"),
    ],
)
def test_wrong_field_types_are_named(tmp_path: Path, changes: dict[str, Any], message: str) -> None:
    with pytest.raises(DataError, match=message) as info:
        load_case(make(tmp_path / "a", **changes))
    assert not isinstance(info.value.__cause__, (TypeError, KeyError, AttributeError))


def test_a_perturbation_that_does_not_rebuild_is_named(tmp_path: Path) -> None:
    params = {"noise": {"type": "NoiseOutsideROI", "points": "not numbers"}}
    with pytest.raises(DataError, match=r"params\.noise cannot be rebuilt"):
        load_case(make(tmp_path / "a", params=params))


def test_a_record_that_is_a_fifo_does_not_block(tmp_path: Path) -> None:
    folder = tmp_path / "a"
    folder.mkdir()
    os.mkfifo(folder / "record.json")
    with pytest.raises(DataError, match="FIFO"):
        load_artifact(folder)


def test_replaying_a_bad_record_is_a_usage_error_not_an_internal_error(
    pytester: pytest.Pytester, tmp_path: Path
) -> None:
    folder = make(tmp_path / "a")
    (folder / "record.json").write_text("{" * 50_000)
    result = pytester.runpytest_subprocess("--mt-replay", str(folder))
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--mt-replay:*record.json*"])
    assert "INTERNALERROR" not in result.stdout.str() + result.stderr.str()


def test_picture_titles_cut_the_verdict_at_a_word_and_say_so() -> None:
    from types import SimpleNamespace

    from pytest_metamorphic.reports.violation_picture import _picture_title

    blame = (
        "inserted object detected (>= 30 returns: >= 50% of them in obstacles; wholly in "
        "ROI): the inserted car at (-2.2, -46.6) (53 returns, a labelled car from "
        "synthetic:generated#0) is not detected: 45% of its returns lie in follow-up obstacles"
    )
    record = SimpleNamespace(
        relation="an object inserted", reduction=None,
        minimal_verdict=SimpleNamespace(explanation=blame + "\nsecond line"),
    )  # fmt: skip
    title = _picture_title(record).split("\n")
    assert title[0] == "an object inserted"
    assert "the inserted car at (-2.2, -46.6)" in " ".join(title)  # was cut at "(-2."
    assert all(len(line) <= 110 for line in title[1:]) and len(title) <= 3
    long = SimpleNamespace(
        relation="r", reduction=None, minimal_verdict=SimpleNamespace(explanation=blame * 3)
    )
    lines = _picture_title(long).split("\n")
    assert len(lines) == 3 and lines[-1].endswith(" ...")
    assert all(blame.count(word) for word in lines[1].split())  # whole words only


def test_pictures_mark_only_the_obstacles_the_relation_blames() -> None:
    """The mirror's follow-up boxes are in the mirrored frame: none is an identical twin of
    a source box, so every source obstacle used to be drawn "hidden" (6 of 6, those
    outside the ROI too) while the relation blamed one."""
    from types import SimpleNamespace

    from pytest_metamorphic.core.relations import CheckContext
    from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX
    from pytest_metamorphic.lidar.systems.perception import ReferencePerception
    from pytest_metamorphic.relations.lidar import mirror_symmetry
    from pytest_metamorphic.reports.violation_picture import _hidden, _unjudged
    from tests.core.lidar_cases import street

    frame = street()
    mirror = MirrorAcrossX()
    followup = mirror.apply(frame)
    system = ReferencePerception()
    source_output, followup_output = system(frame), system(followup)
    assert len(source_output) >= 3
    dropped = followup_output[1:]  # the mirrored twin of one obstacle is missing
    verdict = mirror_symmetry().relation.check(
        source_output, dropped, CheckContext(frame, followup, mirror.params(), 0)
    )
    assert not verdict.holds
    record = SimpleNamespace(
        minimal_verdict=verdict, source_output=source_output, minimal_output=dropped
    )
    hidden = _hidden(record)
    assert len(hidden) == len(verdict.details["missing"]) == 1
    gone = followup_output[0]  # the mirrored obstacle taken away, mapped back: hidden[0]
    assert abs(hidden[0].center[0] - gone.center[0]) < 0.1
    assert abs(hidden[0].center[1] + gone.center[1]) < 0.1
    assert not set(map(id, hidden)) & set(map(id, _unjudged(record)))


def test_pictures_draw_a_moved_follow_up_back_in_the_source_frame() -> None:
    import math

    from pytest_metamorphic.lidar.followups.perturb import RotateAboutSensor
    from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX
    from pytest_metamorphic.lidar.systems.perception import ReferencePerception
    from pytest_metamorphic.reports.violation_picture import _in_source_frame
    from tests.core.lidar_cases import street

    frame = street()
    system = ReferencePerception()
    source = sorted(system(frame), key=lambda box: box.center)
    for motion, note in (
        (MirrorAcrossX(), "mirrored back"),
        (RotateAboutSensor(math.radians(90)), "turned back by 90 degrees"),
    ):
        moved = system(motion.apply(frame))
        back, title = _in_source_frame(moved, motion.params())
        assert note in title
        back = sorted(back, key=lambda box: box.center)
        assert len(back) == len(source)
        for box, twin in zip(back, source, strict=True):
            assert math.dist(box.center[:2], twin.center[:2]) < 1e-6
    # Follow-ups that do not move the scene are drawn as they are.
    assert _in_source_frame(source, {"n": 10}) == (source, "")


ROI_SPEC = {"polygons": [[[0, 0], [5, 0], [5, 5]]], "extend_dist": 0.0}


@pytest.mark.parametrize(
    ("roi", "message"),
    [
        # Before: loaded, then MemoryError (149 GiB) at the ROI's first lookup
        ({**ROI_SPEC, "cell_size": 1e-9, "raster_range": 1e9}, "cells a side; at most 16384"),
        ({**ROI_SPEC, "cell_size": 0.25, "raster_range": -3}, "raster_range"),
        ({**ROI_SPEC, "cell_size": float("nan"), "raster_range": 70}, "cell_size"),
    ],
)
def test_an_roi_grid_is_range_checked_on_load(
    tmp_path: Path, roi: dict[str, Any], message: str
) -> None:
    with pytest.raises(DataError, match=rf"source\.roi: .*{message}") as info:
        load_case(make(tmp_path / "a", source=frame_spec(roi=roi)))
    assert "record.json" in str(info.value)
