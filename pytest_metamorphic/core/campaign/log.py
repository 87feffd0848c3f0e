"""The campaign log: a header line, then one JSON record per finished source.

Records are flushed and fsynced as they come, so an interrupted run loses at most the
sources in progress; a log is read back to resume or to report a partial run.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import time
from collections.abc import Callable, Collection, Container, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.campaign.records import (
    CHECKED,
    MAX_LINE,
    parse_line,
    seal,
    verify_record,
)
from pytest_metamorphic.core.campaign.results import CampaignResult, SizeCounts, tally
from pytest_metamorphic.core.campaign.spec import Campaign
from pytest_metamorphic.core.errors import (
    CampaignLogError,
    DataError,
    InvalidArgument,
    OtherSystemError,
)
from pytest_metamorphic.core.files import check_regular, write_advice, write_error
from pytest_metamorphic.core.locks import exclusive

__all__ = [
    "Check",
    "LogFile",
    "ShardLogs",
    "as_logs",
    "logged_digest",
    "read_campaign_log",
    "read_log",
    "set_aside",
    "shard_indices",
]

SYNC_SECONDS = 1.0
_LAYOUT = re.compile(r"shard-\d+-of-(\d+)\.jsonl")


@dataclass(frozen=True)
class Check:
    """How a resume checks the records it reads back: ``verify(record)`` gives a reason a
    record cannot be trusted (or None); ``rerun``: such records are dropped and their
    sources run again (named in the result's ``dropped``) instead of being an error."""

    verify: Callable[[dict[str, Any]], str | None] | None = None
    rerun: bool = False


def read_log(
    path: Path,
    header: dict[str, Any],
    system: dict[str, str] | None = None,
    *,
    verify: Callable[[dict[str, Any]], str | None] | None = None,
    dropped: list[str] | None = None,
) -> Iterator[dict[str, Any]]:
    """The records of a log whose header is ``header`` (the campaign's), each verified
    (:mod:`pytest_metamorphic.core.campaign.records`).

    Parameters
    ----------
    verify : callable(record) -> reason or None, optional
        A further check of each record (a resume re-derives the source's input digest).
    dropped : list, optional
        Records that do not verify are skipped (their sources run again) and named here
        as ``"file:line: reason"``; without it such a record is an error.

    Raises
    ------
    InvalidArgument
        The log belongs to another campaign (name, relation, seed, sizes, ...).
    OtherSystemError
        ``system`` is given and the log records another system under test (logs written
        before 0.5 record none and are accepted).
    DataError
        The log is not a regular file, or a record is malformed or does not verify
        (naming the file and line).
    """
    check_regular(path, what="campaign log")
    with path.open(encoding="utf-8") as handle:
        first = handle.readline(MAX_LINE + 1)
        if not first:
            return
        logged = _header(first, path)
        _same_campaign(logged, header, system, path)
        number, line = 1, handle.readline(MAX_LINE + 1)
        while line:
            number += 1
            following = handle.readline(MAX_LINE + 1)
            where = f"{path}:{number}"
            try:
                record = parse_line(line.rstrip("\n"), where)
            except json.JSONDecodeError:
                if not following and not line.endswith("\n"):
                    return  # a line cut off by an interruption: that source is simply redone
                raise DataError(f"{where}: corrupt campaign record (not JSON)") from None
            reason = verify_record(record, header, logged, where)
            if reason is None and verify is not None:
                reason = verify(record)
            if reason is None:
                yield record
            elif dropped is not None:
                dropped.append(f"{where}: {reason}")
            else:
                raise DataError(
                    f"{where}: the record of source {record.get('source')} does not verify: "
                    f"{reason}. Delete the log to start afresh, or resume with "
                    "--mt-resume-rerun-unverified (run_campaign(unverified='rerun')) to run "
                    "such sources again"
                )
            line = following


def _header(line: str, path: Path) -> dict[str, Any]:
    try:
        found = parse_line(line.rstrip("\n"), f"{path}:1")
    except json.JSONDecodeError:
        raise InvalidArgument(f"{path}: first line is not a campaign header") from None
    if not isinstance(found, dict):
        raise InvalidArgument(f"{path}: first line is not a campaign header")
    return found


def _same_campaign(
    logged: dict[str, Any], header: dict[str, Any], system: dict[str, str] | None, path: Path
) -> None:
    found = {k: v for k, v in logged.items() if k not in ("system", CHECKED)}
    logged_system = logged.get("system")
    if found != header:
        raise InvalidArgument(
            f"{path} holds results of a different campaign ({found}); expected {header}. "
            "Use another log path or the same seed and parameters."
        )
    if system is not None and logged_system is not None and logged_system != system:
        raise OtherSystemError(
            f"{path} holds results of another system under test ({_named(logged_system)}); "
            f"this run's is {_named(system)}. Resuming would blend the two systems' rates: "
            "use another log, run without resume (the log is set aside, not lost), or pass "
            'resume="any-system" (--mt-resume-any-system) if the change is intended.'
        )


def set_aside(path: Path) -> None:
    """Keep an earlier log instead of overwriting it: nothing recorded is lost."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    target = path.with_name(f"{path.stem}.{stamp}{path.suffix}")
    counter = 1
    while target.exists():
        target = path.with_name(f"{path.stem}.{stamp}-{counter}{path.suffix}")
        counter += 1
    path.rename(target)


def read_campaign_log(
    campaign: Campaign,
    log: LogLike,
    *,
    shard: int = 0,
    shards: int = 1,
    keep_examples: int = 20,
) -> CampaignResult:
    """The result of the sources of one shard that ``log`` records as finished.

    Nothing runs: this is what an interrupted run had done (an empty result when the log
    is absent or empty). ``log`` is one file or a :class:`ShardLogs` folder. Raises
    InvalidArgument when the log belongs to another campaign.
    """
    indices = shard_indices(campaign.sources, shard, shards)
    return as_logs(log).read(campaign, indices, keep_examples=keep_examples)


def _named(system: Any) -> str:
    if not isinstance(system, dict):
        return repr(system)[:200]
    return f"{system.get('name')!s:.120} [{system.get('fingerprint')}]"


def logged_digest(logs: Any, campaign: Campaign, index: int) -> str | None:
    """The output digest a log recorded for source ``index`` (None: not logged, or a log
    written before digests were)."""
    for path in logs.paths():
        if not path.exists() or not path.stat().st_size:
            continue
        # Only records that verify say what the system gave (the others are rerun or refused
        # by the read that tallies them).
        for record in read_log(path, campaign.header(), dropped=[]):
            if record.get("source") == index and "digest" in record:
                return str(record["digest"])
    return None


def _empty_result(campaign: Campaign, keep_examples: int) -> CampaignResult:
    return CampaignResult(
        campaign.header(),
        {size: SizeCounts() for size in campaign.sizes},
        keep_examples=keep_examples,
    )


def _tally_file(
    result: CampaignResult,
    path: Path,
    header: dict[str, Any],
    wanted: Container[int],
    system: dict[str, str] | None = None,
    check: Check | None = None,
) -> None:
    if not path.exists() and not path.is_symlink():
        return
    check_regular(path, what="campaign log")
    if not path.stat().st_size:
        return
    verify = None if check is None else check.verify
    dropped = result.dropped if check is not None and check.rerun else None
    for record in read_log(path, header, system, verify=verify, dropped=dropped):
        if record["source"] in wanted and record["source"] not in result.sources_done:
            tally(result, record)


def _drop_cut_off_record(path: Path) -> None:
    """Truncate a last line an interruption cut off (resuming redoes that source), so
    the records appended after it stay one per line."""
    if not path.exists():
        return
    with path.open("rb+") as handle:
        size = handle.seek(0, os.SEEK_END)
        if not size:
            return
        handle.seek(max(size - 1, 0))
        if handle.read(1) == b"\n":
            return
        block = min(size, 1 << 16)
        while True:
            handle.seek(size - block)
            data = handle.read(block)
            cut = data.rfind(b"\n")
            if cut >= 0:
                handle.truncate(size - block + cut + 1)
                return
            if block == size:
                handle.truncate(0)
                return
            block = min(size, block * 2)


def _file_header(path: Path) -> dict[str, Any]:
    with path.open(encoding="utf-8") as handle:
        return _header(handle.readline(MAX_LINE + 1), path)


class _Writer:
    """Appends records to one log: each flushed at once (a killed process loses nothing
    written), fsynced at least every ``SYNC_SECONDS`` and on close (an OS crash loses at
    most that much); a per-record fsync would cap a cluster's throughput at the disk's."""

    def __init__(self, path: Path, header: dict[str, Any]) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.exists() or path.is_symlink():
            check_regular(path, what="campaign log")
        _drop_cut_off_record(path)
        fresh = not path.exists() or path.stat().st_size == 0
        # Records are sealed with the header line of the file they go to: on a resume that
        # is the header the file already has (resume="any-system" keeps the old system).
        self.header = {**header, CHECKED: 1} if fresh else _file_header(path)
        self.path = path
        try:
            self.handle = path.open("a", encoding="utf-8")
        except OSError as error:
            raise write_error(error, path, what="the campaign log") from None
        self.synced = time.monotonic()
        if fresh:
            self._line(self.header)
            self.sync()

    def write(self, record: dict[str, Any]) -> None:
        self._line(seal(self.header, record) if self.header.get(CHECKED) else record)

    def _line(self, data: dict[str, Any]) -> None:
        try:
            self.handle.write(json.dumps(data, separators=(",", ":")) + "\n")
            self.handle.flush()
            if time.monotonic() - self.synced >= SYNC_SECONDS:
                self.sync()
        except OSError as error:
            raise CampaignLogError(
                f"could not write the campaign log {self.path} ({error.strerror or error}); "
                f"the records written before are intact: {write_advice(error)}, then run "
                "again with --mt-resume to continue where it stopped",
                cause=error,
            ) from error

    def sync(self) -> None:
        os.fsync(self.handle.fileno())
        self.synced = time.monotonic()

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sync()
        self.handle.close()


@dataclass(frozen=True)
class LogFile:
    """One JSONL log for all the sources a run is given."""

    path: Path

    def paths(self) -> list[Path]:
        return [self.path]

    def read(
        self,
        campaign: Campaign,
        indices: Collection[int],
        *,
        keep_examples: int = 20,
        system: dict[str, str] | None = None,
        check: Check | None = None,
    ) -> CampaignResult:
        result = _empty_result(campaign, keep_examples)
        _tally_file(result, self.path, campaign.header(), indices, system, check)
        result._trim_examples()
        return result

    def lock(self, indices: Iterable[int]) -> contextlib.AbstractContextManager[None]:
        """One writer at a time for this log (:mod:`pytest_metamorphic.core.locks`)."""
        return exclusive(_lock_path(self.path), what=f"campaign log {self.path.name}")

    def set_aside(self, indices: Iterable[int]) -> None:
        if self.path.exists() and self.path.stat().st_size:
            set_aside(self.path)

    @contextmanager
    def open(self, header: dict[str, Any]) -> Iterator[Callable[[dict[str, Any]], None]]:
        writer = _Writer(self.path, header)
        try:
            yield writer.write
        finally:
            writer.close()


@dataclass(frozen=True)
class ShardLogs:
    """One log per shard, ``folder/shard-K-of-N.jsonl``; source ``i`` goes to shard
    ``i % shards``.

    The pytest plugin's layout, whichever engine ran the sources (pytest-xdist shards or
    a Dask cluster), so a run interrupted on one resumes on the other. The number of
    shards follows the number of workers, so a folder may hold logs of several layouts
    (``-n 4`` yesterday, ``-n 2`` today): reading takes each source from whichever log
    has it, and a fresh run sets all of them aside.
    """

    folder: Path
    shards: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "folder", Path(self.folder))
        if isinstance(self.shards, bool) or not isinstance(self.shards, int) or self.shards < 1:
            raise InvalidArgument(f"shards={self.shards!r} must be an int >= 1")

    def path(self, shard: int) -> Path:
        return self.folder / f"shard-{shard}-of-{self.shards}.jsonl"

    def paths(self) -> list[Path]:
        """This layout's logs, then those of other layouts found in the folder."""
        own = [self.path(shard) for shard in range(self.shards)]
        return own + [path for path in self._other_layouts() if path not in own]

    def _other_layouts(self) -> list[Path]:
        if not self.folder.is_dir():
            return []
        found = []
        for path in self.folder.glob("shard-*-of-*.jsonl"):
            match = _LAYOUT.fullmatch(path.name)
            if match and int(match.group(1)) != self.shards:
                found.append(path)
        return sorted(found)

    def read(
        self,
        campaign: Campaign,
        indices: Collection[int],
        *,
        keep_examples: int = 20,
        system: dict[str, str] | None = None,
        check: Check | None = None,
    ) -> CampaignResult:
        result = _empty_result(campaign, keep_examples)
        indices = indices if isinstance(indices, (range, set, frozenset)) else set(indices)
        for shard in range(self.shards):
            mine = shard_indices(campaign.sources, shard, self.shards)
            wanted = [index for index in mine if index in indices]
            if wanted:
                _tally_file(result, self.path(shard), campaign.header(), set(wanted), system, check)
        for path in self._other_layouts():  # a source already read is not read again
            _tally_file(result, path, campaign.header(), indices, system, check)
        result._trim_examples()
        return result

    @contextmanager
    def lock(self, indices: Iterable[int]) -> Iterator[None]:
        """One writer at a time for each shard log holding ``indices`` (pytest-xdist
        workers write different shards of one folder side by side)."""
        with contextlib.ExitStack() as stack:
            for shard in sorted({index % self.shards for index in indices}):
                path = self.path(shard)
                stack.enter_context(
                    exclusive(_lock_path(path), what=f"campaign log {self.folder}/{path.name}")
                )
            yield

    def set_aside(self, indices: Iterable[int]) -> None:
        """Rename aside the logs of the shards holding ``indices`` (another shard's log
        may belong to a run going on beside this one), and every log of another layout
        (a fresh run must not be resumed from older records later)."""
        shards = {index % self.shards for index in indices}
        paths = [self.path(shard) for shard in sorted(shards)] + self._other_layouts()
        for path in paths:
            # Shards of one run set the other layouts aside side by side: the first wins.
            with contextlib.suppress(FileNotFoundError):
                if path.stat().st_size:
                    set_aside(path)

    @contextmanager
    def open(self, header: dict[str, Any]) -> Iterator[Callable[[dict[str, Any]], None]]:
        writers: dict[int, _Writer] = {}

        def write(record: dict[str, Any]) -> None:
            shard = record["source"] % self.shards
            if shard not in writers:
                writers[shard] = _Writer(self.path(shard), header)
            writers[shard].write(record)

        try:
            yield write
        finally:
            for writer in writers.values():
                writer.close()


