"""Running a campaign on a Dask cluster (the optional ``dask`` extra).

The unit of work is one source, or ``batch_size`` sources, with all their sizes and
follow-ups: the same :func:`~pytest_metamorphic.core.campaign.source.run_source` a process
runs, so every record, and therefore the merged result, is identical to a one-process run
with the same seed. Only the controller writes the log, as results come back: a worker
that dies loses nothing (the scheduler runs its units again) and counts nothing twice
(each unit's result is taken once). A source whose task kills its worker every time
(a segfaulting detector) is recorded as a crash of that source, once it has killed
workers while running alone on the cluster, and the campaign goes on.

What travels, and where it must be:

- the campaign is pickled once (cloudpickle) and installed on every worker by a worker
  plugin (workers that join or restart later get it too); its system is built there,
  once per worker, when it is a
  :class:`~pytest_metamorphic.core.campaign.system.SystemFactory`;
- recorded frames travel by reference (a ``FrameCatalog`` pickles as its paths and
  options): every worker must see the data at the same absolute path;
- every worker needs pytest-metamorphic and the module that defines the campaign's
  functions importable (same checkout on a shared path, or installed).

Before anything runs, the campaign is checked: a part that cannot be pickled is named,
and every worker loads the campaign and its first source, so a missing module or data
path is reported at once instead of as a crash of every source.
"""

from __future__ import annotations

import contextlib
import logging
import time
import uuid
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from pytest_metamorphic.core.campaign.spec import Campaign
from pytest_metamorphic.core.errors import InvalidArgument, MetamorphicError

__all__ = [
    "ClusterError",
    "DaskEngine",
    "check_address",
    "check_sendable",
    "connect",
]

LOCAL_PREFIX = "local:"
WORKERS_TIMEOUT = 30.0
RESTART_TIMEOUT = 20.0  # a restarted worker registers in 1-3 s on a loaded 2-core machine
LARGE_PART_BYTES = 16 * 2**20
MAX_AUTO_BATCH = 8
GUIDED_SHARE = 4  # a guided task takes at most 1/(4 x workers) of what is left
_PARTS = ("source", "followup", "system", "relation", "category", "counted")
_INSTALL = "pip install 'pytest-metamorphic[dask]'"
# Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536, which switches off glibc's dynamic
# mmap threshold: every large array is then mmapped and unmapped afresh, and the reference
# pipeline ran 1.7x slower per worker (measured). Local clusters start without it.
TRIM_SETTING = "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"
# Local clusters share the cores with the system under test, so Dask's own periodic work is
# slowed down: its event-loop tick every 20 ms and system monitor every 0.5 s in each
# scheduler, nanny and worker, memory polling every 0.1 s, work stealing every 0.1 s, and
# the workers' 10 ms statistical profiler (we never read it). Measured on 2 cores beside the
# reference pipeline: nanny and controller CPU fell from 0.53 to 0.21 s per 10 s of run.
# A dead worker is still noticed at once (its connection closes).
LOCAL_SETTINGS = {
    TRIM_SETTING: None,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.tick.cycle": "10s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.profile.enabled": False,
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.scheduler.work-stealing-interval": "1s",
}
TRIM_FIX = (
    "a Dask config file (YAML, in ~/.config/dask/ or the folder DASK_CONFIG names) with "
    "distributed: {nanny: {pre-spawn-environ: {MALLOC_TRIM_THRESHOLD_: null}}}"
)


class ClusterError(MetamorphicError):
    """The cluster cannot run the campaign (unreachable, or workers that cannot load it)."""


def check_address(address: str) -> str:
    """Validate ``"local:N"`` or a scheduler address; return it stripped."""
    if not isinstance(address, str) or not address.strip():
        raise InvalidArgument(
            f"cluster={address!r} must be a Dask scheduler address (tcp://host:8786) or "
            "'local:N' for a local cluster of N worker processes"
        )
    address = address.strip()
    if address.startswith(LOCAL_PREFIX):
        count = address[len(LOCAL_PREFIX) :]
        if not count.isdigit() or int(count) < 1:
            raise InvalidArgument(
                f"cluster={address!r}: N in 'local:N' must be a number of workers >= 1"
            )
    elif ":" not in address:
        raise InvalidArgument(
            f"cluster={address!r} is neither 'local:N' nor a scheduler address with a port "
            "(e.g. tcp://10.0.0.5:8786)"
        )
    return address


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise InvalidArgument(
            f"running a campaign on a Dask cluster needs Dask distributed: {_INSTALL}"
        ) from None
    return distributed


