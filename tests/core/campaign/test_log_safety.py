"""A campaign log is a record others trust: one writer at a time, and a resume never
blends two systems' results (issue: inputs from outside)."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pytest_metamorphic.core.campaign import ShardLogs, run_campaign
from pytest_metamorphic.core.errors import (
    DataError,
    FolderInUse,
    InvalidArgument,
    OtherSystemError,
)
from pytest_metamorphic.core.locks import exclusive
from tests.core.campaign.test_campaign import Lossy, campaign


class Faulty(Lossy):
    """Another system: loses the first object of every scene with noise."""

    def __call__(self, scene):  # type: ignore[no-untyped-def]
        self.calls += 1
        _, objects, noise = scene
        return list(objects[1:] if noise else objects)


class Renamed(Lossy):
    """Same behaviour, another class: a system of another name."""


def interrupted(log: Path, system: Lossy, after: int = 20) -> None:
    """Run until ``after`` sources are logged, then stop as Ctrl-C would."""

    def stop(progress) -> None:  # type: ignore[no-untyped-def]
        if progress.done == after:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign(system), log=log, progress=stop)


def test_the_log_header_names_the_system_and_records_output_digests(tmp_path: Path) -> None:
    log = tmp_path / "log.jsonl"
    run_campaign(campaign(Lossy(), sources=3), log=log)
    header, *records = (json.loads(line) for line in log.read_text().splitlines())
    assert header["system"]["name"].endswith("test_campaign.Lossy")
    assert len(header["system"]["fingerprint"]) == 16
    assert all(len(record["digest"]) == 16 for record in records)


def test_resuming_with_another_system_is_refused(tmp_path: Path) -> None:
    # Before: resumed silently, printing a blend of the two systems' violation rates.
    log = tmp_path / "log.jsonl"
    interrupted(log, Lossy())
    with pytest.raises(OtherSystemError, match="another system under test") as info:
        run_campaign(campaign(Faulty()), log=log, resume=True)
    assert "Lossy" in str(info.value) and "Faulty" in str(info.value)
    # The user says the change is intended: the run goes on from the log.
    result = run_campaign(campaign(Faulty()), log=log, resume="any-system")
    assert result.complete


def test_a_system_changed_in_place_is_caught_by_its_outputs(tmp_path: Path) -> None:
    # Same class, same repr, other behaviour (a model retrained under the same path).
    log = tmp_path / "log.jsonl"
    interrupted(log, Lossy())
    changed = Lossy()
    changed.__class__ = type("Lossy", (Faulty,), {"__module__": Lossy.__module__})
    with pytest.raises(OtherSystemError, match=r"records outputs .* on source 0"):
        run_campaign(campaign(changed), log=log, resume=True)


def test_the_same_system_resumes_to_the_uninterrupted_result(tmp_path: Path) -> None:
    log = tmp_path / "log.jsonl"
    interrupted(log, Lossy())
    resumed = run_campaign(campaign(Lossy()), log=log, resume=True)
    assert resumed.outcome_json() == run_campaign(campaign(Lossy())).outcome_json()


def test_a_system_name_identifies_the_system(tmp_path: Path) -> None:
    log = tmp_path / "log.jsonl"
    named = dataclasses.replace(campaign(Lossy(), sources=30), system_name="detector v1")
    interrupted_named = dataclasses.replace(named, sources=60)
    with pytest.raises(KeyboardInterrupt):
        run_campaign(interrupted_named, log=log, progress=_stop_at(10))
    other = dataclasses.replace(interrupted_named, system_name="detector v2")
    with pytest.raises(OtherSystemError, match="detector v1"):
        run_campaign(other, log=log, resume=True)
    with pytest.raises(InvalidArgument, match="system_name"):
        dataclasses.replace(named, system_name=" ")


def _stop_at(done: int):  # type: ignore[no-untyped-def]
    def stop(progress) -> None:  # type: ignore[no-untyped-def]
        if progress.done == done:
            raise KeyboardInterrupt

    return stop


def test_a_log_of_an_earlier_version_without_a_system_still_resumes(tmp_path: Path) -> None:
    log = tmp_path / "log.jsonl"
    interrupted(log, Lossy())
    lines = log.read_text().splitlines()
    header = json.loads(lines[0])
    del header["system"], header["checked"]  # as 0.4 wrote it: no system, no checks
    records = [json.loads(line) for line in lines[1:]]
    for record in records:
        for key in ("digest", "check", "input"):
            record.pop(key, None)
    log.write_text("\n".join(json.dumps(x) for x in [header, *records]) + "\n")
    resumed = run_campaign(campaign(Renamed()), log=log, resume=True)  # nothing to compare
    assert resumed.complete


def test_resume_takes_true_false_or_any_system(tmp_path: Path) -> None:
    with pytest.raises(InvalidArgument, match="resume="):
        run_campaign(campaign(Lossy(), sources=2), log=tmp_path / "l", resume="yes")  # type: ignore[arg-type]


def test_a_second_writer_of_a_log_fails_at_once_naming_the_first(tmp_path: Path) -> None:
    # Before: no lock; both ran, and the report was whichever finished last.
    log = tmp_path / "log.jsonl"
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from pytest_metamorphic.core.locks import exclusive\n"
         f"with exclusive({str(tmp_path / '.log.jsonl.lock')!r}, what='x'):\n"
         "    print('held', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        started = time.monotonic()
        with pytest.raises(FolderInUse, match=f"in use by process {holder.pid} on"):
            run_campaign(campaign(Lossy(), sources=3), log=log)
        assert time.monotonic() - started < 10  # at once, not after the other finishes
        assert not log.exists()  # nothing was set aside or written
    finally:
        holder.kill()
        holder.wait()
    assert run_campaign(campaign(Lossy(), sources=3), log=log).complete  # died with it


def test_shards_of_one_folder_lock_only_their_own_logs(tmp_path: Path) -> None:
    # pytest-xdist workers write different shards of one folder side by side.
    logs = ShardLogs(tmp_path, 2)
    with logs.lock(range(0, 60, 2)):
        run_campaign(campaign(Lossy()), log=logs, shard=1, shards=2)
        with pytest.raises(FolderInUse, match="shard-0-of-2"):
            run_campaign(campaign(Lossy()), log=logs, shard=0, shards=2)


def test_a_lock_is_released_when_its_holder_ends(tmp_path: Path) -> None:
    lock = tmp_path / "x.lock"
    with exclusive(lock, what="it"), pytest.raises(FolderInUse), exclusive(lock, what="it"):
        pass
    with exclusive(lock, what="it"):
        pass


def test_a_campaign_whose_sources_all_crash_saves_no_calls() -> None:
    # Before: "-2 saved by reusing source outputs".
    def broken(scene):  # type: ignore[no-untyped-def]
        raise RuntimeError("no GPU")

    result = run_campaign(campaign(broken, sources=2))  # type: ignore[arg-type]
    assert result.source_crashes == 2 and result.sut_calls_saved == 0


# -- logs that cannot be forged by accident or by a stale cache -------------------------------


def _logged(tmp_path: Path) -> tuple[Path, list[dict]]:
    """An interrupted run's log (20 of 60 sources), and its lines as JSON."""
    log = tmp_path / "log.jsonl"
    interrupted(log, Lossy())
    return log, [json.loads(line) for line in log.read_text().splitlines()]