class _NoLog:
    def paths(self) -> list[Path]:
        return []

    def read(
        self,
        campaign: Campaign,
        indices: Collection[int],
        *,
        keep_examples: int = 20,
        system: dict[str, str] | None = None,
        check: Check | None = None,
    ) -> CampaignResult:
        return _empty_result(campaign, keep_examples)

    def lock(self, indices: Iterable[int]) -> contextlib.AbstractContextManager[None]:
        return contextlib.nullcontext()

    def set_aside(self, indices: Iterable[int]) -> None:
        pass

    @contextmanager
    def open(self, header: dict[str, Any]) -> Iterator[Callable[[dict[str, Any]], None]]:
        yield lambda record: None


def _lock_path(log: Path) -> Path:
    return log.with_name(f".{log.name}.lock")


LogLike = Path | str | os.PathLike[str] | LogFile | ShardLogs | None


def as_logs(log: LogLike) -> LogFile | ShardLogs | _NoLog:
    """Normalise a ``log=`` argument: a path, a :class:`ShardLogs`, or None."""
    if log is None:
        return _NoLog()
    if isinstance(log, (LogFile, ShardLogs)):
        return log
    if isinstance(log, (str, os.PathLike)):
        return LogFile(Path(log))
    raise InvalidArgument(f"log={log!r} must be a path, a ShardLogs or None")


def shard_indices(sources: int, shard: int, shards: int) -> range:
    """Source indices of one shard: every ``shards``-th index starting at ``shard``."""
    if not 0 <= shard < shards:
        raise InvalidArgument(f"shard={shard} must be in [0, {shards})")
    return range(shard, sources, shards)
