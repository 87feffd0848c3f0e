"""Every exception type the project raises on purpose.

Users catch these; the engine tells them apart (a violation is a failed check, a crash is
an error in the system under test, bad input is the caller's fault).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pytest_metamorphic.core.verdict import Verdict

__all__ = [
    "CampaignLogError",
    "DataError",
    "ExternalSystemError",
    "FolderInUse",
    "InvalidArgument",
    "MetamorphicError",
    "MetamorphicViolation",
    "NondeterministicSystemError",
    "NothingTestedWarning",
    "OtherSystemError",
    "ProtocolWarning",
    "SystemTimeout",
    "SystemUnderTestCrash",
    "WriteError",
]


class MetamorphicError(Exception):
    """Base class of every error pytest-metamorphic raises on purpose."""


class InvalidArgument(MetamorphicError, TypeError, ValueError):
    """A function or decorator was called with arguments it cannot use.

    Raised early, at decoration or strategy-construction time, naming the argument.
    Subclasses both TypeError and ValueError, like ``hypothesis.errors.InvalidArgument``
    users expect one of the two.
    """


class DataError(MetamorphicError, ValueError):
    """A file or an in-memory array is malformed.

    The message names the file (or argument) and what is wrong with it. Readers let
    no other exception type escape for bad input.
    """

    def __init__(self, message: str, *, path: object = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path else message)


class MetamorphicViolation(AssertionError):
    """A metamorphic relation does not hold between a source and a follow-up output.

    An ``AssertionError`` so that pytest and Hypothesis treat it as a test failure.
    The engine fills in what it knows about the violating pair: the (minimal) follow-up,
    both outputs and its full record (``None`` when the error was raised elsewhere).
    ``verdict`` is the relation's :class:`~pytest_metamorphic.core.relations.Verdict` on
    the (minimal) follow-up: its ``explanation`` and machine-readable ``details``.
    """

    followup: Any
    source_output: Any
    followup_output: Any
    record: Any

    def __init__(self, message: str, *, relation: str = "", verdict: Verdict | None = None) -> None:
        self.relation = relation
        self.verdict = verdict
        self.followup = self.source_output = self.followup_output = self.record = None
        super().__init__(message)


class SystemUnderTestCrash(MetamorphicError):
    """The system under test raised an exception on a source or follow-up input.

    The original exception is chained as ``__cause__``. ``stage`` is ``"source"`` or
    ``"followup"``.
    """

    def __init__(self, message: str, *, stage: str, relation: str | None = None) -> None:
        self.stage = stage
        self.relation = relation
        super().__init__(message)


class NondeterministicSystemError(MetamorphicError):
    """Running the system under test twice on the same source gave different outputs.

    A relation violation would be meaningless then, so the engine reports this instead.
    """


class SystemTimeout(MetamorphicError, TimeoutError):
    """One call of the system under test ran past its time limit.

    The engine and campaigns report it as a crash of that call (never as a violation).
    ``seconds`` is the limit that was exceeded.
    """

    def __init__(self, message: str, *, seconds: float) -> None:
        self.seconds = seconds
        super().__init__(message)


class ExternalSystemError(MetamorphicError):
    """A system under test running in another process died, failed or wrote garbage.

    The message names the command, its exit status and the end of what it wrote to
    stderr, or the output file that could not be read.
    """


class FolderInUse(MetamorphicError):
    """Another process is writing the same campaign log or export folder.

    The message names the holder (process id, host, command line). ``path`` is the folder.
    """

    def __init__(self, message: str, *, path: object = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path else message)


class WriteError(MetamorphicError, OSError):
    """A file or folder could not be written where the user asked (a read-only mount, a
    full disk, a name too long for the file system).

    The message names the user's path (never a hidden temporary sibling), the cause and
    what to do about it; ``errno`` and ``strerror`` are the operating system's.
    """

    def __init__(self, message: str, *, path: object = None, cause: OSError | None = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path else message)
        if cause is not None:
            self.errno, self.strerror = cause.errno, cause.strerror

    def __str__(self) -> str:  # OSError's would be "[Errno 30] Read-only file system"
        return str(self.args[0]) if self.args else ""


class CampaignLogError(WriteError):
    """A campaign log could not be written (a full disk, a folder gone): the records
    written before are intact and a resumed run continues from them."""


class OtherSystemError(MetamorphicError):
    """A campaign log holds results of another system under test than the one resuming.

    Resuming would blend the two systems' rates; start afresh, or pass
    ``resume="any-system"`` (``--mt-resume-any-system``) when the change is intended.
    """


class ProtocolWarning(UserWarning):
    """A program under test speaks its protocol in a way that cannot be checked (e.g. a
    long-lived detector whose answers do not name the frames they answer)."""


class NothingTestedWarning(UserWarning):
    """A metamorphic relation ran but tested nothing in a whole test: no follow-up could
    be made of any source, every follow-up equalled its source, or its checks judged no
    element (no obstacle in scope). The test passed vacuously; ``--mt-strict-tested``
    makes it fail instead."""
