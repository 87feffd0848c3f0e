"""The coverage of a run: which cells of the operating domain its follow-ups reached, and
the bands the summary names as never reached."""

from __future__ import annotations

import json

import pytest

from pytest_metamorphic.core.relations import CheckContext, Verdict
from pytest_metamorphic.core.stats import RelationStats
from pytest_metamorphic.lidar.judging.coverage import domain_cells, unreached
from pytest_metamorphic.lidar.model.pose import SensorPose
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.reports.summary import SessionSummary
from pytest_metamorphic.reports.summary import TestSummary as Summary
from tests.core.lidar_cases import street


def test_a_follow_up_reaches_the_distance_bearing_class_and_density_of_what_it_judged() -> None:
    frame = street()
    boxes = ReferencePerception()(frame)
    pose = SensorPose(pitch_deg=2.4, height_m=-0.07)
    context = CheckContext(frame, pose.apply(frame), pose.params(), 0)
    cells = domain_cells(context, boxes, boxes, Verdict(True, "x", details={"judged": 3}))
    assert "judged distance: 5-20 m" in cells and "judged distance: 20-40 m" in cells
    assert "judged bearing: front" in cells
    assert {"judged class: car", "judged class: pedestrian"} <= set(cells)
    assert "judged returns: 1000 or more (dense)" in cells  # the car 12 m away
    assert "pose pitch: +2 to +3°" in cells and "pose height: -0.05 to -0.1 m" in cells
    # A check that judged nothing reached no object; the pose it drew is still counted.
    nothing = domain_cells(context, boxes, boxes, Verdict(True, "x", details={"judged": 0}))
    assert nothing == ["pose pitch: +2 to +3°", "pose height: -0.05 to -0.1 m"]
    # Outputs that are not boxes (a component's labels) reach no object cell.
    assert domain_cells(context, [1, 2], [1, 2], Verdict(True, "x")) == nothing


def test_the_gaps_are_the_bands_of_a_dimension_the_relation_reached_elsewhere() -> None:
    coverage = {
        "judged distance: 5-20 m": 4,
        "judged bearing: front": 4,
        "pose pitch: +1 to +2°": 1,
    }
    gaps = unreached(coverage)
    assert (
        "judged distance: none 0-5 m (near field), none 20-40 m, none 40-70 m, none 70 m and beyond"
    ) in gaps
    assert "judged bearing: none left, none rear, none right" in gaps
    assert not any(line.startswith("placed") for line in gaps)  # never placed: not varied


def test_the_summary_names_what_no_follow_up_reached_and_the_json_keeps_the_counts(
    tmp_path: pytest.TempPathFactory,
) -> None:
    summary = SessionSummary()
    test = summary.tests.setdefault("t", Summary("t"))
    near = {"judged distance: 0-5 m (near field)": 2, "judged distance: 5-20 m": 3}
    far = {"judged distance: 5-20 m": 1, "judged distance: 20-40 m": 1}
    test.relations["a"] = RelationStats(followups=2, coverage=dict(near))
    test.relations["b"] = RelationStats(followups=2, coverage=dict(far))
    lines = summary.format_table()
    assert any(line.startswith("operating domain not reached") for line in lines)
    assert (
        "  judged distance 70 m and beyond: none of the 2 relation(s) that vary it (a; b)" in lines
    )
    # One relation reached the near field: the run tested it, and no line names it.
    assert not any("0-5 m" in line for line in lines)
    # Merged across reports (xdist workers) and kept in the JSON rows.
    merged = RelationStats.from_json(json.loads(json.dumps(test.relations["a"].__dict__)))
    merged.add(RelationStats(coverage={"judged distance: 5-20 m": 1}))
    assert merged.coverage == {"judged distance: 0-5 m (near field)": 2,
                               "judged distance: 5-20 m": 4}  # fmt: skip
    assert summary.rows()[0]["coverage"] == near
