"""PointCloud: validation, the NaN policy, selection, concatenation, equality."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud, column_bounds, iter_chunks

FINITE = st.floats(-1e4, 1e4, allow_nan=False, width=32)


@st.composite
def clouds(draw, *, max_size=12, fields=("ring",)):
    n = draw(st.integers(0, max_size))
    points = draw(hnp.arrays(np.float32, (n, 4), elements=FINITE))
    extra = {name: draw(hnp.arrays(np.uint16, (n,))) for name in fields}
    return PointCloud(points, fields=extra, frame_id="lidar", timestamp=draw(st.floats(0, 2e9)))


def test_three_columns_get_zero_intensity_and_float32():
    cloud = PointCloud([[1, 2, 3], [4, 5, 6]])
    assert cloud.points.dtype == np.float32 and cloud.points.flags.c_contiguous
    assert cloud.points.tolist() == [[1, 2, 3, 0], [4, 5, 6, 0]]
    assert cloud.xyz.shape == (2, 3) and cloud.xy.shape == (2, 2)
    assert cloud.intensity.tolist() == [0, 0]


def test_float32_input_is_not_copied():
    points = np.ones((5, 4), np.float32)
    assert PointCloud(points).points is points


@pytest.mark.parametrize(
    ("points", "message"),
    [
        (np.zeros((3, 5)), r"shape \(n, 3\) or \(n, 4\), got \(3, 5\)"),
        (np.zeros(4), r"got \(4,\)"),
        (np.array([["a", "b", "c"]]), "must be numeric"),
        ([[1, 2], [3]], "cannot be converted"),
    ],
)
def test_bad_points_name_the_problem(points, message):
    with pytest.raises(DataError, match=message):
        PointCloud(points, name="frame.bin")


def test_error_names_the_cloud():
    with pytest.raises(DataError, match=r"^frame\.bin must have shape"):
        PointCloud(np.zeros((3, 5)), name="frame.bin")


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"ring": np.zeros(2)}, r"field 'ring' has shape \(2,\), expected \(3,\)"),
        ({"x": np.zeros(3)}, "clashes with the column"),
        ({"": np.zeros(3)}, "non-empty strings"),
        ({"label": np.array(["a", "b", "c"])}, "numeric or boolean"),
        ({"cube": np.zeros((3, 2, 2))}, r"expected \(3,\) or \(3, k\)"),
        ([("ring", np.zeros(3))], "must be a mapping"),
    ],
)
def test_bad_fields_are_refused(fields, message):
    with pytest.raises(DataError, match=message):
        PointCloud(np.zeros((3, 4)), fields=fields)


def test_fields_keep_dtype_and_may_have_several_values_per_point():
    normals = np.arange(9, dtype=np.float64).reshape(3, 3)
    cloud = PointCloud(
        np.zeros((3, 4)), fields={"ring": np.arange(3, dtype=np.uint8), "n": normals}
    )
    assert cloud.fields["ring"].dtype == np.uint8
    assert cloud.fields["n"].shape == (3, 3)
    assert cloud[[2, 0]].fields["n"].tolist() == [[6, 7, 8], [0, 1, 2]]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_rejected_by_default_with_row_and_hint(bad):
    points = np.zeros((4, 4), np.float32)
    points[2, 1] = bad
    with pytest.raises(
        DataError, match=r"1 point\(s\) .* \(first at row 2\); pass nonfinite='drop'"
    ):
        PointCloud(points)


def test_nonfinite_drop_removes_and_counts_and_fields_follow():
    points = np.arange(20, dtype=np.float32).reshape(5, 4)
    points[1, 0] = np.nan
    points[3, 3] = np.inf  # intensity counts too
    cloud = PointCloud(points, fields={"ring": np.arange(5)}, nonfinite="drop")
    assert cloud.dropped_nonfinite == 2
    assert cloud.fields["ring"].tolist() == [0, 2, 4]
    assert cloud.points[:, 0].tolist() == [0, 8, 16]


# Every float32 a file can hold: NaN, infinities, subnormals and values whose squares
# overflow (the finite check's fast path sums squares, so those must not read as bad).
ANY_FLOAT32 = st.floats(width=32) | st.sampled_from([3.4e38, -3.4e38, 2e19, 1e-45, -0.0])


@settings(max_examples=200)
@given(
    points=hnp.arrays(np.float32, st.tuples(st.integers(0, 40), st.just(4)), elements=ANY_FLOAT32)
)
def test_the_nonfinite_policy_sees_exactly_the_rows_isfinite_sees(points):
    finite = np.isfinite(points).all(axis=1)
    cloud = PointCloud(points, nonfinite="drop")
    assert cloud.dropped_nonfinite == int((~finite).sum())
    assert cloud.points.tobytes() == points[finite].tobytes()
    if finite.all():
        assert PointCloud(points).points.tobytes() == points.tobytes()
        assert cloud.with_points(points).points.tobytes() == points.tobytes()
    else:
        with pytest.raises(DataError, match="NaN or infinite"):
            PointCloud(points)


def test_huge_values_and_signalling_nans_are_judged_without_a_warning():
    # Squares of huge values overflow float32 and arithmetic on a signalling NaN (any bit
    # pattern a file holds) raises "invalid": the fast path gives up and the values are
    # checked one by one, silently (a user running with -W error must see no warning).
    points = np.full((3, 4), 3e38, np.float32)
    signalling = points.copy()
    signalling.view(np.uint32)[1, 2] = 0x7F800001
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert PointCloud(points).points.tobytes() == points.tobytes()
        with pytest.raises(DataError, match=r"first at row 1"):
            PointCloud(signalling)
        assert PointCloud(signalling, nonfinite="drop").dropped_nonfinite == 1


def test_float64_beyond_float32_range_meets_the_policy():
    with pytest.raises(DataError, match="NaN or infinite"):
        PointCloud([[1e39, 0, 0, 0]])
    assert len(PointCloud([[1e39, 0, 0, 0], [1, 2, 3, 4]], nonfinite="drop")) == 1


def test_bad_policy_and_timestamp_arguments():
    with pytest.raises(InvalidArgument, match="nonfinite='keep'"):
        PointCloud(np.zeros((1, 4)), nonfinite="keep")
    with pytest.raises(InvalidArgument, match="timestamp='soon'"):
        PointCloud(np.zeros((1, 4)), timestamp="soon")
    with pytest.raises(DataError, match="timestamp nan is not finite"):
        PointCloud(np.zeros((1, 4)), timestamp=float("nan"))


def test_selection_by_mask_indices_and_slice():
    cloud = PointCloud(np.arange(24, dtype=np.float32).reshape(6, 4), fields={"t": np.arange(6)})
    assert cloud[cloud.points[:, 0] > 10].fields["t"].tolist() == [3, 4, 5]
    assert cloud[[5, -6]].fields["t"].tolist() == [5, 0]
    assert cloud[1:3].fields["t"].tolist() == [1, 2]
    assert cloud[np.array([], dtype=int)].points.shape == (0, 4)
    assert len(cloud[[]]) == 0


@pytest.mark.parametrize(
    ("index", "message"),
    [
        (3, "not an array of shape"),
        (np.zeros((2, 2), int), r"shape \(2, 2\)"),
        ([6], "index 6 is out of range for a cloud of 6 points"),
        ([-7], "index -7 is out of range"),
        (np.ones(5, bool), r"boolean mask has shape \(5,\)"),
        (np.array([0.5]), "float64"),
    ],
)
def test_bad_selection_is_an_invalid_argument(index, message):
    cloud = PointCloud(np.zeros((6, 4)))
    with pytest.raises(InvalidArgument, match=message):
        cloud[index]


def test_selection_result_owns_contiguous_points():
    cloud = PointCloud(np.arange(24, dtype=np.float32).reshape(6, 4))
    picked = cloud[::2]
    assert picked.points.flags.c_contiguous
    assert picked.xyz.base is picked.points


def test_concatenate_keeps_first_metadata_and_checks_fields():
    a = PointCloud(
        np.zeros((2, 4)), fields={"ring": np.zeros(2, np.uint8)}, frame_id="a", timestamp=1
    )
    b = PointCloud(np.ones((3, 4)), fields={"ring": np.ones(3, np.uint8)}, frame_id="b")
    both = PointCloud.concatenate([a, b])
    assert len(both) == 5 and both.frame_id == "a" and both.timestamp == 1.0
    assert both.fields["ring"].tolist() == [0, 0, 1, 1, 1]
    with pytest.raises(InvalidArgument, match="at least one"):
        PointCloud.concatenate([])
    with pytest.raises(InvalidArgument, match=r"clouds\[1\] has fields \[\]"):
        PointCloud.concatenate([a, PointCloud(np.zeros((1, 4)))])
    with pytest.raises(InvalidArgument, match=r"clouds\[1\] is ndarray"):
        PointCloud.concatenate([a, np.zeros((1, 4))])
    wide = PointCloud(np.zeros((1, 4)), fields={"ring": np.zeros((1, 2))})
    with pytest.raises(InvalidArgument, match="values per point"):
        PointCloud.concatenate([a, wide])


def test_with_points_bounds_and_empty():
    cloud = PointCloud([[0, 0, 0, 1], [2, -1, 5, 3]], fields={"t": [1, 2]}, frame_id="f")
    moved = cloud.with_points(cloud.points + 1)
    assert moved.frame_id == "f" and moved.fields["t"].tolist() == [1, 2]
    assert cloud.bounds().tolist() == [[0, -1, 0, 1], [2, 0, 5, 3]]
    with pytest.raises(InvalidArgument, match="3 rows, the cloud has 2"):
        cloud.with_points(np.zeros((3, 4)))
    with pytest.raises(DataError, match="NaN"):
        cloud.with_points([[np.nan, 0, 0, 0], [0, 0, 0, 0]])
    empty = PointCloud.empty(fields={"ring": np.uint8})
    assert len(empty) == 0 and empty.fields["ring"].dtype == np.uint8
    with pytest.raises(DataError, match="no bounds"):
        empty.bounds()


@given(
    n=st.integers(1, 700) | st.sampled_from([255, 256, 257, 512, 513]),
    k=st.integers(1, 5),
    dtype=st.sampled_from([np.float32, np.float64, np.int16]),
    special=st.sampled_from([None, np.nan, np.inf, -np.inf]),
    seed=st.integers(0, 2**32 - 1),
)
@settings(max_examples=80)
def test_column_bounds_are_the_per_column_min_and_max(n, k, dtype, special, seed):
    rng = np.random.default_rng(seed)
    array = (rng.standard_normal((n, k)) * 1000).astype(dtype)
    if special is not None and dtype != np.int16:
        array[rng.integers(n), rng.integers(k)] = special  # NaN propagates like numpy.min
    expected = np.stack([array.min(axis=0), array.max(axis=0)])
    got = column_bounds(array)
    assert got.dtype == array.dtype and got.shape == (2, k)
    assert np.array_equal(got, expected, equal_nan=dtype != np.int16)
    # Columns are not mixed up across the folded rows (each column has its own range).
    shifted = array.astype(np.float64) + np.arange(k) * 1e4
    assert np.array_equal(column_bounds(shifted)[1], shifted.max(axis=0), equal_nan=True)


def test_column_bounds_refuses_what_has_no_bounds():
    with pytest.raises(InvalidArgument, match=r"n >= 1, got \(0, 4\)"):
        column_bounds(np.zeros((0, 4)))
    with pytest.raises(InvalidArgument, match=r"got \(5,\)"):
        column_bounds(np.zeros(5))
    cloud = PointCloud(np.arange(4000, dtype=np.float32).reshape(1000, 4) - 2000)
    assert cloud.bounds().tolist() == [[-2000, -1999, -1998, -1997], [1996, 1997, 1998, 1999]]


def test_equals_compares_everything():
    base = PointCloud(
        np.zeros((2, 4)), fields={"r": np.zeros(2, np.uint8)}, frame_id="f", timestamp=1.0
    )
    same = PointCloud(
        np.zeros((2, 4)), fields={"r": np.zeros(2, np.uint8)}, frame_id="f", timestamp=1.0
    )
    assert base.equals(same) and not base.equals("cloud")
    variants = [
        PointCloud(
            np.zeros((2, 4)), fields={"r": np.zeros(2, np.uint16)}, frame_id="f", timestamp=1.0
        ),
        PointCloud(
            np.zeros((2, 4)), fields={"s": np.zeros(2, np.uint8)}, frame_id="f", timestamp=1.0
        ),
        PointCloud(
            np.zeros((2, 4)), fields={"r": np.zeros(2, np.uint8)}, frame_id="g", timestamp=1.0
        ),
        PointCloud(np.zeros((2, 4)), fields={"r": np.zeros(2, np.uint8)}, frame_id="f"),
        PointCloud(
            np.ones((2, 4)), fields={"r": np.zeros(2, np.uint8)}, frame_id="f", timestamp=1.0
        ),
    ]
    assert not any(base.equals(other) for other in variants)


def test_repr_is_short():
    cloud = PointCloud(np.zeros((100_000, 4)), fields={"ring": np.zeros(100_000)}, frame_id="velo")
    assert repr(cloud) == "PointCloud(<100000 points>, fields=['ring'], frame_id='velo')"


def test_iter_chunks():
    cloud = PointCloud(np.arange(40, dtype=np.float32).reshape(10, 4))
    assert [len(c) for c in iter_chunks(cloud, 4)] == [4, 4, 2]
    with pytest.raises(InvalidArgument):
        list(iter_chunks(cloud, 0))


@given(clouds(), st.data())
@settings(max_examples=40)
def test_selection_then_concatenation_restores_the_cloud(cloud, data):
    mask = data.draw(hnp.arrays(bool, (len(cloud),)))
    order = np.concatenate([np.flatnonzero(mask), np.flatnonzero(~mask)])
    parts = PointCloud.concatenate([cloud[mask], cloud[~mask]])
    assert parts.equals(cloud[order])
    assert np.array_equal(parts.fields["ring"], cloud.fields["ring"][order])
