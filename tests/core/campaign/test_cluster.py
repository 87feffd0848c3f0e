"""Campaigns on a Dask LocalCluster: identical results, killed workers, Ctrl-C, resume.

The clusters are real: worker processes started by nannies, talking TCP to a scheduler.
Functions the workers run are module-level here, so the workers import them (they inherit
this process's ``sys.path``), as they would import a user's test module.
"""

from __future__ import annotations

import json
import os
import pickle
import signal
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument, relations
from pytest_metamorphic.core.campaign import (
    Campaign,
    CampaignProgress,
    ShardLogs,
    SystemFactory,
    run_campaign,
)
from pytest_metamorphic.reports.campaign import describe_execution

distributed = pytest.importorskip("distributed", reason="the dask extra is not installed")

from pytest_metamorphic.core.campaign.cluster import (  # noqa: E402
    ClusterError,
    check_address,
    connect,
)

SLEEP = 0.01


def source(rng: np.random.Generator, index: int) -> tuple[int, ...]:
    return tuple(int(v) for v in rng.integers(0, 30, size=6))


def followup(value: tuple[int, ...], size: int, rng: np.random.Generator) -> tuple[int, ...]:
    return value + tuple(int(v) for v in rng.integers(0, 30, size=size))


def lossy(value: tuple[int, ...]) -> list[int]:
    """Drops the smallest element when the input is long: violations to count."""
    time.sleep(SLEEP)
    kept = sorted(set(value))
    return kept[1:] if len(value) > 8 and sum(value) % 3 == 0 else kept


def killer(value: tuple[int, ...]) -> list[int]:
    """Kills the worker process on one particular source, as a segfaulting detector would."""
    if value == POISON:
        os._exit(7)
    return lossy(value)


POISON = source(np.random.default_rng([5, 11]), 11)


def lossy_batches(values: list[tuple[int, ...]]) -> list[list[int]]:
    """``lossy`` as a batch system: one call per batch of inputs."""
    return [lossy(value) for value in values]


def toy(system=lossy, *, sources: int = 40, name: str = "toy") -> Campaign:
    return Campaign(
        name=name,
        source=source,
        followup=followup,
        system=system,
        relation=relations.subset(),
        sizes=(1, 4),
        sources=sources,
        followups=2,
        seed=5,
        category=str,
    )


@pytest.fixture(scope="module")
def client():
    with connect("local:2") as client:
        yield client


def log_sources(paths: list[Path]) -> Counter:
    counts: Counter = Counter()
    for path in paths:
        for line in path.read_text().splitlines()[1:]:
            counts[json.loads(line)["source"]] += 1
    return counts


def test_a_cluster_run_equals_the_one_process_run(client, tmp_path: Path) -> None:
    campaign = toy()
    alone = run_campaign(campaign)
    assert alone.sizes[4].violations > 0  # something to get identical
    spread = run_campaign(campaign, cluster=client, log=tmp_path / "log.jsonl")
    assert spread.outcome_json() == alone.outcome_json()
    (run,) = spread.execution
    assert run["engine"] == "dask" and run["workers"] == 2
    assert len(run["units_per_worker"]) == 2  # both workers took part
    assert run["sources"] == 40 and run["units"] < 40  # guided batches
    assert log_sources([tmp_path / "log.jsonl"]) == Counter(range(40))
    single = run_campaign(campaign, cluster=client, batch_size=1)
    assert single.outcome_json() == alone.outcome_json()
    assert single.execution[0]["units"] == 40


def test_a_batch_system_on_the_cluster_gives_the_one_process_result(client) -> None:
    from pytest_metamorphic.core.batching import batched

    alone = run_campaign(toy())
    spread = run_campaign(toy(batched(lossy_batches, batch_size=3)), cluster=client)
    assert spread.outcome_json() == alone.outcome_json()


