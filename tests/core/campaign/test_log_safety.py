"""A campaign log is a record others trust: one writer at a time, and a resume never
blends two systems' results (issue: inputs from outside)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pytest_metamorphic.core.campaign import ShardLogs, run_campaign
from pytest_metamorphic.core.errors import FolderInUse, InvalidArgument, OtherSystemError
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
    del header["system"]
    records = [json.loads(line) for line in lines[1:]]
    for record in records:
        record.pop("digest", None)
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
