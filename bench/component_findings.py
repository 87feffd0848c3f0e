"""The component relations on the components people compose, on four real recordings.

Every component of :mod:`pytest_metamorphic.lidar.systems.components` (ground segmenters:
the reference's ground stage, Patchwork++ fresh and reused, Open3D's RANSAC plane seeded
and unseeded; clusterers fed the ROI's non-ground returns: the reference grid, scikit-learn's
DBSCAN, HDBSCAN and OPTICS, Open3D's DBSCAN) is run on one sweep of KITTI (HDL-64E, the
camera wedge as ROI), the Velodyne VLP-16 and VLP-32C recordings and the Ouster OS1-64
recording (the 7 m corridor ahead as ROI), under every relation of
``component_relations(kind, symmetric=True)`` with ``--draws`` follow-ups each, drawn
derandomized (the same follow-ups every run). Printed: per component and relation, the
follow-ups that violated it, how many returns changed (median), and the first
explanation; ``docs/findings/README.md`` classifies them. Ends with
``RESULT components=<n> relations=<n> pairs=<n> violating_pairs=<n>``.

    python bench/component_findings.py [--draws 3] [--components dbscan,hdbscan]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import conftest  # noqa: E402
from pytest_metamorphic.core.cases import Followup  # noqa: E402
from pytest_metamorphic.core.relations import CheckContext  # noqa: E402
from pytest_metamorphic.lidar.io.catalog import FrameCatalog  # noqa: E402
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.model.frame import Frame  # noqa: E402
from pytest_metamorphic.lidar.roi import corridor_roi  # noqa: E402
from pytest_metamorphic.lidar.systems import components as c  # noqa: E402
from pytest_metamorphic.relations.lidar.components import component_relations  # noqa: E402

DATA = conftest.SHARED_DATA


def recordings() -> dict[str, Frame]:
    corridor = corridor_roi(width=7.0)
    return {
        "KITTI 000001": FrameCatalog(
            str(DATA / "kitti_openpcdet" / "training"), roi=kitti_label_region()
        )[1],
        "VLP-16": FrameCatalog(
            str(DATA / "nebula_velodyne" / "vlp16" / "1673400472138016708.pcd"), roi=corridor
        )[0],
        "VLP-32C": FrameCatalog(
            str(DATA / "nebula_velodyne" / "vlp32" / "1713492677464078412.pcd"), roi=corridor
        )[0],
        "OS1-64": FrameCatalog(
            str(DATA / "pointcloudset_ouster" / "test_converted.bag"),
            topic="/os1_cloud_node/points",
            roi=corridor,
        )[0],
    }


def components() -> dict[str, tuple[Any, str, float]]:
    """name -> (component, kind, DBSCAN border)."""
    from sklearn.cluster import DBSCAN, HDBSCAN, OPTICS

    ground = c.ReferenceGround()
    feed: dict[str, Any] = {"ground": ground, "within_roi": True}
    return {
        "reference ground": (ground, "labels", 0.0),
        "Patchwork++": (c.PatchworkGround(), "labels", 0.0),
        "Patchwork++ reused": (c.PatchworkGround(reuse=True), "labels", 0.0),
        "Open3D plane, seed 0": (c.Open3DPlaneGround(seed=0), "labels", 0.0),
        "Open3D plane, unseeded": (c.Open3DPlaneGround(seed=None), "labels", 0.0),
        "reference clusters": (c.ReferenceClusters(**feed), "clusters", 0.0),
        "sklearn DBSCAN": (
            c.SklearnClusters(DBSCAN(eps=0.5, min_samples=5), **feed),
            "clusters",
            0.5,
        ),
        "Open3D DBSCAN": (c.Open3DClusters(eps=0.5, min_points=5, **feed), "clusters", 0.5),
        "sklearn HDBSCAN": (
            c.SklearnClusters(HDBSCAN(min_cluster_size=10, copy=True), **feed),
            "clusters",
            0.0,
        ),
        "sklearn OPTICS": (
            c.SklearnClusters(OPTICS(min_samples=10, max_eps=1.0), **feed),
            "clusters",
            0.0,
        ),
    }


def run_pair(system: Any, frame: Frame, source_output: Any, relation: Any, followup: Any) -> Any:
    """One follow-up judged as the engine judges it (a history runs its input twice first)."""
    if not isinstance(followup, Followup):
        followup = Followup(followup)
    if followup.skipped:
        return None
    source = followup.compared_output(system, source_output)
    output = system(followup.input)
    return relation.relation.check(
        source, output, CheckContext(frame, followup.input, params=followup.params)
    )


def judge(system: Any, frame: Frame, relation: Any, draws: int) -> list[Any]:
    verdicts: list[Any] = []
    source_output = system(frame)

    @settings(
        max_examples=draws,
        derandomize=True,
        database=None,
        deadline=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(st.data())
    def draw(data: Any) -> None:
        verdict = run_pair(
            system, frame, source_output, relation, data.draw(relation.followup(frame))
        )
        if verdict is not None:
            verdicts.append(verdict)

    draw()
    return verdicts


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=3)
    parser.add_argument("--components", default="", help="comma-separated names (default: all)")
    options = parser.parse_args(argv)
    warnings.filterwarnings("ignore", category=FutureWarning)
    frames = recordings()
    chosen = components()
    if options.components:
        wanted = [name.strip() for name in options.components.split(",")]
        chosen = {k: v for k, v in chosen.items() if k in wanted}
    started = time.perf_counter()
    pairs = violating = relation_count = 0
    for name, (system, kind, border) in chosen.items():
        relations = component_relations(kind, border=border, symmetric=True)  # type: ignore[arg-type]
        relation_count = len(relations)
        print(f"== {name} ({system!r})", flush=True)
        for relation in relations:
            for frame_name, frame in frames.items():
                verdicts = judge(system, frame, relation, options.draws)
                failed = [v for v in verdicts if not v.holds]
                pairs += len(verdicts)
                violating += len(failed)
                changed = statistics.median(v.details["changed"] for v in failed) if failed else 0
                line = f"  {relation.name} | {frame_name}: {len(failed)}/{len(verdicts)} violate"
                if failed:
                    line += f", median {changed:g} returns changed: {failed[0].explanation[:240]}"
                print(line, flush=True)
    elapsed = time.perf_counter() - started
    print(f"{pairs} pairs in {elapsed:.0f} s")
    print(
        f"RESULT components={len(chosen)} relations={relation_count} pairs={pairs} "
        f"violating_pairs={violating}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