@contextmanager
def connect(cluster: Any, *, timeout: float | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` for ``cluster``: an address, ``"local:N"`` or a client.

    A local cluster (N single-threaded worker processes, each restarted by its nanny if
    it dies) and the connection are closed on exit, after workers that died are back
    (up to ``RESTART_TIMEOUT`` s); a local cluster that then fails to shut down is a
    ``RuntimeWarning``, never an error that hides the campaign's result or its own
    exception. A client given is left open.
    ``timeout`` defaults to Dask's ``distributed.comm.timeouts.connect`` (30 s unless
    configured, e.g. ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5``).
    """
    distributed = _distributed()
    if isinstance(cluster, distributed.Client):
        yield cluster
        return
    address = check_address(cluster)
    if address.startswith(LOCAL_PREFIX):
        import dask

        workers = int(address[len(LOCAL_PREFIX) :])
        # Only while the nannies are made: they keep their workers' settings for restarts.
        with dask.config.set(LOCAL_SETTINGS):
            local = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                # Loopback only: a scheduler runs any code sent to it (docs/campaigns.md).
                host="127.0.0.1",
                dashboard_address="127.0.0.1:0",  # a free port: never clash with another
                silence_logs=logging.ERROR,
            )
        try:
            with distributed.Client(local) as client:
                yield client
                _wait_for_restarts(client, workers)
        finally:
            _close_local(local)
        return
    if timeout is None:
        import dask

        timeout = _seconds(dask.config.get("distributed.comm.timeouts.connect"))
    try:
        client = distributed.Client(address, timeout=timeout)
    except (OSError, TimeoutError) as error:
        raise ClusterError(
            f"could not reach the Dask scheduler at {address} within {timeout:.0f} s "
            f"({type(error).__name__}: {error}); start it with `dask scheduler` and workers "
            f"with `dask worker {address}`"
        ) from None
    with client:
        yield client


def _wait_for_restarts(client: Any, workers: int) -> None:
    """Let nannies finish restarting workers that died before the cluster is closed.

    Closing a nanny while it restarts a worker that a crashing system killed races inside
    Dask (``AssertionError: can only join a started process``, seen in CI); waiting until
    every worker is back closes that window. A worker that does not come back in time is
    left to the close.
    """
    with contextlib.suppress(TimeoutError, OSError):
        client.wait_for_workers(workers, timeout=RESTART_TIMEOUT)


def _close_local(local: Any) -> None:
    """Close a local cluster this module started; a failure to close is a warning.

    By then the campaign's results are returned and its log written: Dask failing to shut
    down its own worker processes (they are daemons and die with this process) must not
    turn a finished campaign into an error, nor hide the error a failed one raised.
    """
    try:
        local.close()
    except Exception as error:  # whatever Dask raises while shutting down its processes
        warnings.warn(
            f"the local Dask cluster did not shut down cleanly ({type(error).__name__}: "
            f"{error}); the campaign's results and log are complete, and its worker "
            "processes end with this process",
            RuntimeWarning,
            stacklevel=3,
        )


def _seconds(value: Any) -> float:
    from dask.utils import parse_timedelta

    return float(parse_timedelta(value, default="seconds"))


def check_sendable(campaign: Campaign) -> bytes:
    """The campaign pickled as Dask sends it; a part that cannot be sent is named.

    Raises InvalidArgument naming the part (its system, source function, ...) and what
    to do instead; warns when a part is large (it is copied to every worker). The parts
    are pickled one by one only when the whole campaign fails or is large.
    """
    from distributed.protocol.pickle import dumps

    try:
        payload = dumps(campaign)
    except Exception:
        payload = None
    if payload is not None and len(payload) <= LARGE_PART_BYTES:
        return payload
    for part in _PARTS:
        value = getattr(campaign, part)
        if value is None:
            continue
        try:
            size = len(dumps(value))
        except Exception as error:
            raise InvalidArgument(
                f"campaign {campaign.name!r}: its {part} {value!r} cannot be sent to Dask "
                f"workers ({type(error).__name__}: {error}). Give the campaign what builds "
                "it instead: a module-level function or class, or "
                "SystemFactory(build, *args) for a system that holds a model, a process or "
                "an open file (each worker builds its own, once)."
            ) from None
        if size > LARGE_PART_BYTES:
            import warnings

            warnings.warn(
                f"campaign {campaign.name!r}: its {part} pickles to {size / 2**20:.0f} MiB, "
                "copied to every worker; hold data by reference (a FrameCatalog, a path) "
                "and load it on the workers",
                stacklevel=3,
            )
    return payload if payload is not None else dumps(campaign)


class DaskEngine:
    """Runs a campaign's sources as Dask tasks; see the module's documentation.

    Parameters
    ----------
    cluster : str or distributed.Client
        A scheduler address, ``"local:N"``, or a connected client (left open).
    batch_size : int, optional
        Sources per task; by default guided (up to ``MAX_AUTO_BATCH``, fewer towards the
        end).
    """

    def __init__(self, cluster: Any, *, batch_size: int | None = None) -> None:
        if batch_size is not None and (
            isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1
        ):
            raise InvalidArgument(f"batch_size={batch_size!r} must be None or an int >= 1")
        distributed = _distributed()
        if not isinstance(cluster, distributed.Client):
            check_address(cluster)
        self.cluster = cluster
        self.batch_size = batch_size
        self.units: dict[str, int] = {}  # worker address -> units it returned
        self.retried = 0
        self.worker_crashes = 0
        self.workers_seen: set[str] = set()

    @contextmanager
    def session(self, campaign: Campaign, timeout: float | None) -> Iterator[DaskEngine]:
        payload = check_sendable(campaign)
        with connect(self.cluster) as client:
            from pytest_metamorphic.core.campaign import _worker

            self.client, self.campaign, self.timeout = client, campaign, timeout
            self._preflight(payload)
            # Sent once, installed on every worker (restarted ones too); tasks carry only
            # its token, and share the worker's copy and the system built in it.
            self.token = f"pytest-metamorphic-{uuid.uuid4().hex}"
            client.register_plugin(_worker.CampaignPlugin(self.token, payload))
            try:
                yield self
            finally:
                with contextlib.suppress(Exception):
                    client.unregister_worker_plugin(self.token)

    def _preflight(self, payload: bytes) -> None:
        try:
            self.client.wait_for_workers(1, timeout=WORKERS_TIMEOUT)
        except TimeoutError:
            raise ClusterError(
                f"the Dask scheduler {self.client.scheduler.address} has no workers after "
                f"{WORKERS_TIMEOUT:.0f} s; start some with `dask worker ADDRESS`"
            ) from None
        from pytest_metamorphic.core.campaign import _worker

        answers = self.client.run(_worker.preflight, payload, 0, on_error="return")
        broken = {w: a for w, a in answers.items() if isinstance(a, BaseException)}
        trimmed = sorted(w for w, a in answers.items() if isinstance(a, dict) and a["trim"])
        if trimmed:
            import warnings

            warnings.warn(
                f"{len(trimmed)} Dask worker(s) run with MALLOC_TRIM_THRESHOLD_ set (Dask's "
                "default), which makes array-heavy systems much slower (1.7x for the "
                f"reference pipeline); start the workers with {TRIM_FIX}",
                stacklevel=4,
            )
        self.workers_seen = set(answers)
        if broken:
            worker, error = next(iter(sorted(broken.items())))
            raise ClusterError(
                f"{len(broken)} of {len(answers)} Dask worker(s) cannot run campaign "
                f"{self.campaign.name!r}; {worker}: {type(error).__name__}: {error}. Every "
                "worker needs pytest-metamorphic, the module defining the campaign's "
                "functions importable, and the data at the same path (docs/campaigns.md: "
                "running on several machines)."
            )

    def describe(self) -> dict[str, Any]:
        workers = self.workers_seen | set(self.units)
        current = set(self._current_workers())
        return {
            "engine": "dask",
            "scheduler": self.client.scheduler.address,
            "workers": len(self.workers_seen),
            "workers_used": len(self.units),
            # Lost: gone by the end. Joined: ran sources without being there at the start
            # (a restarted or added worker). Only both together are a replacement.
            "workers_lost": len(workers - current),
            "workers_joined": len(set(self.units) - self.workers_seen),
            "batch_size": self.batch_size or "guided",
            "units": sum(self.units.values()),
            "units_per_worker": dict(sorted(self.units.items())),
            "units_retried": self.retried,
            "worker_crashes": self.worker_crashes,
        }

    def _current_workers(self) -> list[str]:
        try:
            return list(self.client.scheduler_info()["workers"])
        except Exception:
            return []

    def records(self, todo: list[int]) -> Iterator[tuple[dict[str, Any], int]]:
        """Each finished source's record as it comes back, with the sources in flight.

        Sources of tasks Dask gave up on (KilledWorker) are suspects: Dask blames every
        task a dying worker held, queued ones too, so each suspect is run again at the
        end, alone on the cluster, where only a source that kills its worker itself
        fails again; that one is recorded as a crash.
        """
        distributed = _distributed()
        pending: dict[Any, list[int]] = {}
        suspects: list[int] = []
        in_flight = len(todo)
        try:
            for batch in self._batches(todo):
                pending[self._submit(batch)] = batch
            finished = distributed.as_completed(list(pending))
            for future in finished:
                batch = pending.pop(future)
                records, again = self._collect(future, batch, distributed)
                if len(again) > 1:
                    # One source may be what kills the worker: run each on its own.
                    for index in again:
                        retry = self._submit([index])
                        pending[retry] = [index]
                        finished.add(retry)
                else:
                    suspects += again
                for record in records:
                    in_flight -= 1
                    yield record, in_flight
            for index in suspects:
                future = self._submit([index])
                pending[future] = [index]
                distributed.wait(future)
                del pending[future]
                records, again = self._collect(future, [index], distributed)
                if again:
                    self.worker_crashes += 1
                    records = [_worker_died(index, _failure(future))]
                in_flight -= 1
                yield records[0], in_flight
        finally:
            # Interrupted (Ctrl-C) or failed: stop the cluster's work on this campaign;
            # what came back is already in the log.
            if pending:
                with contextlib.suppress(Exception):
                    self.client.cancel(list(pending))

    def _batches(self, todo: list[int]) -> Iterator[list[int]]:
        """``batch_size`` sources per task; by default guided: a task costs the engine about
        a millisecond, so early tasks take up to ``MAX_AUTO_BATCH`` sources, and the sizes
        shrink towards one as the end nears, so no worker is left with a long last task."""
        workers = max(len(self.workers_seen), 1)
        start = 0
        while start < len(todo):
            remaining = len(todo) - start
            size = self.batch_size or min(
                MAX_AUTO_BATCH, max(1, -(-remaining // (GUIDED_SHARE * workers)))
            )
            yield todo[start : start + size]
            start += size

    def _submit(self, batch: list[int]) -> Any:
        from pytest_metamorphic.core.campaign import _worker

        return self.client.submit(
            _worker.run_unit,
            self.token,
            batch,
            self.timeout,
            key=f"mt-{self.campaign.name}-{batch[0]}-{time.monotonic_ns()}",
            pure=False,
        )

    def _collect(
        self, future: Any, batch: list[int], distributed: Any
    ) -> tuple[list[dict[str, Any]], list[int]]:
        """(records, sources to run again) for one finished task."""
        if future.status not in ("finished", "error", "cancelled"):
            # Finished, then lost with its worker before we fetched it: the scheduler is
            # computing it again (seen under load while workers were being killed).
            distributed.wait(future)
        if future.status == "finished":
            try:
                answer = future.result()
            except Exception:  # its data died with a worker: nothing counted, run again
                self.retried += 1
                return [], list(batch)
            self.units[answer["worker"]] = self.units.get(answer["worker"], 0) + 1
            return answer["records"], []
        if future.status == "cancelled":
            # Not by us: the scheduler gave the task up (seen under load while workers
            # were dying); it counted nothing, so it simply runs again.
            self.retried += 1
            return [], list(batch)
        error = future.exception()
        if isinstance(error, distributed.KilledWorker):
            self.retried += 1
            return [], list(batch)
        raise ClusterError(
            f"campaign {self.campaign.name!r}, sources {batch}: the task failed on the "
            f"cluster with {type(error).__name__}: {error}"
        ) from error


def _failure(future: Any) -> str:
    if future.status == "cancelled":
        return "the scheduler cancelled the task"
    error = future.exception()
    return f"{type(error).__name__}: {error}"


def _worker_died(index: int, failure: str) -> dict[str, Any]:
    """The record of a source whose worker died every time it ran it: a crash, as any."""
    return {
        "source": index,
        "pairs": [],
        "sut_calls": 0,
        "crash": f"WorkerDied: the Dask worker running source {index} died each time it "
        f"was tried ({failure})",
    }