def test_a_shard_runs_only_its_sources_on_the_cluster(client) -> None:
    campaign = toy()
    part = run_campaign(campaign, cluster=client, shard=1, shards=3)
    assert part.sources_done == set(range(1, 40, 3))
    assert part.outcome_json() == run_campaign(campaign, shard=1, shards=3).outcome_json()


def test_the_synthetic_mr1_campaign_is_identical_on_the_cluster(client) -> None:
    from pytest_metamorphic.lidar.campaign import mr1_campaign

    campaign = mr1_campaign(
        SystemFactory(_mutant_system, "count_scaled_radius"),
        name="mr1 cluster",
        sources=6,
        sizes=(10, 1000),
    )
    alone = run_campaign(campaign)
    assert alone.sizes[1000].violations > 0
    assert run_campaign(campaign, cluster=client).outcome_json() == alone.outcome_json()


def _mutant_system(name: str):
    from pytest_metamorphic.lidar.systems.perception.mutants import mutant

    faulty = mutant(name)
    return lambda frame: faulty(frame.cloud, frame.roi)


def test_recorded_frames_travel_by_path_and_give_the_same_result(client) -> None:
    from conftest import shared_data_path
    from pytest_metamorphic.lidar.campaign import mr1_campaign
    from pytest_metamorphic.lidar.io.catalog import FrameCatalog
    from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region

    catalog = FrameCatalog(
        shared_data_path("kitti_openpcdet", "training"), roi=kitti_label_region()
    )
    catalog.load(0)  # a cached frame must not travel with the catalog
    assert len(pickle.dumps(catalog)) < 20_000
    campaign = mr1_campaign(
        SystemFactory(_mutant_system, "count_scaled_radius"),
        name="mr1 kitti cluster",
        frames=catalog,
        sizes=(1000,),
    )
    alone = run_campaign(campaign)
    assert alone.complete and alone.sources_done == set(range(len(catalog)))
    assert run_campaign(campaign, cluster=client).outcome_json() == alone.outcome_json()


