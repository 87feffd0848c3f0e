from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from pytest_metamorphic import InvalidArgument, relations
from pytest_metamorphic.core.comparison import deep_equal, first_difference
from pytest_metamorphic.core.matching import PredicateMatcher, one_to_one
from pytest_metamorphic.core.relations import CheckContext, Verdict

CTX = CheckContext(index=1)


def test_equal_holds_and_explains_difference() -> None:
    assert relations.equal().check([1, 2], [1, 2], CTX)
    verdict = relations.equal().check([1, 2], [1, 3], CTX)
    assert not verdict
    assert verdict.explanation == "follow-up 1 differs from the source output: output[1]: 2 != 3"


def test_equal_with_expected_output_uses_params() -> None:
    relation = relations.equal(expected=lambda out, ctx: [x + ctx.params["shift"] for x in out])
    ctx = CheckContext(params={"shift": 2})
    assert relation.check([1, 2], [3, 4], ctx)
    assert not relation.check([1, 2], [1, 2], ctx)


def test_subset_needs_one_to_one_matching_not_counting() -> None:
    near = relations.subset(matcher=lambda a, b: abs(a - b) <= 1)
    # Both source elements are within 1 of the single follow-up element 10; counting or
    # "each has some match" would pass, one-to-one matching must not.
    verdict = near.check([9, 11], [10, 50], CTX)
    assert not verdict
    assert verdict.details["unmatched"] == [1] or verdict.details["unmatched"] == [0]
    assert "has no match in follow-up 1" in verdict.explanation
    assert near.check([9, 11], [10, 12], CTX)


def test_subset_names_the_lost_element() -> None:
    verdict = relations.subset().check(["car", "pedestrian"], ["car", "truck"], CTX)
    assert (
        verdict.explanation == "element #1 ('pedestrian') of the source has no match in follow-up 1"
    )


def test_superset_is_the_mirror_of_subset() -> None:
    assert relations.superset().check([1, 2, 3], [3, 1], CTX)
    verdict = relations.superset().check([1], [1, 2], CTX)
    assert "element #1 (2) of follow-up 1 has no match in the source" in verdict.explanation


def test_cardinality_is_the_papers_weaker_check() -> None:
    assert relations.cardinality().check([1, 2], [5, 6, 7], CTX)
    verdict = relations.cardinality("<=").check([1, 2, 3], [1], CTX)
    assert not verdict
    assert verdict.details == {"source_size": 3, "followup_size": 1}
    with pytest.raises(InvalidArgument, match="op='=<' must be one of"):
        relations.cardinality("=<")


def test_approx_tolerances() -> None:
    assert relations.approx(abs=0.01).check([1.0, 2.0], [1.005, 2.0], CTX)
    verdict = relations.approx(rel=1e-3).check(np.array([1.0, 2.0]), np.array([1.0, 2.1]), CTX)
    assert not verdict
    assert "1 value(s) outside tolerance" in verdict.explanation
    with pytest.raises(InvalidArgument, match="abs=-1 must be a finite number >= 0"):
        relations.approx(abs=-1)


def test_predicate_accepts_bool_or_verdict_and_rejects_other_results() -> None:
    assert relations.predicate(lambda a, b, ctx: a <= b).check(1, 2, CTX)
    custom = Verdict(False, "mine", "because")
    assert relations.predicate(lambda a, b, ctx: custom).check(1, 2, CTX) is custom
    with pytest.raises(InvalidArgument, match="must return a bool or a Verdict"):
        relations.predicate(lambda a, b, ctx: "yes").check(1, 2, CTX)


def test_combination_reports_every_failing_part() -> None:
    both = relations.cardinality("<=") & relations.subset()
    assert both.name == "cardinality(|O| <= |O'|) & subset[equality]"
    verdict = both.check([1, 2, 3], [4], CTX)
    assert not verdict
    assert verdict.explanation.startswith("cardinality(|O| <= |O'|): the source output has 3")
    assert "subset[equality]: element #0 (1)" in verdict.explanation


def test_collection_relations_reject_scalar_outputs_clearly() -> None:
    with pytest.raises(InvalidArgument, match="needs collection outputs; the source output is 5"):
        relations.subset().check(5, [5], CTX)


@given(st.lists(st.lists(st.booleans(), min_size=4, max_size=4), min_size=0, max_size=5))
def test_one_to_one_finds_a_maximum_matching(rows: list[list[bool]]) -> None:
    compatible = np.array(rows, dtype=bool).reshape(len(rows), 4)
    pairs = one_to_one(compatible)
    assert all(compatible[i, j] for i, j in pairs)
    assert len({i for i, _ in pairs}) == len({j for _, j in pairs}) == len(pairs)
    expected = maximum_bipartite_matching(csr_matrix(compatible.astype(int)), perm_type="column")
    assert len(pairs) == int((expected >= 0).sum())


def test_one_to_one_prefers_cheaper_pairs_among_maximum_matchings() -> None:
    compatible = np.ones((2, 2), bool)
    cost = np.array([[5.0, 0.0], [0.0, 5.0]])
    assert one_to_one(compatible, cost) == [(0, 1), (1, 0)]


def test_predicate_matcher_shapes_for_empty_sides() -> None:
    compatible, cost = PredicateMatcher(lambda a, b: True).pairwise([], [1, 2])
    assert compatible.shape == cost.shape == (0, 2)


def test_deep_equal_understands_arrays_nan_and_nesting() -> None:
    assert deep_equal({"a": [np.array([1.0, np.nan])]}, {"a": [np.array([1.0, np.nan])]})
    assert first_difference(np.zeros(3), np.array([0, 1.0, 0])) == (
        "output[1]: np.float64(0.0) != np.float64(1.0) (1 element(s) differ)"
    )
    assert first_difference((1, 2), [1, 2]) == "output: tuple != list"
    assert first_difference({"a": 1}, {"b": 1}).startswith("output: keys differ")
