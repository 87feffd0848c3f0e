"""Campaign violations as cases: the first violations of each size saved as artifacts
exactly like ``@metamorphic`` ones, and replayed the same way.

A campaign's record of a violation is a line of text; an engineer needs the case. For the
first ``k`` violating pairs of each size (in source order, so the same ones however the
sources were sharded), :func:`save_cases` draws the source and the follow-up again from
the campaign's seeds, runs the system on both (the violation must still be there: a
system that is not deterministic is reported, not saved), reduces a reducible follow-up
(injected points, dropped points) to a 1-minimal one within the call budget, and writes
the folder :mod:`pytest_metamorphic.reports.artifacts` writes for a test: clouds, record,
bird's-eye picture, and ``pytest --mt-replay <folder>``, which re-runs the campaign's
system on the saved inputs and checks the campaign's relation (:func:`replay_case`).

Each pytest-xdist shard saves the first violations of its own sources; the process that
merges the shards keeps the first ``k`` of each size overall and removes the rest
(:func:`keep_first`), so the folder holds the same cases whichever way the run was split.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.batching import SystemCalls
from pytest_metamorphic.core.campaign import Campaign, CampaignResult
from pytest_metamorphic.core.campaign.baseline import slug
from pytest_metamorphic.core.campaign.spec import draw_followup
from pytest_metamorphic.core.cases import Followup
from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.core.files import field
from pytest_metamorphic.core.reduction import reduce_followup
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.core.violations import ViolationRecord
from pytest_metamorphic.reports.artifacts import Artifact, write_artifact

__all__ = ["SavedCase", "case_folder", "keep_first", "replay_case", "save_cases"]

KEYS = ("source", "size", "followup")  # what names a campaign's case


@dataclass(frozen=True)
class SavedCase:
    """One campaign violation saved as an artifact folder (or why it was not)."""

    source: int
    size: int
    followup: int
    folder: str  # "" when not saved
    note: str = ""

    def to_json(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "size": self.size,
            "followup": self.followup,
            "folder": self.folder,
            "note": self.note,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SavedCase:
        return cls(
            int(data["source"]),
            int(data["size"]),
            int(data["followup"]),
            str(data.get("folder", "")),
            str(data.get("note", "")),
        )


def campaign_root(root: Path, nodeid: str, campaign: str) -> Path:
    """Where a campaign's cases go: ``<root>/<test>/<campaign>/``."""
    test = slug(nodeid.split("[")[0].replace("::", "__").replace("/", "_"))[:80]
    return Path(root) / test / slug(campaign)[:80]


def case_folder(root: Path, label: str, source: int, size: int, followup: int) -> Path:
    return root / f"{slug(label)}{size}-source{source}-followup{followup}"


def first_cases(result: CampaignResult, k: int) -> list[dict[str, Any]]:
    """The first ``k`` violating pairs of each size, in (source, follow-up) order."""
    chosen: list[dict[str, Any]] = []
    per_size: dict[int, int] = {}
    for example in sorted(result.examples, key=lambda e: (e["source"], e["size"], e["followup"])):
        if per_size.get(example["size"], 0) < k:
            per_size[example["size"]] = per_size.get(example["size"], 0) + 1
            chosen.append(example)
    return chosen


def save_cases(
    campaign: Campaign,
    result: CampaignResult,
    *,
    root: Path,
    nodeid: str,
    k: int,
    budget: int,
    timeout: float | None = None,
    seconds: float | None = None,
) -> list[SavedCase]:
    """Save the first ``k`` violations of each size of ``result`` under ``root``.

    Parameters
    ----------
    campaign : Campaign
    result : CampaignResult
        This process's (shard's) result; its examples name the violating pairs.
    root : Path
        The campaign's artifact folder (:func:`campaign_root`).
    nodeid : str
        The campaign test's node id without its shard, which ``--mt-replay`` runs.
    k : int
        Violations per size.
    budget : int
        System calls allowed for reducing one case (0: not reduced).
    timeout : float, optional
        Seconds one system call may take.
    seconds : float, optional
        Seconds one case's reduction may take.
    """
    saved = []
    for example in first_cases(result, k):
        try:
            saved.append(_save_one(campaign, example, root, nodeid, (budget, seconds), timeout))
        except Exception as error:  # a case that cannot be saved must not cost the result
            case = SavedCase(example["source"], example["size"], example["followup"], "")
            saved.append(_note(case, f"not saved: {type(error).__name__}: {error}"))
    return saved


