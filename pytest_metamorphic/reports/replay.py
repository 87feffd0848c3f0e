"""Replaying a saved violation against the current system under test.

``pytest --mt-replay mt-artifacts/<test>/<relation>`` runs only the artifact's test, and
instead of a Hypothesis search runs the system once on the saved source and once on the
saved (minimal) follow-up, then checks the saved relation: the test fails while the
violation is still there and passes once it is fixed, which makes the artifact a
regression test for CI. :func:`example_snippet` prints the ``@example`` that keeps the case
in the test itself.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.reports.artifacts import Artifact

__all__ = ["ReplayResult", "example_snippet", "replay", "replay_inputs", "replay_with"]


@dataclass(frozen=True)
class ReplayResult:
    """The outcome of re-running one artifact.

    Attributes
    ----------
    artifact : Artifact
    still_fails : bool
        The saved relation is still violated on the saved inputs.
    verdict : Verdict
    source_output, followup_output
        What the current system returned.
    """

    artifact: Artifact
    still_fails: bool
    verdict: Verdict
    source_output: Any
    followup_output: Any

    def lines(self) -> list[str]:
        """A short human report, ending with the ``@example`` snippet."""
        record = self.artifact.record
        state = "still FAILS" if self.still_fails else "passes now (fixed)"
        lines = [f"{self.artifact.folder}: relation {self.artifact.relation!r} {state}"]
        if self.still_fails:
            lines.append(f"  {self.verdict.explanation}")
        else:
            lines.append(f"  when saved: {record.get('explanation', '')}")
        lines.append(f"  source output:    {describe_value(self.source_output)}")
        lines.append(f"  follow-up output: {describe_value(self.followup_output)}")
        if "campaign" in record:  # a campaign's case: its test has no @example to add to
            lines.append(
                "  keep it as a regression test: copy the folder into the repository and run "
                "pytest --mt-replay <copied folder> in CI (it fails while the case does)"
            )
            return lines
        lines.append("  keep it as a regression example:")
        lines.extend(f"    {line}" for line in example_snippet(self.artifact).splitlines())
        return lines

    def to_json(self) -> dict[str, Any]:
        return {
            "artifact": str(self.artifact.folder),
            "nodeid": self.artifact.nodeid,
            "relation": self.artifact.relation,
            "still_fails": self.still_fails,
            "explanation": self.verdict.explanation,
            "lines": self.lines(),
        }


def replay(
    artifact: Artifact, spec: Any, fixtures: Mapping[str, Any] | None = None
) -> ReplayResult:
    """Run the system of ``spec`` (an ``@metamorphic`` test's spec) on a saved violation.

    Parameters
    ----------
    artifact : Artifact
        From :func:`~pytest_metamorphic.reports.artifacts.load_artifact`.
    spec : MetamorphicSpec
        ``test._metamorphic`` of the test the artifact came from: its system under test
        and relations (the relation is looked up by name, so a renamed relation is an
        error rather than a silent pass).
    fixtures : mapping, optional
        Values of the test function's fixture parameters.
    """
    relation = next((mr for mr in spec.relations if mr.name == artifact.relation), None)
    if relation is None:
        names = [mr.name for mr in spec.relations]
        raise InvalidArgument(
            f"{artifact.folder}: the test has no relation named {artifact.relation!r} any more "
            f"(it has {names}); the artifact cannot be replayed"
        )
    kwargs = dict(fixtures or {})
    return replay_with(artifact, relation.relation, lambda value: spec.call(value, **kwargs))


def replay_with(
    artifact: Artifact, relation: Relation, system: Callable[[Any], Any]
) -> ReplayResult:
    """Run ``system`` on the artifact's saved source and follow-up and check ``relation``
    (the output relation): what :func:`replay` does for a test, and a campaign's case
    replays with its campaign's system and relation."""
    return replay_inputs(artifact, relation, system, artifact.source(), artifact.followup())


def replay_inputs(
    artifact: Artifact,
    relation: Relation,
    system: Callable[[Any], Any],
    source: Any,
    followup: Any,
) -> ReplayResult:
    """:func:`replay_with` on inputs rebuilt elsewhere (a campaign draws them again).

    A follow-up whose parameters hold a history (a ``params["history"]`` with
    ``earlier_inputs(source)``, such as
    :class:`~pytest_metamorphic.lidar.followups.history.EarlierSweeps`) runs after those
    inputs, as it did in the test, and is compared with its own input's output right
    after that input (the source's for a plain history)."""
    earlier = getattr(followup.params.get("history"), "earlier_inputs", None)
    history = tuple(earlier(source)) if callable(earlier) else tuple(followup.before)
    # As the engine: a history's input right after itself, then the history.
    source_output = replace(followup, before=history).compared_output(system, system(source))
    followup_output = system(followup.input)
    index = int(artifact.record.get("followup_index", 0))
    context = CheckContext(source, followup.input, followup.params, index)
    verdict = relation.check(source_output, followup_output, context)
    return ReplayResult(artifact, not verdict.holds, verdict, source_output, followup_output)


def _inline_case(artifact: Artifact) -> str | None:
    """``MetamorphicCase(...)`` source text when both inputs and the params are plain JSON."""
    record = artifact.record
    source, followup = record["source"], record["followup"]
    if source.get("kind") != "json" or followup.get("kind") != "json":
        return None
    params = record.get("params") or {}
    try:
        plain = json.loads(json.dumps(params, allow_nan=False)) == params
    except (TypeError, ValueError):
        plain = False
    if not plain or any(isinstance(v, dict) and "repr" in v for v in params.values()):
        return None
    extra = f", params={params!r}" if params else ""
    return (
        f"MetamorphicCase(source={source['value']!r}, followups={{{artifact.relation!r}: "
        f"(Followup({followup['value']!r}{extra}),)}})"
    )


def example_snippet(artifact: Artifact) -> str:
    """Python source for an ``@example`` that replays ``artifact`` in every test run."""
    inline = _inline_case(artifact)
    if inline is not None:
        return "\n".join(
            [
                "from hypothesis import example",
                "from pytest_metamorphic import Followup, MetamorphicCase",
                "",
                f"@example(case={inline})  # on top of @metamorphic / @settings",
            ]
        )
    name = Path(artifact.folder).name
    return "\n".join(
        [
            f"# copy the folder next to the test: cp -r {artifact.folder} <tests>/mt-regressions/",
            "from pathlib import Path",
            "from hypothesis import example",
            "from pytest_metamorphic.reports.artifacts import load_case",
            "",
            f'@example(case=load_case(Path(__file__).parent / "mt-regressions" / "{name}"))'
            "  # on top of @metamorphic / @settings",
        ]
    )