class _Builds:
    """A factory that leaves one file per build, named by the building process."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def __call__(self):
        (self.folder / f"built-{os.getpid()}-{time.monotonic_ns()}").touch()
        return lossy


def test_a_system_factory_builds_once_per_worker(client, tmp_path: Path) -> None:
    system = SystemFactory(_Builds(tmp_path))
    result = run_campaign(toy(system), cluster=client, batch_size=1)
    builds = sorted(p.name.split("-")[1] for p in tmp_path.glob("built-*"))
    assert len(builds) == len(set(builds)) == len(result.execution[0]["units_per_worker"]) == 2
    assert str(os.getpid()) not in builds  # built on the workers, not here
    assert system.builds == 0  # and the controller never called it


def test_a_killed_worker_loses_nothing_and_counts_nothing_twice(tmp_path: Path) -> None:
    campaign = toy(sources=60, name="kill")
    logs = ShardLogs(tmp_path, 4)
    with connect("local:2") as client:
        pids = client.run(os.getpid)
        killed: list[int] = []

        def progress(status: CampaignProgress) -> None:
            if status.done == 10 and not killed:
                victim = sorted(pids.values())[0]
                os.kill(victim, signal.SIGKILL)
                killed.append(victim)

        spread = run_campaign(campaign, cluster=client, log=logs, progress=progress, batch_size=2)
    assert killed
    assert spread.outcome_json() == run_campaign(campaign).outcome_json()
    assert log_sources(logs.paths()) == Counter(range(60))  # each source logged once
    assert spread.execution[0]["worker_crashes"] == 0
    # Lost is what happened; a replacement only if the nanny's new worker also ran sources.
    entry = spread.execution[0]
    assert entry["workers_lost"] == 1
    said = describe_execution(spread.execution)
    assert "1 worker(s) lost" in said and "replaced" not in said


def test_a_lost_worker_is_not_called_replaced() -> None:
    entry = {"engine": "dask", "scheduler": "tcp://a:1", "workers": 2, "units": 5}
    lost = describe_execution([{**entry, "workers_lost": 1, "workers_joined": 0}])
    assert "1 worker(s) lost" in lost and "joined" not in lost
    both = describe_execution([{**entry, "workers_lost": 1, "workers_joined": 1}])
    assert "1 worker(s) lost, 1 worker(s) joined" in both
    old_log = describe_execution([{**entry, "workers_replaced": 1}])  # logs of 0.4
    assert "1 worker(s) lost" in old_log


def test_a_source_that_kills_its_worker_is_a_crash_and_the_campaign_goes_on(
    tmp_path: Path,
) -> None:
    dask = pytest.importorskip("dask")
    campaign = toy(killer, sources=16, name="poison")
    # One retry instead of three: each death costs a worker restart.
    with (
        dask.config.set({"distributed.scheduler.allowed-failures": 1}),
        connect("local:2") as client,
    ):
        result = run_campaign(campaign, cluster=client, log=tmp_path / "log.jsonl")
    assert result.complete and result.source_crashes == 1
    assert result.execution[0]["worker_crashes"] == 1
    crash = json.loads(
        next(
            line
            for line in (tmp_path / "log.jsonl").read_text().splitlines()[1:]
            if '"crash"' in line
        )
    )
    assert crash["source"] == 11 and crash["crash"].startswith("WorkerDied")
    others = toy(lossy, sources=16, name="poison")
    expected = run_campaign(others)
    for size in (1, 4):  # every other source counted exactly as without the poison
        assert result.sizes[size].pairs == expected.sizes[size].pairs - 2


def test_a_worker_killed_at_the_end_is_back_before_the_cluster_closes() -> None:
    distributed = pytest.importorskip("distributed")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no unclean shutdown
        with connect("local:2") as client:
            doomed = client.submit(os._exit, 7, pure=False)
            with pytest.raises(distributed.KilledWorker):
                doomed.result(timeout=60)
            # connect() waits for the nanny's restart: closing a restarting nanny races in
            # Dask ("can only join a started process", seen in CI).


def test_a_cluster_that_fails_to_close_warns_and_keeps_the_result(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    distributed = pytest.importorskip("distributed")
    close = distributed.LocalCluster.close

    def close_then_fail(self, *args, **kwargs):
        close(self, *args, **kwargs)
        raise AssertionError("can only join a started process")

    monkeypatch.setattr(distributed.LocalCluster, "close", close_then_fail)
    with (
        pytest.warns(RuntimeWarning, match=r"did not shut down cleanly \(AssertionError: can"),
        connect("local:1") as client,
    ):
        result = run_campaign(toy(sources=4), cluster=client, log=tmp_path / "log.jsonl")
    assert result.complete and len(result.sources_done) == 4
    # A campaign's own error is what the caller sees, not the shutdown's.
    with (
        pytest.raises(ValueError, match="the campaign's own error"),
        pytest.warns(RuntimeWarning, match="did not shut down cleanly"),
        connect("local:1"),
    ):
        raise ValueError("the campaign's own error")


class _CtrlC(KeyboardInterrupt):
    pass


@pytest.mark.parametrize("resume_on", ["cluster", "process"])
def test_ctrl_c_leaves_a_log_that_resumes_anywhere(client, tmp_path: Path, resume_on) -> None:
    campaign = toy(sources=40, name="ctrl-c")
    logs = ShardLogs(tmp_path, 4)

    def progress(status: CampaignProgress) -> None:
        if status.done == 15:
            raise _CtrlC

    with pytest.raises(_CtrlC):
        run_campaign(campaign, cluster=client, log=logs, progress=progress)
    logged = log_sources(logs.paths())
    assert len(logged) >= 15 and set(logged.values()) == {1}
    if resume_on == "cluster":
        resumed = run_campaign(campaign, cluster=client, log=logs, resume=True)
    else:  # shard by shard, as pytest without --mt-dask runs them
        from pytest_metamorphic.core.campaign import merge_results

        resumed = merge_results(
            run_campaign(campaign, log=logs, resume=True, shard=k, shards=4) for k in range(4)
        )
    assert resumed.outcome_json() == run_campaign(campaign).outcome_json()
    assert log_sources(logs.paths()) == Counter(range(40))


def test_the_cluster_stops_working_on_an_interrupted_campaign(client) -> None:
    def progress(status: CampaignProgress) -> None:
        raise _CtrlC

    with pytest.raises(_CtrlC):
        run_campaign(toy(sources=40, name="stop"), cluster=client, progress=progress)
    deadline = time.monotonic() + 10
    while client.processing() and any(client.processing().values()):
        assert time.monotonic() < deadline, client.processing()
        time.sleep(0.05)


def test_a_system_that_cannot_be_sent_is_named_before_anything_runs(client, tmp_path: Path) -> None:
    with open(__file__, "rb") as handle:
        holds_a_file = _Reader(handle)
        with pytest.raises(InvalidArgument, match=r"its system .*_Reader.* cannot be sent") as e:
            run_campaign(toy(holds_a_file), cluster=client, log=tmp_path / "log.jsonl")
    assert "SystemFactory" in str(e.value)
    assert not (tmp_path / "log.jsonl").exists()


class _Reader:
    def __init__(self, handle) -> None:
        self.handle = handle

    def __call__(self, value):
        return lossy(value)


def test_a_lambda_is_sent_by_value(client) -> None:
    campaign = toy(lambda value: lossy(value), sources=6)
    assert run_campaign(campaign, cluster=client).outcome_json() == (
        run_campaign(campaign).outcome_json()
    )


def test_workers_that_cannot_import_the_campaign_are_reported(client, tmp_path: Path) -> None:
    (tmp_path / "only_here.py").write_text(
        "import time\n\ndef system(value):\n    return sorted(set(value))\n"
    )
    sys.path.insert(0, str(tmp_path))  # the workers started before: they do not see it
    try:
        import only_here

        with pytest.raises(ClusterError, match="No module named 'only_here'") as error:
            run_campaign(toy(only_here.system), cluster=client)
        assert "2 of 2 Dask worker(s) cannot run campaign 'toy'" in str(error.value)
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("only_here", None)


def test_addresses_are_checked() -> None:
    assert check_address(" local:3 ") == "local:3"
    assert check_address("tcp://10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    for bad in ("local:0", "local:x", "myhost", ""):
        with pytest.raises(InvalidArgument):
            check_address(bad)
    with pytest.raises(InvalidArgument, match="batch_size=0"):
        run_campaign(toy(), cluster="local:1", batch_size=0)
    with pytest.raises(InvalidArgument, match="batch_size= is for cluster runs"):
        run_campaign(toy(), batch_size=2)


def test_an_unreachable_scheduler_is_a_clear_error() -> None:
    with (
        pytest.raises(ClusterError, match=r"could not reach the Dask scheduler at tcp://127"),
        connect("tcp://127.0.0.1:9", timeout=2),
    ):
        pass


def test_local_workers_keep_glibcs_dynamic_mmap_threshold(client) -> None:
    # Dask's default MALLOC_TRIM_THRESHOLD_ made the reference pipeline 1.7x slower.
    assert set(client.run(os.environ.get, "MALLOC_TRIM_THRESHOLD_").values()) == {None}


def test_workers_started_with_dasks_trim_setting_get_a_warning() -> None:
    # A nanny writes its workers' variables into this process's environment; they would
    # reach every cluster and subprocess started after this test: put them back.
    names = ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
    saved = {name: os.environ.get(name) for name in names}
    try:
        with (
            distributed.LocalCluster(n_workers=1, processes=True, dashboard_address=":0") as local,
            distributed.Client(local) as client,
            pytest.warns(UserWarning, match="MALLOC_TRIM_THRESHOLD_.*pre-spawn-environ"),
        ):
            run_campaign(toy(sources=2), cluster=client)
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
