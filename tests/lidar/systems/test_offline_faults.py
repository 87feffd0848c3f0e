"""An offline dataset comes back from a detector farm: its manifest is outside data. Ids
cannot lead outside the predictions folder, an edited manifest cannot pair an input with
another input's predictions, and bad structure is named (issue: inputs from outside)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from pytest_metamorphic.core.campaign import campaign_inputs, run_campaign
from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.systems.offline import (
    OfflinePredictions,
    export_dataset,
    offline_campaign,
)
from pytest_metamorphic.lidar.systems.perception import ReferencePerception


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path, Path]:
    """A campaign of 2 sources x 2 follow-ups, exported, with an (empty) prediction file
    per id."""
    root = tmp_path_factory.mktemp("offline")
    campaign = mr1_campaign(ReferencePerception(), name="farm", sources=2, sizes=(10,), followups=2)
    manifest = export_dataset(campaign, root / "dataset")
    predictions = root / "predictions"
    predictions.mkdir()
    for entry in json.loads(manifest.read_text())["inputs"]:
        (predictions / f"{entry['id']}.json").write_text(json.dumps({"boxes": []}))
    return campaign, root / "dataset", predictions


def edited(exported: tuple[Any, Path, Path], tmp_path: Path, edit: Any) -> Path:
    """A copy of the dataset's manifest folder with ``edit(document)`` applied."""
    import shutil

    _, dataset, _ = exported
    copy = tmp_path / "dataset"
    shutil.copytree(dataset, copy)
    document = json.loads((copy / "manifest.json").read_text())
    result = edit(document)
    text = result if isinstance(result, (str, bytes)) else json.dumps(document)
    if isinstance(text, bytes):
        (copy / "manifest.json").write_bytes(text)
    else:
        (copy / "manifest.json").write_text(text)
    return copy


def test_the_untouched_dataset_runs(exported: tuple[Any, Path, Path]) -> None:
    campaign, dataset, predictions = exported
    result = run_campaign(
        offline_campaign(campaign, OfflinePredictions(dataset, predictions, format="json"))
    )
    assert sum(c.crashes for c in result.sizes.values()) == 0


@pytest.mark.parametrize("evil", ["../../evil", "/etc/passwd", "sub/000001", "..", ""])
def test_an_id_that_is_not_a_plain_file_name_is_refused(
    exported: tuple[Any, Path, Path], tmp_path: Path, evil: str
) -> None:
    def edit(document: dict[str, Any]) -> None:
        document["inputs"][1]["id"] = evil

    dataset = edited(exported, tmp_path, edit)
    with pytest.raises(DataError, match=r"inputs\[1\]: id .* is not a plain file name"):
        OfflinePredictions(dataset, exported[2], format="json")


def test_an_id_given_twice_is_refused(exported: tuple[Any, Path, Path], tmp_path: Path) -> None:
    def edit(document: dict[str, Any]) -> None:
        document["inputs"][2]["id"] = document["inputs"][1]["id"]

    with pytest.raises(DataError, match="appears twice"):
        OfflinePredictions(edited(exported, tmp_path, edit), exported[2], format="json")


def test_swapped_ids_are_caught_not_turned_into_violations(
    exported: tuple[Any, Path, Path], tmp_path: Path
) -> None:
    # Before: accepted, and each input was judged on another input's predictions.
    campaign, _, predictions = exported

    def edit(document: dict[str, Any]) -> None:
        first, second = document["inputs"][0], document["inputs"][1]
        first["id"], second["id"] = second["id"], first["id"]

    swapped = OfflinePredictions(edited(exported, tmp_path, edit), predictions, format="json")
    result = run_campaign(offline_campaign(campaign, swapped))
    assert sum(c.violations for c in result.sizes.values()) == 0
    assert result.source_crashes + sum(c.crashes for c in result.sizes.values()) >= 1
    first = next(campaign_inputs(campaign, [0])).input
    with pytest.raises(DataError, match="holds another cloud"):
        swapped(first)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: json.dumps(d["inputs"]), "must be a JSON object, not an array"),
        (lambda d: d.pop("inputs") and None, "has no 'inputs'"),
        (lambda d: d.update(inputs={"a": 1}), "'inputs' must be an array"),
        (lambda d: d["inputs"][0].pop("sha1") and None, r"inputs\[0\] has no 'sha1'"),
        (lambda d: d["inputs"][0].update(sha1="xyz"), "40 hexadecimal"),
        (lambda d: b"\xff\xfe{}", "not UTF-8"),
        (lambda d: "[" * 100_000, "nested too deeply"),
    ],
)
def test_a_broken_manifest_is_named(
    exported: tuple[Any, Path, Path], tmp_path: Path, edit: Any, message: str
) -> None:
    with pytest.raises(DataError, match=message) as info:
        OfflinePredictions(edited(exported, tmp_path, edit), exported[2], format="json")
    assert "manifest.json" in str(info.value)


def test_two_exports_into_one_folder_do_not_mix(
    exported: tuple[Any, Path, Path], tmp_path: Path
) -> None:
    # Before: both reported success, and 9 of 18 files belonged to the other campaign.
    from pytest_metamorphic.core.errors import FolderInUse
    from pytest_metamorphic.core.locks import exclusive

    campaign = exported[0]
    folder = tmp_path / "shared"
    with exclusive(folder / ".export.lock", what="the first export"):
        with pytest.raises(FolderInUse, match="in use by process"):
            export_dataset(campaign, folder)
        assert not (folder / "manifest.json").exists()
    assert export_dataset(campaign, folder).exists()