def _save_one(
    campaign: Campaign,
    example: Mapping[str, Any],
    root: Path,
    nodeid: str,
    limits: tuple[int, float | None],
    timeout: float | None,
) -> SavedCase:
    index, size, f = int(example["source"]), int(example["size"]), int(example["followup"])
    label = str(campaign.header().get("size_label", "n"))
    folder = case_folder(root, label, index, size, f)
    where = SavedCase(index, size, f, "")
    try:
        source = campaign.source(campaign.source_rng(index), index)
        value, params = draw_followup(campaign, source, index, campaign.sizes.index(size), f)
    except Exception as error:
        return _note(where, f"could not draw the pair again: {type(error).__name__}: {error}")
    calls = SystemCalls(campaign.system, timeout)
    outcomes = calls.run([source, value], [f"source {index}", f"source {index}, {label}={size}"])
    errors = [error for _, error in outcomes if error is not None]
    if errors:
        return _note(where, f"the system crashed on the pair again: {errors[0]}")
    source_output, followup_output = (output for output, _ in outcomes)
    context = CheckContext(source, value, params, f)
    verdict = campaign.relation.check(source_output, followup_output, context)
    if verdict.holds:
        return _note(where, "the pair holds when run again: the system is not deterministic")
    reduction, reduction_note = None, ""
    budget, seconds = limits
    if budget > 0:

        def run(reduced: Any) -> Any:
            output, error = calls.run([reduced], ["a reduced follow-up"])[0]
            if error is not None:
                raise error
            return output

        try:
            reduction = reduce_followup(
                params,
                source=source,
                source_output=source_output,
                followup_output=followup_output,
                run=run,
                check=campaign.relation.check,
                index=f,
                budget=budget,
                seconds=seconds,
            )
        except Exception as error:
            reduction_note = f"could not reduce the follow-up: {type(error).__name__}: {error}"
    record = ViolationRecord(
        nodeid=nodeid,
        relation=campaign.relation.name,
        check=verdict.relation,
        index=f,
        total=campaign.followups,
        source=source,
        followup=Followup(value, dict(params)),
        source_output=source_output,
        followup_output=followup_output,
        verdict=verdict,
        reduction=reduction,
        reduction_note=reduction_note,
        seed={"campaign_seed": campaign.seed, "source": index, "size": size, "followup": f},
    )
    extra = {
        "campaign": {
            "name": campaign.name,
            "header": campaign.header(),
            "source": index,
            "size": size,
            "followup": f,
        }
    }
    try:
        write_artifact(record, folder, status="final", extra=extra)
    except Exception as error:
        return _note(where, f"not saved to {folder}: {type(error).__name__}: {error}")
    return SavedCase(index, size, f, str(folder))


def _note(case: SavedCase, note: str) -> SavedCase:
    return SavedCase(case.source, case.size, case.followup, "", note)


def keep_first(
    result: CampaignResult, saved: Iterable[SavedCase], k: int, root: Path
) -> list[SavedCase]:
    """The saved cases among the first ``k`` of each size of the merged ``result``; every
    other case folder under ``root`` (another shard's later ones, an earlier run's) is
    removed."""
    wanted = {(e["source"], e["size"], e["followup"]) for e in first_cases(result, k)}
    kept = [case for case in saved if (case.source, case.size, case.followup) in wanted]
    keep_folders = {Path(case.folder).resolve() for case in kept if case.folder}
    if Path(root).is_dir():
        for folder in Path(root).iterdir():
            if folder.is_dir() and folder.resolve() not in keep_folders:
                shutil.rmtree(folder, ignore_errors=True)
    return sorted(kept, key=lambda case: (case.size, case.source, case.followup))


def replay_case(artifact: Artifact, campaign: Campaign) -> Any:
    """Re-run ``campaign``'s system on a saved campaign case and check its relation
    (a :class:`~pytest_metamorphic.reports.replay.ReplayResult`).

    Inputs saved as files or JSON are read back; inputs of a kind no file holds (a
    tuple, an object of the user's) are drawn again from the campaign's seeds, which
    needs the campaign unchanged since the case was saved (its header is compared).
    """
    from pytest_metamorphic.reports.replay import replay_inputs, replay_with

    record = artifact.record
    if campaign.relation.name != artifact.relation:
        raise DataError(
            f"the case was saved for relation {artifact.relation!r}; the campaign now judges "
            f"{campaign.relation.name!r}",
            path=artifact.folder,
        )
    kinds = {record["source"].get("kind"), record["followup"].get("kind")}
    if "unsupported" not in kinds:
        return replay_with(artifact, campaign.relation, campaign.system)
    found = record.get("campaign")
    saved: Mapping[str, Any] = found if isinstance(found, Mapping) else {}
    if saved.get("header") != campaign.header():
        raise DataError(
            "the case's inputs were not saved as files, and the campaign is not the one "
            f"that saved it (then {saved.get('header')}, now {campaign.header()}): they "
            "cannot be drawn again",
            path=artifact.folder,
        )
    where, path = "the record's campaign", artifact.folder / "record.json"
    index, size, f = (field(saved, key, int, where=where, path=path) for key in KEYS)
    if size not in campaign.sizes or not 0 <= f < campaign.followups:
        raise DataError(f"{where} names size {size}, follow-up {f}: not the campaign's", path=path)
    source = campaign.source(campaign.source_rng(index), index)
    value, params = draw_followup(campaign, source, index, campaign.sizes.index(size), f)
    return replay_inputs(
        artifact, campaign.relation, campaign.system, source, Followup(value, dict(params))
    )
