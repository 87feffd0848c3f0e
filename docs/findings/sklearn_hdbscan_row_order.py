"""scikit-learn's HDBSCAN labels six points differently depending on their row order.

Needs only scikit-learn and numpy. Exits with an AssertionError while the defect is
present (seen with scikit-learn 1.9.1, numpy 2.4.6); silent once it is fixed.

The six values are a 1-minimal reduction of a real LiDAR sweep's behaviour (see
docs/findings/sklearn-hdbscan-row-order.md): two groups of returns and tied mutual
reachability distances, as millimetre coordinates give them.
"""

import numpy as np
from sklearn.cluster import HDBSCAN

X = np.array([[0.2], [1.2], [1.2], [0.1], [0.1], [0.7]])


def labels_in_row_order(order: list[int]) -> list[int]:
    """HDBSCAN's labels for X fed in ``order``, read back in X's own order."""
    labels = np.empty(len(X), dtype=int)
    labels[order] = HDBSCAN(min_cluster_size=3, copy=True).fit_predict(X[order])
    return labels.tolist()


as_given = labels_in_row_order([0, 1, 2, 3, 4, 5])
reversed_ = labels_in_row_order([5, 4, 3, 2, 1, 0])
print("as given:", as_given)  # [-1, -1, -1, -1, -1, -1]
print("reversed:", reversed_)  # [1, 0, 0, 1, 1, 0]
assert as_given == reversed_, "the same six points, in another order, are clustered differently"
