"""A fuzz round over everything the project reads from outside that is not a recording
(those are fuzzed in ``tests/lidar/io/test_io_fuzz.py``): OSM extracts, violation
artifacts, offline manifests, prediction files and AEB records, corrupted byte-wise and
structurally (a JSON value anywhere replaced by another, a key dropped, the document
wrapped). The contract for each: a result or a project error (DataError, or
ExternalSystemError for a system's output) naming the file; never another exception,
never a hang (an alarm fails the example), never memory out of proportion to the input
(tracemalloc's peak is bounded). About 300 corrupted files per run, seeds drawn by
Hypothesis (derandomized under CI)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from pytest_metamorphic.core.errors import DataError, ExternalSystemError
from pytest_metamorphic.driving.osm import read_osm
from pytest_metamorphic.driving.records import scenario_from_json, scenario_to_json
from pytest_metamorphic.driving.scenario import euro_ncap
from pytest_metamorphic.lidar.systems.offline import OfflinePredictions
from pytest_metamorphic.lidar.systems.process import read_json_predictions
from pytest_metamorphic.reports.artifacts import load_case
from tests.lidar.io.test_io_fuzz import corrupted, guarded
from tests.reports.test_artifact_faults import make

FUZZ = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
PROJECT_ERRORS = (DataError, ExternalSystemError)
MEMORY = 64e6  # bytes: far above any honest parse of these small files

JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.sampled_from([1e308, -1e308, 1e9, 0, -1, "", "../../etc/passwd", "/etc/passwd"])
    | st.text(max_size=12),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=8,
)


def _paths(value: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    found = [path]
    if isinstance(value, dict):
        for key, item in value.items():
            found += _paths(item, (*path, key))
    elif isinstance(value, list):
        for index, item in enumerate(value[:6]):
            found += _paths(item, (*path, index))
    return found


@st.composite
def mutated(draw: Any, document: Any) -> Any:
    """``document`` with 1-3 structural edits."""
    doc = json.loads(json.dumps(document))
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(_paths(doc)))
        kind = draw(st.sampled_from(["replace", "drop", "wrap"]))
        if not path:
            doc = draw(JSON_VALUES) if kind == "replace" else [doc]
            continue
        parent = doc
        for step in path[:-1]:
            parent = parent[step]
        last = path[-1]
        if kind == "drop" and isinstance(parent, dict):
            del parent[last]
        elif kind == "wrap":
            parent[last] = [parent[last]]
        else:
            parent[last] = draw(JSON_VALUES)
    return doc


def outcome(read: Any, named: Path) -> None:
    """``read()`` gives a result or a project error naming ``named``."""
    with guarded(MEMORY):
        try:
            read()
        except PROJECT_ERRORS as error:
            event(type(error).__name__)
            assert str(named) in str(error) or named.name in str(error), error
            return
    event("read")


# -- OSM ----------------------------------------------------------------------------------


@FUZZ
@given(data=st.data())
def test_osm_extracts(shared_data: Path, tmp_path: Path, data: Any) -> None:
    original = (shared_data / "osm_osmnx" / "planet_10.068,48.135_10.071,48.137.osm").read_bytes()
    path = tmp_path / "map.osm"
    path.write_bytes(data.draw(corrupted(original, header=4096)))
    outcome(lambda: read_osm(path), path)


# -- artifacts -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def artifact(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make(tmp_path_factory.mktemp("artifact") / "a")


@FUZZ
@given(data=st.data())
def test_artifact_records(artifact: Path, tmp_path: Path, data: Any) -> None:
    folder = tmp_path / "copy"
    shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(artifact, folder)
    record = folder / "record.json"
    if data.draw(st.booleans()):
        document = data.draw(mutated(json.loads(record.read_text())))
        record.write_text(json.dumps(document))
    else:
        record.write_bytes(data.draw(corrupted(record.read_bytes())))
    outcome(lambda: load_case(folder), record)


# -- offline manifests and prediction files ---------------------------------------------------


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Any]:
    from pytest_metamorphic.core.campaign import campaign_inputs
    from pytest_metamorphic.lidar.campaign import mr1_campaign
    from pytest_metamorphic.lidar.systems.offline import export_dataset
    from pytest_metamorphic.lidar.systems.perception import ReferencePerception

    root = tmp_path_factory.mktemp("offline")
    campaign = mr1_campaign(ReferencePerception(), name="fuzz", sources=1, sizes=(10,))
    manifest = export_dataset(campaign, root / "dataset")
    predictions = root / "predictions"
    predictions.mkdir()
    for entry in json.loads(manifest.read_text())["inputs"]:
        (predictions / f"{entry['id']}.json").write_text(json.dumps({"boxes": []}))
    frame = next(campaign_inputs(campaign, [0])).input
    return root / "dataset", predictions, frame


@FUZZ
@given(data=st.data())
def test_offline_manifests(dataset: tuple[Path, Path, Any], tmp_path: Path, data: Any) -> None:
    folder, predictions, frame = dataset
    copy = tmp_path / "dataset"
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(folder, copy)
    manifest = copy / "manifest.json"
    document = data.draw(mutated(json.loads(manifest.read_text())))
    manifest.write_text(json.dumps(document))

    def read() -> None:
        answers = OfflinePredictions(copy, predictions, format="json")
        try:
            answers(frame)
        except ExternalSystemError as error:  # "not in the dataset": named by the dataset
            assert str(copy) in str(error) or "no predictions" in str(error)
            raise DataError(f"{error}", path=manifest) from None

    outcome(read, manifest)


PREDICTIONS = {
    "boxes": [
        {"center": [10.0, 1.0, -1.0], "size": [4.2, 1.8, 1.5], "yaw": 0.1, "label": "Car",
         "score": 0.9},
        {"center": [20.0, -3.0, -1.0], "size": [0.8, 0.7, 1.7], "yaw": 0.0, "label": "pedestrian"},
    ]
}  # fmt: skip


@FUZZ
@given(data=st.data())
def test_prediction_files(tmp_path: Path, data: Any) -> None:
    path = tmp_path / "p.json"
    if data.draw(st.booleans()):
        path.write_text(json.dumps(data.draw(mutated(PREDICTIONS))))
    else:
        path.write_bytes(data.draw(corrupted(json.dumps(PREDICTIONS).encode())))
    outcome(lambda: read_json_predictions(path), path)


# -- AEB scenario records ---------------------------------------------------------------------


@FUZZ
@given(data=st.data())
def test_aeb_scenario_records(tmp_path: Path, data: Any) -> None:
    document = data.draw(mutated(scenario_to_json(euro_ncap("CPNA-25", ego_speed_kmh=40))))
    path = tmp_path / "scenario.json"

    def read() -> None:
        try:
            scenario_from_json(document)
        except DataError as error:
            raise DataError(str(error), path=path) from None

    outcome(read, path)
