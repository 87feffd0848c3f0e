"""Violation artifacts: what is written, that it reads back exactly, atomicity, replay.

The LiDAR artifact is made by the engine itself (a KITTI sweep, a perception mutant, MR1
with 1000 points); its minimality is re-checked from the saved files alone.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import Phase, example, settings
from hypothesis import strategies as st

import conftest
from pytest_metamorphic import Followup, MetamorphicCase, MetamorphicViolation, metamorphic
from pytest_metamorphic import relations as rel
from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.core.stats import Recorder, recording
from pytest_metamorphic.lidar.followups.edit import RemoveObject
from pytest_metamorphic.lidar.followups.insert import InsertObject
from pytest_metamorphic.lidar.followups.perturb import NoiseOutsideROI
from pytest_metamorphic.lidar.io import read_bag, read_pcd
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.relations.lidar import (
    mr1_subset,
    object_insertion,
    object_removal,
    outside_noise_invariance,
)
from pytest_metamorphic.reports import artifacts
from pytest_metamorphic.reports.artifacts import (
    ArtifactWriter,
    load_artifact,
    load_case,
    write_artifact,
)
from pytest_metamorphic.reports.replay import example_snippet, replay
from pytest_metamorphic.strategies import frames
from tests.core.lidar_cases import assert_minimal_hiding_set, kitti, labelled_kitti

NODEID = "tests/test_perception.py::test_mr1"
MUTANT = mutant("grid_anchored_at_sweep")


def run_saving(test: Any, root: Path, nodeid: str = NODEID) -> tuple[ArtifactWriter, Any]:
    """Run an @metamorphic test with an artifact writer; return it and the violation."""
    recorder = Recorder(nodeid=nodeid)
    writer = ArtifactWriter(root, nodeid, recorder)
    recorder.on_violation = writer
    with recording(recorder), pytest.raises(MetamorphicViolation) as caught:
        test()
    return writer, caught.value


def mr1_test(system: Any, frame: Any) -> Any:
    @settings(database=None, derandomize=True, max_examples=5, phases=[Phase.generate])
    @metamorphic(source=st.just(frame), relations=[mr1_subset(n=1000)], followups=1)
    def test_mr1(frame):
        return system(frame)

    return test_mr1


@pytest.fixture(scope="module")
def lidar_artifact(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any, Any]:
    frame = kitti(1)
    test = mr1_test(MUTANT, frame)
    writer, violation = run_saving(test, tmp_path_factory.mktemp("artifacts"))
    assert len(writer.written) == 2  # first sight, then the final reduced one
    assert writer.written[0] == writer.written[1]  # the final replaced the first
    return writer.written[-1], violation, test


def test_lidar_artifact_holds_every_file(lidar_artifact) -> None:
    folder, violation, _ = lidar_artifact
    names = {path.name for path in folder.iterdir()}
    expected = {"record.json", "source.pcd", "followup.pcd", "perturbation.pcd", "birdseye.png"}
    assert names == expected
    # Nothing half-written is left beside it.
    assert [p.name for p in folder.parent.iterdir()] == [folder.name]
    assert f"artifacts: {folder}" in str(violation)
    assert folder.parent.name == "tests_test_perception.py__test_mr1"
    assert (folder / "birdseye.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_lidar_record_describes_the_minimal_violation(lidar_artifact) -> None:
    folder, violation, _ = lidar_artifact
    record = json.loads((folder / "record.json").read_text())
    reduction = violation.record.reduction
    assert record["status"] == "final" and record["nodeid"] == NODEID
    assert record["relation"] == violation.record.relation
    minimization = record["minimization"]
    assert minimization["proven_minimal"] is True
    assert minimization["size"] == reduction.size == len(minimization["indices"])
    unreduced = record["params_unreduced"]["noise_outside_roi"]["points"]
    assert minimization["original_size"] == len(unreduced) > 900  # 1000 slots, a few empty
    assert minimization["sut_calls"] == reduction.calls == record["sut_calls"]["minimization"]
    assert record["sut_calls"]["test"] >= reduction.calls
    assert record["seed"] == {"seed": None, "derandomize": True}
    points = np.array(record["params"]["noise_outside_roi"]["points"], dtype=np.float32)
    assert np.array_equal(points, reduction.perturbation.points)
    assert record["params"]["n"] == reduction.size
    hidden = [box["describe"] for box in record["hidden"]]
    # The explanation lists at most 10 unmatched obstacles.
    assert hidden and all(
        f"({name}) of the source" in record["explanation"] for name in hidden[:10]
    )
    assert len(record["outputs"]["source"]) == len(violation.record.source_output)
    assert record["picture"] == "birdseye.png"
    assert record["replay"] == f"pytest --mt-replay {folder}"


def test_lidar_files_read_back_exactly(lidar_artifact) -> None:
    folder, violation, _ = lidar_artifact
    source = violation.record.source
    minimal = violation.record.reduction.perturbation.points
    assert np.array_equal(read_pcd(folder / "source.pcd").points, source.cloud.points)
    followup = read_pcd(folder / "followup.pcd").points
    assert np.array_equal(followup, np.concatenate([source.cloud.points, minimal]))
    assert np.array_equal(read_pcd(folder / "perturbation.pcd").points, minimal)
    artifact = load_artifact(folder)
    frame = artifact.source()
    assert frame.roi.equals(source.roi)
    assert np.array_equal(frame.cloud.points, source.cloud.points)
    params = artifact.followup().params
    assert isinstance(params["noise_outside_roi"], NoiseOutsideROI)
    assert np.array_equal(params["noise_outside_roi"].points, minimal)


def test_minimality_from_the_saved_files_alone(lidar_artifact) -> None:
    folder, _, _ = lidar_artifact
    frame = load_artifact(folder).source()
    points = read_pcd(folder / "perturbation.pcd").points
    assert_minimal_hiding_set(MUTANT, frame, points)


def test_replay_says_whether_the_violation_persists(lidar_artifact) -> None:
    folder, _, test = lidar_artifact
    artifact = load_artifact(folder)
    result = replay(artifact, test._metamorphic)
    assert result.still_fails and "still FAILS" in result.lines()[0]
    fixed = mr1_test(ReferencePerception(), kitti(1))
    result = replay(artifact, fixed._metamorphic)
    assert not result.still_fails and "passes now" in result.lines()[0]
    snippet = "\n".join(result.lines())
    assert (
        f'"mt-regressions" / "{folder.name}"' in snippet and "@example(case=load_case(" in snippet
    )


def test_load_case_makes_a_regression_example(lidar_artifact) -> None:
    folder, _, _ = lidar_artifact
    calls: list[int] = []

    @example(case=load_case(folder))
    @settings(database=None, phases=[Phase.explicit])
    @metamorphic(source=st.just(kitti(1)), relations=[mr1_subset(n=1000)], followups=1)
    def test_regression(frame):
        calls.append(len(frame.cloud))
        return MUTANT(frame)

    with pytest.raises(MetamorphicViolation, match="proven 1-minimal"):
        test_regression()
    assert calls[:2] == [
        len(kitti(1).cloud),
        len(kitti(1).cloud) + len(read_pcd(folder / "perturbation.pcd")),
    ]


# -- plain Python inputs --------------------------------------------------------------------------


class Append:
    def __init__(self, items: Sequence[int]) -> None:
        self.items = list(items)

    def __len__(self) -> int:
        return len(self.items)

    def restrict(self, indices: Sequence[int]) -> Append:
        return Append([self.items[i] for i in indices])

    def apply(self, source: list[int]) -> list[int]:
        return [*source, *self.items]

    def params(self) -> dict[str, Any]:
        return {"n": len(self.items), "append": self}

    def to_json(self) -> dict[str, Any]:
        return {"type": "Append", "items": self.items}


def appended(source: list[int]) -> st.SearchStrategy[Followup]:
    def make(items: list[int]) -> Followup:
        transform = Append(items)
        return Followup(transform.apply(source), transform.params())

    return st.lists(st.integers(0, 99), min_size=1, max_size=40).map(make)


def buggy_max(values: list[int]) -> int:
    return max((v for v in values if not 100 <= v < 200), default=0) if 7 in values else max(values)


MONOTONE = rel.predicate(lambda a, b, ctx: b >= a, name="max never drops")


def plain_test(system: Any = buggy_max, **options: Any) -> Any:
    @settings(database=None, derandomize=True, max_examples=300, **options)
    @metamorphic(
        source=st.lists(st.integers(100, 199), min_size=1, max_size=3),
        followup=appended,
        relation=MONOTONE,
        followups=1,
    )
    def test_plain(values):
        return system(values)

    return test_plain


def test_plain_inputs_are_stored_inline_and_replay(tmp_path: Path) -> None:
    test = plain_test()
    writer, violation = run_saving(test, tmp_path, "tests/t.py::test_plain")
    folder = writer.written[-1]
    record = json.loads((folder / "record.json").read_text())
    assert record["source"] == {"kind": "json", "value": violation.record.source}
    assert record["followup"]["value"] == violation.followup.input
    assert record["params"]["append"] == {"type": "Append", "items": [7]}
    assert record["picture"] is None and sorted(p.name for p in folder.iterdir()) == ["record.json"]
    artifact = load_artifact(folder)
    assert replay(artifact, test._metamorphic).still_fails
    assert not replay(artifact, plain_test(max)._metamorphic).still_fails
    snippet = example_snippet(artifact)
    expression = snippet.split("@example(case=", 1)[1].rsplit(")  #", 1)[0]
    case = eval(expression, {"MetamorphicCase": MetamorphicCase, "Followup": Followup})
    assert case.source == violation.record.source
    assert case.followups["max never drops"][0].input == violation.followup.input


def test_first_violation_is_saved_before_shrinking_and_survives_an_interrupt(
    tmp_path: Path,
) -> None:
    recorder = Recorder(nodeid="tests/t.py::test_plain")
    writer = ArtifactWriter(tmp_path, recorder.nodeid, recorder)
    recorder.on_violation = writer

    def interrupted(values: list[int]) -> int:
        if writer.written:  # the user presses Ctrl-C while Hypothesis shrinks
            raise KeyboardInterrupt
        return buggy_max(values)

    with recording(recorder), pytest.raises(KeyboardInterrupt):
        plain_test(interrupted)()
    (folder,) = writer.written
    record = json.loads((folder / "record.json").read_text())
    assert record["status"] == "found" and record["minimization"] is None
    assert 7 in record["followup"]["value"]


def test_a_failed_write_leaves_the_old_artifact_and_no_debris(tmp_path: Path, monkeypatch) -> None:
    writer, violation = run_saving(plain_test(), tmp_path, "tests/t.py::test_plain")
    folder = writer.written[-1]
    before = (folder / "record.json").read_text()

    def broken(record: Any) -> str:
        raise OSError("disk full")

    monkeypatch.setattr(artifacts, "_hidden", broken)
    with pytest.raises(OSError, match="disk full"):
        write_artifact(violation.record, folder, status="final")
    assert (folder / "record.json").read_text() == before
    assert [p.name for p in folder.parent.iterdir()] == [folder.name]
    # Through the writer a failure becomes part of the message, never a new exception.
    message = ArtifactWriter(tmp_path, "tests/t.py::test_plain")(violation.record, True)
    assert message.startswith("not saved to") and "OSError: disk full" in message


def test_unsupported_inputs_are_described_but_do_not_replay(tmp_path: Path) -> None:
    @settings(database=None, derandomize=True, max_examples=50)
    @metamorphic(
        source=st.frozensets(st.integers(0, 5), min_size=1),
        followup=lambda s: st.just(frozenset()),
        relation=rel.cardinality("<="),
    )
    def test_sets(values):
        return list(values)

    writer, _ = run_saving(test_sets, tmp_path, "tests/t.py::test_sets")
    record = json.loads((writer.written[-1] / "record.json").read_text())
    assert record["source"]["kind"] == "unsupported" and "frozenset" in record["source"]["repr"]
    with pytest.raises(DataError, match="only LiDAR frames, AEB scenarios and JSON values replay"):
        load_artifact(writer.written[-1]).source()


def test_bag_sources_are_saved_as_bags(tmp_path: Path) -> None:
    bag = conftest.shared_data_path("pointcloudset_ouster", "test_converted.bag")
    roi = ROI.from_polygons([[(-3.0, -3.0), (12.0, -3.0), (12.0, 3.0), (-3.0, 3.0)]])
    source = frames(str(bag), roi=roi)

    @settings(database=None, derandomize=True, max_examples=3, phases=[Phase.generate])
    @metamorphic(source=source, relations=[outside_noise_invariance(n=20)], followups=1)
    def test_bag(frame):
        return len(frame.cloud)  # counts points outside the ROI too: broken on purpose

    writer, violation = run_saving(test_bag, tmp_path, "tests/t.py::test_bag")
    folder = writer.written[-1]
    record = json.loads((folder / "record.json").read_text())
    assert record["source"]["bag"] == "source.bag" and record["followup"]["bag"] == "followup.bag"
    assert record["source"]["topic"] == "/os1_cloud_node/points"
    assert record["minimization"]["size"] == 1 and record["minimization"]["proven_minimal"]
    original = violation.record.source.cloud
    assert np.array_equal(read_bag(folder / "source.bag", zeros="keep").points, original.points)
    followup = read_bag(folder / "followup.bag", zeros="keep").points
    assert len(followup) == len(original) + 1


def test_bad_artifact_folders_are_named(tmp_path: Path) -> None:
    with pytest.raises(DataError, match=r"no record\.json"):
        load_artifact(tmp_path)
    (tmp_path / "record.json").write_text("{not json")
    with pytest.raises(DataError, match="artifact record is not valid JSON"):
        load_artifact(tmp_path)
    (tmp_path / "record.json").write_text(json.dumps({"format": "something else"}))
    with pytest.raises(DataError, match="not a pytest-metamorphic artifact"):
        load_artifact(tmp_path / "record.json")
    (tmp_path / "record.json").write_text(json.dumps({"format": artifacts.FORMAT, "version": 99}))
    with pytest.raises(DataError, match="version 99"):
        load_artifact(tmp_path)


def test_to_jsonable_is_json_safe() -> None:
    value = {
        "array": np.arange(3, dtype=np.int16),
        "scalar": np.float32(0.5),
        "nan": float("nan"),
        "nested": [(1, 2), {"inf": float("-inf")}],
        "object": object(),
    }
    encoded = artifacts.to_jsonable(value)
    json.dumps(encoded, allow_nan=False)
    assert encoded["array"] == [0, 1, 2] and encoded["scalar"] == 0.5
    assert encoded["nan"] == "nan" and encoded["nested"] == [[1, 2], {"inf": "-inf"}]
    assert "object object" in encoded["object"]["repr"]


def _edit_test(system: Any, relation: Any, frame: Any) -> Any:
    @settings(database=None, derandomize=True, max_examples=30, deadline=None)
    @metamorphic(source=st.just(frame), relations=[relation], followups=1)
    def test_edit(frame):
        return system(frame)

    return test_edit


@pytest.mark.parametrize(
    ("relation", "faulty", "kind", "sweep"),
    [
        (object_removal(), "count_scaled_radius", RemoveObject, 2),
        (object_insertion(), "nearest_object_list", InsertObject, 5),
    ],
    ids=["removal", "insertion"],
)
def test_object_edit_violations_replay_from_their_artifacts(
    tmp_path: Path, relation: Any, faulty: str, kind: type, sweep: int
) -> None:
    """The edit is saved as JSON (its box, and for an insertion its returns and what they
    hide), rebuilt on replay, and judged again: still failing with the faulty system,
    passing with the reference."""
    # An insertion's templates are the source's labelled objects (ground truth only).
    frame = labelled_kitti(sweep) if kind is InsertObject else kitti(sweep)
    test = _edit_test(mutant(faulty), relation, frame)
    writer, _ = run_saving(test, tmp_path)
    artifact = load_artifact(writer.written[-1])
    edit = artifact.followup().params["remove_object" if kind is RemoveObject else "insert_object"]
    assert isinstance(edit, kind)
    assert replay(artifact, test._metamorphic).still_fails
    fixed = _edit_test(ReferencePerception(), relation, frame)
    assert not replay(artifact, fixed._metamorphic).still_fails


def test_a_large_reduction_keeps_its_record_small_and_replays(tmp_path: Path) -> None:
    # Before: every noise point was written into record.json twice as indented JSON (221 MB
    # for 10^6 points). Above INLINE_ROWS the arrays go to .npy files the record names.
    n = 3 * artifacts.INLINE_ROWS

    def loses_everything_with_noise(frame: Any) -> Any:
        boxes = ReferencePerception()(frame)
        return [] if len(frame.cloud) > len(kitti(1).cloud) else boxes

    @settings(database=None, derandomize=True, max_examples=1, phases=[Phase.generate])
    @metamorphic(source=st.just(kitti(1)), relations=[mr1_subset(n=n)], followups=1)
    def test_big(frame):
        return loses_everything_with_noise(frame)

    writer, violation = run_saving(test_big, tmp_path)
    folder = writer.written[-1]
    record = json.loads((folder / "record.json").read_text())
    assert (folder / "record.json").stat().st_size < 200_000
    unreduced = record["params_unreduced"]["noise_outside_roi"]
    assert unreduced["rows"] > artifacts.INLINE_ROWS and "points" not in unreduced
    saved = np.load(folder / unreduced["file"])
    drawn = violation.record.followup.params["noise_outside_roi"].points
    np.testing.assert_array_equal(saved, drawn)
    assert record["params"]["noise_outside_roi"]["points"]  # the minimal one, small, inline
    followup = load_artifact(folder).followup()
    minimal = violation.record.reduction.perturbation.points
    np.testing.assert_array_equal(followup.params["noise_outside_roi"].points, minimal)


def test_a_saved_array_is_read_only_from_inside_the_folder(tmp_path: Path) -> None:
    record = {"type": "NoiseOutsideROI", "file": "../../etc/passwd", "rows": 5}
    with pytest.raises(DataError, match="leaves the folder"):
        artifacts._decode_params({"noise_outside_roi": record}, tmp_path / "record.json")
    np.save(tmp_path / "p.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    record["file"] = "p.npy"
    with pytest.raises(DataError, match="holds Python objects"):
        artifacts._decode_params({"noise_outside_roi": record}, tmp_path / "record.json")
