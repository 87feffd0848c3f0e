from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument, relations
from pytest_metamorphic.core.campaign import (
    Campaign,
    CampaignProgress,
    CampaignResult,
    SizeCounts,
    merge_results,
    run_campaign,
)
from pytest_metamorphic.core.intervals import wilson


def test_wilson_matches_published_values() -> None:
    # Reference values: Newcombe (1998), Table I, and the closed form.
    rate = wilson(0, 10)
    assert rate.low == 0.0 and rate.high == pytest.approx(0.2775, abs=1e-4)
    rate = wilson(5, 10)
    assert (rate.low, rate.high) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    rate = wilson(81, 263)
    assert (rate.low, rate.high) == pytest.approx((0.2553, 0.3662), abs=1e-4)
    assert str(wilson(0, 0)) == "n/a"
    with pytest.raises(InvalidArgument, match="need 0 <= k <= n"):
        wilson(3, 2)


class Lossy:
    """A system that drops one detection with probability ~ size / 200, reproducibly."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, scene: tuple[int, tuple[str, ...], int]) -> list[str]:
        self.calls += 1
        _, objects, noise = scene
        lose = noise > 0 and np.random.default_rng(noise).random() < noise / 2000
        return list(objects[1:] if lose else objects)


def source(rng: np.random.Generator, index: int) -> tuple[int, tuple[str, ...], int]:
    labels = ("car", "pedestrian", "cyclist")
    return index, tuple(rng.choice(labels, size=int(rng.integers(1, 4)))), 0


def followup(scene: tuple[int, tuple[str, ...], int], size: int, rng: np.random.Generator):
    return scene[0], scene[1], int(rng.integers(1, 10**6)) % (size * 10) + 1


def campaign(system: Lossy, sources: int = 60) -> Campaign:
    return Campaign(
        name="toy MR1",
        source=source,
        followup=followup,
        system=system,
        relation=relations.subset(),
        sizes=(10, 100),
        sources=sources,
        followups=2,
        seed=7,
        category=str,
    )


def test_campaign_counts_rates_and_caching() -> None:
    system = Lossy()
    result = run_campaign(campaign(system))
    assert result.complete
    assert system.calls == result.sut_calls == 60 * (1 + 2 * 2)
    assert result.sut_calls_saved == 60 * 4 - 60
    small, large = result.sizes[10], result.sizes[100]
    assert small.pairs == large.pairs == 120
    assert small.fewer + small.equal + small.more == 120
    assert small.violations == small.fewer  # losing one detection is both
    assert large.violations > small.violations
    assert sum(sum(v) for v in large.categories.values()) >= large.pairs
    data = result.to_json()
    assert data["sizes"]["100"]["rates"]["violations"]["k"] == large.violations
    assert result.examples and "has no match in follow-up" in result.examples[0]["explanation"]


def test_shards_merge_to_the_single_process_result() -> None:
    whole = run_campaign(campaign(Lossy()))
    parts = [run_campaign(campaign(Lossy()), shard=i, shards=3) for i in range(3)]
    merged = merge_results(parts)
    assert merged.outcome_json() == whole.outcome_json()


class Interrupt(BaseException):
    pass


def test_interrupted_campaign_resumes_without_redoing_work(tmp_path: Path) -> None:
    log = tmp_path / "campaign.jsonl"
    system = Lossy()

    def progress(status: CampaignProgress) -> None:
        assert status.total == 60 and status.ran == status.done
        if status.done == 25:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_campaign(campaign(system), log=log, progress=progress)
    lines = log.read_text().splitlines()
    assert len(lines) == 1 + 25  # header + every finished source, nothing lost
    # Simulate a record cut off mid-write by the interruption.
    log.write_text("\n".join(lines) + '\n{"source": 25, "pai')

    resumed_system = Lossy()
    resumed = run_campaign(campaign(resumed_system), log=log, resume=True)
    # Only the sources not finished before, and the two calls that check the log is of
    # this system (the first logged source and its first follow-up, run again).
    assert resumed_system.calls == 35 * 5 + 2
    assert resumed.outcome_json() == run_campaign(campaign(Lossy())).outcome_json()
    # The cut-off line was dropped, not glued to the next record: the log reads back whole.
    again = run_campaign(campaign(Lossy()), log=log, resume=True)
    assert again.outcome_json() == resumed.outcome_json()
    assert again.execution[-1]["resumed"] == 60 and again.execution[-1]["sources"] == 0


def test_resume_refuses_a_log_of_another_campaign(tmp_path: Path) -> None:
    log = tmp_path / "c.jsonl"
    run_campaign(campaign(Lossy(), sources=3), log=log)
    with pytest.raises(InvalidArgument, match="holds results of a different campaign"):
        run_campaign(campaign(Lossy(), sources=4), log=log, resume=True)


def test_rerun_without_resume_keeps_the_old_log(tmp_path: Path) -> None:
    log = tmp_path / "c.jsonl"
    run_campaign(campaign(Lossy(), sources=3), log=log)
    run_campaign(campaign(Lossy(), sources=3), log=log)
    logs = sorted(tmp_path.glob("c*.jsonl"))
    assert len(logs) == 2
    assert all(json.loads(p.read_text().splitlines()[0])["sources"] == 3 for p in logs)


def test_crashes_are_counted_not_fatal() -> None:
    def fragile(scene):
        if scene[2] % 3 == 0 and scene[2]:
            raise RuntimeError("boom")
        return list(scene[1])

    result = run_campaign(
        Campaign(
            "fragile",
            source,
            followup,
            fragile,
            relations.subset(),
            sizes=(10,),
            sources=30,
            followups=3,
            seed=1,
        )
    )
    assert result.sizes[10].crashes > 0
    assert result.sizes[10].pairs == 90


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"sizes": ()}, r"sizes=\(\) must be a non-empty list"),
        ({"sources": 0}, "sources=0 must be an int >= 1"),
        ({"relation": "subset"}, "relation='subset' must be a Relation"),
        ({"seed": -1}, "seed=-1 must be an int >= 0"),
        ({"name": ""}, "name='' must be a non-empty string"),
        ({"name": None}, "name=None must be a non-empty string"),
        ({"size_label": " "}, "size_label=' ' must be a non-empty string"),
    ],
)
def test_bad_campaign_arguments(kwargs: dict, message: str) -> None:
    arguments = {
        "name": "x",
        "source": source,
        "followup": followup,
        "system": Lossy(),
        "relation": relations.subset(),
        **kwargs,
    }
    with pytest.raises(InvalidArgument, match=message):
        Campaign(**arguments)


def test_reports_table_markdown_json_and_chart(tmp_path: Path) -> None:
    from pytest_metamorphic.reports.campaign import (
        format_table,
        write_chart,
        write_json,
        write_markdown,
    )

    result = run_campaign(campaign(Lossy(), sources=20))
    lines = format_table(result)
    assert lines[0].startswith("campaign 'toy MR1', seed 7, 20 sources x 2 sizes x 2 follow-up(s)")
    assert "|O| > |O'|" in lines[1] and "violations of subset[equality]" in lines[1]
    assert any(line.split()[:2] == ["100", "40"] for line in lines)
    first = next(i for i, line in enumerate(lines) if line.startswith("violations by obstacle"))
    assert lines[first].startswith("violations by obstacle (3 of ")
    assert f"{len(result.examples)} kept" in lines[first]
    # grouped: each line names a source, the lost element and how many pairs lost it
    assert all(
        line.startswith("  source ") and ", element #" in line and " pair(s) (n=" in line
        for line in lines[first + 1 :]
    )
    assert len(lines) == first + 4
    write_markdown(result, tmp_path / "r.md")
    assert "| n | pairs |" in (tmp_path / "r.md").read_text()
    write_json(result, tmp_path / "r.json")
    assert json.loads((tmp_path / "r.json").read_text())["complete"] is True
    pytest.importorskip("matplotlib")
    write_chart(result, tmp_path / "r.png")
    assert (tmp_path / "r.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_reports_name_what_a_size_is(tmp_path: Path) -> None:
    """A campaign whose sizes are not noise points says what they are, in the table, the
    examples and the Markdown; the default "n" adds nothing to the log's header, so logs
    written before the label existed still resume."""
    from pytest_metamorphic.reports.campaign import format_table, write_markdown

    assert "size_label" not in campaign(Lossy(), sources=4).header()
    labelled = dataclasses.replace(campaign(Lossy(), sources=20), size_label="dead lasers")
    assert labelled.header()["size_label"] == "dead lasers"
    result = run_campaign(labelled)
    lines = format_table(result)
    assert lines[1].split()[:3] == ["dead", "lasers", "pairs"]
    assert any(line.startswith("  source ") and "dead lasers=" in line for line in lines)
    write_markdown(result, tmp_path / "r.md")
    assert "| dead lasers | pairs |" in (tmp_path / "r.md").read_text()


def test_partial_result_says_it_is_partial(tmp_path: Path) -> None:
    from pytest_metamorphic.reports.campaign import format_table

    partial = run_campaign(campaign(Lossy(), sources=20), shard=0, shards=2)
    assert "PARTIAL: 10 of 20 sources" in format_table(partial)[0]


def test_chart_columns_and_pixels_follow_the_counts(tmp_path: Path) -> None:
    from pytest_metamorphic.reports.campaign import chart_columns, write_chart

    header = {"campaign": "c", "sources": 1, "sizes": [10, 1000]}
    result = CampaignResult(
        header,
        {
            10: SizeCounts(pairs=4, categories={"car": [1, 1, 2], "pedestrian": [0, 4, 0]}),
            1000: SizeCounts(pairs=4, categories={"car": [2, 0, 2]}),
        },
        sources_done={0},
    )
    columns = chart_columns(result)
    assert [(c.category, c.size, c.position) for c in columns] == [
        ("car", 10, 0.0),
        ("car", 1000, 1.0),
        ("pedestrian", 10, 3.0),
        ("pedestrian", 1000, 4.0),
    ]
    assert columns[0].percentages == (25.0, 25.0, 50.0)
    assert columns[1].percentages == (50.0, 0.0, 50.0)
    assert columns[2].percentages == (0.0, 100.0, 0.0)
    assert columns[3].percentages == (0.0, 0.0, 0.0)  # no pedestrians at n=1000
    image = pytest.importorskip("matplotlib.image")
    write_chart(result, tmp_path / "c.png")
    pixels = image.imread(tmp_path / "c.png")[..., :3]
    red = np.all(np.abs(pixels - [0xD6 / 255, 0x27 / 255, 0x28 / 255]) < 0.02, axis=-1)
    blue = np.all(np.abs(pixels - [0x1F / 255, 0x77 / 255, 0xB4 / 255]) < 0.02, axis=-1)
    # Red: 25% + 50% of a column, blue: 50% + 50% (legend swatches are equal for both).
    assert red.sum() / blue.sum() == pytest.approx(0.75, rel=0.05)


def test_follow_ups_that_cannot_be_made_are_not_pairs_and_say_so() -> None:
    """A transform that cannot act on a source (no object to insert) gives
    ``Followup.not_applicable``: the system is not run, no pair is counted, and a size at
    which no follow-up could be made reads NOTHING TESTED, never 0 % of violations."""
    from pytest_metamorphic import Followup
    from pytest_metamorphic.reports.campaign import format_table

    def only_small(scene: tuple[int, tuple[str, ...], int], size: int, rng: np.random.Generator):
        if size > 10:
            return Followup.not_applicable(scene, "nothing to insert at that size")
        return followup(scene, size, rng)

    system = Lossy()
    result = run_campaign(dataclasses.replace(campaign(system, sources=5), followup=only_small))
    assert (result.sizes[10].pairs, result.sizes[10].not_applicable) == (10, 0)
    assert (result.sizes[100].pairs, result.sizes[100].not_applicable) == (0, 10)
    assert system.calls == 5 + 10  # sources and the size-10 follow-ups only
    lines = format_table(result)
    assert any(
        line.startswith("NOTHING TESTED at n=100: none of its 10 follow-ups") for line in lines
    )
    again = SizeCounts.from_json(result.sizes[100].to_json())
    assert again.not_applicable == 10 and again.pairs == 0