def _rewrite(log: Path, lines: list) -> None:
    log.write_text(
        "\n".join(line if isinstance(line, str) else json.dumps(line) for line in lines) + "\n"
    )


def _first_pair_with_a_verdict(records: list[dict]) -> tuple[int, dict]:
    for number, record in enumerate(records[1:], start=2):
        for pair in record["pairs"]:
            if "holds" in pair:
                return number, pair
    raise AssertionError("no pair with a verdict")


def test_an_edited_verdict_is_refused_naming_the_file_and_line(tmp_path: Path) -> None:
    # Before: a record edited to "holds": false resumed as a violation, with no warning.
    log, lines = _logged(tmp_path)
    number, pair = _first_pair_with_a_verdict(lines)
    pair["holds"] = not pair["holds"]
    _rewrite(log, lines)
    with pytest.raises(DataError, match=rf"log\.jsonl:{number}: .*its check does not match"):
        run_campaign(campaign(Lossy()), log=log, resume=True)


def test_an_edited_record_can_be_dropped_and_run_again(tmp_path: Path) -> None:
    fresh = run_campaign(campaign(Lossy()))
    log, lines = _logged(tmp_path)
    number, pair = _first_pair_with_a_verdict(lines)
    pair["holds"] = not pair["holds"]
    _rewrite(log, lines)
    resumed = run_campaign(campaign(Lossy()), log=log, resume=True, unverified="rerun")
    assert [line.split(": ")[0] for line in resumed.dropped] == [f"{log}:{number}"]
    assert resumed.outcome_json()["sizes"] == fresh.outcome_json()["sizes"]  # ran again
    from pytest_metamorphic.reports.campaign import format_table

    assert any("1 logged record(s) did not verify" in line for line in format_table(resumed))


