"""How many returns of a real sweep scikit-learn's HDBSCAN clusters differently when the
same returns come in another order (docs/findings/sklearn-hdbscan-row-order.md).

KITTI training sweep 000001 (HDL-64E): the returns in the camera's field of view that the
reference ground stage (run on those returns only) does not call ground, clustered with
``HDBSCAN(min_cluster_size=10)`` in the recorded order and in ``--orders`` permutations
(numpy seeds 0, 1, ...); returns that changed cluster are counted by pair agreement
(:func:`~pytest_metamorphic.lidar.judging.points.changed_clusters`). Ends with
``RESULT returns=<n> changed_min=<n> changed_max=<n> clusters=<a>-<b>``.

    python bench/hdbscan_row_order.py [--orders 3]
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import conftest  # noqa: E402
from pytest_metamorphic.lidar.io.catalog import FrameCatalog  # noqa: E402
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.judging.points import changed_clusters  # noqa: E402
from pytest_metamorphic.lidar.systems.components import (  # noqa: E402
    ReferenceGround,
    SklearnClusters,
)


def main(argv: list[str]) -> int:
    from sklearn.cluster import HDBSCAN

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orders", type=int, default=3)
    options = parser.parse_args(argv)
    warnings.filterwarnings("ignore", category=FutureWarning)
    frame = FrameCatalog(
        str(conftest.SHARED_DATA / "kitti_openpcdet" / "training"), roi=kitti_label_region()
    )[1]
    feed = SklearnClusters(HDBSCAN(), ground=ReferenceGround(), within_roi=True).feed.mask(frame)
    points = frame.cloud.xyz[feed].astype(np.float64)
    recorded = HDBSCAN(min_cluster_size=10, copy=True).fit_predict(points)
    counts, clusters = [], {len(set(recorded.tolist()) - {-1})}
    for seed in range(options.orders):
        order = np.random.default_rng(seed).permutation(len(points))
        labels = np.empty(len(points), dtype=np.int64)
        labels[order] = HDBSCAN(min_cluster_size=10, copy=True).fit_predict(points[order])
        changed, _ = changed_clusters(recorded, labels)
        counts.append(int(changed.sum()))
        clusters.add(len(set(labels.tolist()) - {-1}))
        print(f"order {seed}: {counts[-1]} of {len(points)} returns changed cluster")
    print(
        f"RESULT returns={len(points)} changed_min={min(counts)} changed_max={max(counts)} "
        f"clusters={min(clusters)}-{max(clusters)}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
