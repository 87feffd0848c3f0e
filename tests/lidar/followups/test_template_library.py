"""Objects for unlabelled recordings: templates cut from labelled sweeps, kept as a
library file, re-cast into a sweep of another sensor."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.followups.insert import (
    ObjectTemplate,
    load_templates,
    object_templates,
    save_templates,
)
from pytest_metamorphic.lidar.followups.insert.catalogue import solid_road_users
from pytest_metamorphic.lidar.followups.insert.reach import domain_placements
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.sensors import VLP16, frame_sensor
from pytest_metamorphic.lidar.synthetic import render
from pytest_metamorphic.lidar.synthetic.layout import random_scene
from tests.core.lidar_cases import labelled_kitti, street
from tests.deterministic import find

SEARCH = settings(
    max_examples=10, derandomize=True, database=None, deadline=None,
    suppress_health_check=list(HealthCheck),
)  # fmt: skip


def test_a_library_round_trips_every_template(tmp_path: Path) -> None:
    templates = object_templates([labelled_kitti(1), street()])
    assert len(templates) >= 3
    path = save_templates(tmp_path / "objects.npz", templates)
    loaded = load_templates(path)
    assert [t.describe() for t in loaded] == [t.describe() for t in templates]
    for a, b in zip(templates, loaded, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
        assert (a.label, a.size, a.view, a.range) == (b.label, b.size, b.view, b.range)
        assert a.spacing == pytest.approx(b.spacing)  # the patch each return stands for
        assert not b.solid


def test_a_whole_mesh_stays_whole_in_a_library_and_goes_to_the_near_field(
    tmp_path: Path,
) -> None:
    solid = solid_road_users()
    loaded = load_templates(save_templates(tmp_path / "meshes.npz", solid))
    assert [t.solid for t in loaded] == [True] * len(solid)
    assert [t.describe() for t in loaded] == [t.describe() for t in solid]
    frame = street()
    adult = next(t for t in loaded if t.source.endswith("[adult close by]"))
    beams = frame_sensor(frame).sensor
    assert domain_placements(frame, adult, reach="near field", layout=beams)
    with np.load(tmp_path / "meshes.npz") as archive:
        arrays = dict(archive)
    index = json.loads(bytes(arrays["index"]).decode())
    index["templates"][0]["solid"] = "yes"
    arrays["index"] = np.frombuffer(json.dumps(index).encode(), dtype=np.uint8)
    np.savez(tmp_path / "forged.npz", **arrays)
    with pytest.raises(DataError, match="template 0: solid must be true or false"):
        load_templates(tmp_path / "forged.npz")


def test_a_library_of_an_earlier_version_loads_with_the_hdl64e_spacing(tmp_path: Path) -> None:
    path = save_templates(tmp_path / "objects.npz", object_templates(street()))
    with np.load(path) as archive:
        arrays = dict(archive)
    index = json.loads(bytes(arrays["index"]).decode())
    for entry in index["templates"]:
        del entry["spacing"]
    arrays["index"] = np.frombuffer(json.dumps(index).encode(), dtype=np.uint8)
    older = tmp_path / "older.npz"
    np.savez(older, **arrays)
    default = ObjectTemplate.__dataclass_fields__["spacing"].default
    assert load_templates(older)[0].spacing == default
    index["templates"][0]["spacing"] = [0.5, "x"]
    arrays["index"] = np.frombuffer(json.dumps(index).encode(), dtype=np.uint8)
    np.savez(older, **arrays)
    with pytest.raises(DataError, match="template 0: spacing must be two angles"):
        load_templates(older)


def test_messages_name_a_templates_file_not_the_folder_it_lies_in() -> None:
    templates = object_templates([labelled_kitti(1)])
    assert "/" in templates[0].source  # the path on this machine, kept in the library
    assert templates[0].origin.startswith("000001.bin#") and "/" not in templates[0].origin
    assert templates[0].origin in templates[0].describe() and "/" not in templates[0].describe()
    bag = dataclasses.replace(templates[0], source="/home/me/drive.bag [/points_raw #3]#0")
    assert bag.origin == "drive.bag [/points_raw #3]#0"


def test_a_bad_library_is_named(tmp_path: Path) -> None:
    not_npz = tmp_path / "objects.npz"
    not_npz.write_text("hello")
    with pytest.raises(DataError, match=r"objects\.npz.*object-template library: not a zip"):
        load_templates(not_npz)
    other = tmp_path / "other.npz"
    np.savez(other, index=np.frombuffer(b'{"format": "x"}', dtype=np.uint8))
    with pytest.raises(DataError, match="format"):
        load_templates(other)
    templates = object_templates(street())
    path = save_templates(tmp_path / "ok.npz", templates)
    with np.load(path) as archive:
        arrays = dict(archive)
    arrays["f0"] = arrays["f0"] + 10_000  # faces pointing past the vertices
    forged = tmp_path / "forged.npz"
    np.savez(forged, **arrays)
    with pytest.raises(DataError, match="template 0: faces index vertices"):
        load_templates(forged)
    with pytest.raises(InvalidArgument):
        save_templates(tmp_path / "none.npz", [])


def test_hdl64e_templates_are_recast_for_a_vlp16_sweep_without_labels(tmp_path: Path) -> None:
    library = load_templates(save_templates(tmp_path / "lib.npz", object_templates(street())))
    rendered = render(random_scene(np.random.default_rng(7), name="vlp16"), beams=VLP16)
    unlabelled = rendered.with_cloud(PointCloud(rendered.cloud.points))  # x, y, z, i only
    unlabelled = type(rendered)(unlabelled.cloud, roi=rendered.roi)
    assert not unlabelled.boxes and frame_sensor(unlabelled).sensor is VLP16
    nothing = find(
        mst.inserted_objects(unlabelled, road_users=False), lambda f: True, settings=SEARCH
    )
    assert nothing.skipped is not None and "no object to insert" in nothing.skipped
    inserted = find(
        mst.inserted_objects(unlabelled, objects=library), lambda f: True, settings=SEARCH
    )
    assert inserted.skipped is None
    insertion = inserted.params["insert_object"]
    # Re-cast with the VLP-16's beams: its returns lie on VLP-16 elevations, 2 degrees apart.
    xyz = insertion.points[:, :3]
    elevation = np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    beams = np.degrees(VLP16.elevations)
    assert np.abs(elevation[:, None] - beams[None, :]).min(axis=1).max() < 0.05