def test_a_record_of_another_system_is_refused(tmp_path: Path) -> None:
    # Before: accepted; the table gained a violation and a phantom "truck" row.
    log, lines = _logged(tmp_path)
    forged = dict(lines[1], source=59, digest="0123456789abcdef")
    forged["pairs"] = [
        {
            "size": 10,
            "followup": 0,
            "o": 1,
            "o2": 0,
            "holds": False,
            "categories": {"truck": [1, 0]},
        }
    ]
    _rewrite(log, [*lines, forged])
    with pytest.raises(DataError, match=rf"log\.jsonl:{len(lines) + 1}: .*check does not match"):
        run_campaign(campaign(Lossy()), log=log, resume=True)


@pytest.mark.parametrize(
    ("change", "words"),
    [
        (lambda r: r.update(source="0"), "source is str, not an integer"),
        (lambda r: r.update(source=10**6), r"source=1000000 is outside \[0, 59\]"),
        (lambda r: r.update(pairs={}), "pairs is dict, not a list"),
        (lambda r: r["pairs"][0].update(size=7), "pair size 7 is not one of the campaign's"),
        (lambda r: r["pairs"][0].update(followup=-1), r"a pair's follow-up=-1 is outside \[0, 1\]"),
    ],
)
def test_a_record_of_wrong_types_is_an_error_not_skipped(
    tmp_path: Path,
    change,
    words: str,  # type: ignore[no-untyped-def]
) -> None:
    log, lines = _logged(tmp_path)
    change(lines[3])
    _rewrite(log, lines)
    with pytest.raises(DataError, match=rf"log\.jsonl:4: {words}"):
        run_campaign(campaign(Lossy()), log=log, resume=True)


def test_a_deeply_nested_record_is_an_error_not_a_recursion_error(tmp_path: Path) -> None:
    log, lines = _logged(tmp_path)
    _rewrite(log, [lines[0], "[" * 100_000 + "]" * 100_000, *lines[1:]])
    with pytest.raises(DataError, match=r"log\.jsonl:2: a record nested too deeply"):
        run_campaign(campaign(Lossy()), log=log, resume=True)


def test_a_fifo_in_place_of_a_shard_log_is_refused(tmp_path: Path) -> None:
    # Before: io.UnsupportedOperation: not seekable.
    folder = tmp_path / "logs"
    folder.mkdir()
    os.mkfifo(folder / "shard-0-of-1.jsonl")
    for resume in (True, False):
        with pytest.raises(DataError, match=r"shard-0-of-1\.jsonl.*FIFO"):
            run_campaign(campaign(Lossy(), sources=4), log=ShardLogs(folder, 1), resume=resume)


def test_a_log_of_other_input_data_is_not_resumed(tmp_path: Path) -> None:
    """A cache restored for another dataset: same campaign, same system, other inputs
    (frames changed on disk). The source is drawn again and compared with its record."""
    log, _ = _logged(tmp_path)

    def other_data(rng, index):  # type: ignore[no-untyped-def]
        return index, ("bus",), 0

    changed = dataclasses.replace(campaign(Lossy()), source=other_data)
    with pytest.raises(DataError, match=r"log\.jsonl:2: .*records source 0 as input .* now"):
        run_campaign(changed, log=log, resume=True)


def test_a_full_disk_fails_the_write_with_a_clear_error_and_keeps_the_log(tmp_path: Path) -> None:
    """RLIMIT_FSIZE stands in for a full disk (Python ignores SIGXFSZ, so the write fails
    with EFBIG like ENOSPC); the run stops, the log keeps every complete record, and a
    resume without the limit finishes the campaign."""
    log = tmp_path / "log.jsonl"
    script = (
        "import resource, sys\n"
        "sys.path.insert(0, sys.argv[2])\n"
        "from tests.core.campaign.test_campaign import Lossy, campaign\n"
        "from pytest_metamorphic.core.campaign import run_campaign\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (6000, 6000))\n"
        "run_campaign(campaign(Lossy()), log=sys.argv[1])\n"
    )
    root = str(Path(__file__).resolve().parents[3])
    done = subprocess.run(
        [sys.executable, "-c", script, str(log), root], capture_output=True, text=True
    )
    assert done.returncode != 0
    assert "CampaignLogError: could not write the campaign log" in done.stderr
    assert "the largest size allowed" in done.stderr and "--mt-resume" in done.stderr
    resumed = run_campaign(campaign(Lossy()), log=log, resume=True)
    assert resumed.complete
    assert (
        resumed.outcome_json()["sizes"] == run_campaign(campaign(Lossy())).outcome_json()["sizes"]
    )
