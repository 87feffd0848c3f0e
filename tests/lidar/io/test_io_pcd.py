"""PCD: real VLP-16/32 and fast_gicp scans, every DATA kind, round trips, header checks."""

from __future__ import annotations

import lzf
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.io import _lzf, read_pcd, read_pcd_header, write_pcd
from pytest_metamorphic.lidar.io.pcd import header as pcd
from pytest_metamorphic.lidar.model.cloud import PointCloud

VLP16 = "nebula_velodyne/vlp16/1673400472138016708.pcd"
VLP32 = "nebula_velodyne/vlp32/1713492677464078412.pcd"
VLP16_LAYOUT = [
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "u1"), ("return_type", "u1"),
    ("channel", "<u2"), ("azimuth", "<f4"), ("elevation", "<f4"), ("distance", "<f4"),
    ("time_stamp", "<u4"),
]  # fmt: skip


def _header(**overrides):
    lines = {
        "VERSION": "0.7",
        "FIELDS": "x y z intensity",
        "SIZE": "4 4 4 4",
        "TYPE": "F F F F",
        "COUNT": "1 1 1 1",
        "WIDTH": "2",
        "HEIGHT": "1",
        "VIEWPOINT": "0 0 0 1 0 0 0",
        "POINTS": "2",
        "DATA": "binary",
    }
    lines.update(overrides)
    return "".join(f"{key} {value}\n" for key, value in lines.items() if value is not None).encode()


def _write(tmp_path, header, payload=b"", name="t.pcd"):
    path = tmp_path / name
    path.write_bytes(header + payload)
    return path


# -- real files -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "count", "ranges"),
    [
        ("fast_gicp/251370668.pcd", 69_088, ((-23.3, 19.0), (-74.7, 8.9), (-3.0, 10.8))),
        ("fast_gicp/251371071.pcd", 69_792, ((-23.8, 18.5), (-52.0, 6.5), (-3.0, 9.2))),
        (VLP16, 14_831, ((-8.1, 2.5), (-12.6, 8.1), (-0.7, 2.2))),
        (VLP32, 26_216, ((-0.5, 23.5), (-11.7, 7.6), (-0.5, 2.6))),
    ],
)
def test_real_pcds_match_sources(shared_data, name, count, ranges):
    cloud = read_pcd(shared_data / name)
    assert len(cloud) == count
    low, high = cloud.bounds()
    for axis, (lo, hi) in enumerate(ranges):
        assert low[axis] == pytest.approx(lo, abs=0.051)
        assert high[axis] == pytest.approx(hi, abs=0.051)


def test_vlp16_fields_keep_their_types_and_values(shared_data):
    path = shared_data / VLP16
    header = read_pcd_header(path)
    assert header.fields == tuple(name for name, _ in VLP16_LAYOUT)
    assert header.sizes == (4, 4, 4, 1, 1, 2, 4, 4, 4, 4) and header.data == "binary"
    assert header.point_step == 32 and header.points == 14_831
    # An independent decode: numpy with the layout written out by hand.
    raw = np.fromfile(path, np.dtype(VLP16_LAYOUT), offset=header.data_offset)
    assert len(raw) == 14_831
    cloud = read_pcd(path)
    assert {k: v.dtype for k, v in cloud.fields.items()} == {
        name: np.dtype(code) for name, code in VLP16_LAYOUT[4:]
    }
    for index, column in enumerate(("x", "y", "z", "intensity")):
        assert np.array_equal(cloud.points[:, index], raw[column].astype(np.float32))
    for name, _ in VLP16_LAYOUT[4:]:
        assert np.array_equal(cloud.fields[name], raw[name])
    assert set(np.unique(cloud.fields["channel"])) <= set(range(16))


def test_vlp32_has_no_intensity(shared_data):
    cloud = read_pcd(shared_data / VLP32)
    assert not cloud.intensity.any() and cloud.fields == {}


@pytest.mark.parametrize("data", ["binary", "binary_compressed", "ascii"])
def test_real_cloud_round_trips_through_every_data_kind(shared_data, tmp_path, data):
    cloud = read_pcd(shared_data / VLP16)
    path = write_pcd(cloud, tmp_path / f"{data}.pcd", data=data)
    back = read_pcd(path)
    assert back.equals(cloud)
    assert read_pcd_header(path).data == data


def test_binary_write_is_the_same_layout_as_the_real_file(shared_data, tmp_path):
    source = shared_data / "fast_gicp/251370668.pcd"
    cloud = read_pcd(source)
    copy = write_pcd(cloud, tmp_path / "copy.pcd")
    start = read_pcd_header(source).data_offset
    assert copy.read_bytes()[read_pcd_header(copy).data_offset :] == source.read_bytes()[start:]


def test_compressed_file_built_by_hand_in_pcl_layout(tmp_path):
    # PCL's binary_compressed: two uint32 sizes, then LZF of the fields one after another
    # (all x, then all y, ...), padding fields included.
    n = 5
    x = np.arange(n, dtype="<f4")
    y = -x
    pad = np.full(n, 0xAB, "u1")
    ring = np.arange(n, dtype="<u2") + 7
    z = x * 2
    raw = x.tobytes() + y.tobytes() + z.tobytes() + pad.tobytes() + ring.tobytes()
    packed = lzf.compress(raw)
    header = _header(
        FIELDS="x y z _ ring", SIZE="4 4 4 1 2", TYPE="F F F U U", COUNT="1 1 1 1 1",
        WIDTH=str(n), POINTS=str(n), DATA="binary_compressed",
    )  # fmt: skip
    path = _write(tmp_path, header, np.array([len(packed), len(raw)], "<u4").tobytes() + packed)
    cloud = read_pcd(path)
    assert cloud.points[:, 0].tolist() == x.tolist() and cloud.points[:, 1].tolist() == y.tolist()
    assert cloud.points[:, 2].tolist() == z.tolist() and not cloud.intensity.any()
    assert list(cloud.fields) == ["ring"] and cloud.fields["ring"].tolist() == ring.tolist()
    assert cloud.fields["ring"].dtype == np.uint16


def test_padding_fields_and_counts_in_binary(tmp_path):
    layout = np.dtype(
        {"names": ["x", "y", "z", "n"], "formats": ["<f4", "<f4", "<f4", ("<f8", (3,))],
         "offsets": [0, 4, 8, 16], "itemsize": 40}
    )  # fmt: skip
    records = np.zeros(3, layout)
    records["x"] = [1, 2, 3]
    records["n"] = np.arange(9).reshape(3, 3)
    raw = bytearray(records.tobytes())
    header = _header(
        FIELDS="x y z _ n", SIZE="4 4 4 4 8", TYPE="F F F U F", COUNT="1 1 1 1 3",
        WIDTH="3", POINTS="3",
    )  # fmt: skip
    cloud = read_pcd(_write(tmp_path, header, bytes(raw)))
    assert cloud.points[:, 0].tolist() == [1, 2, 3]
    assert cloud.fields["n"].shape == (3, 3) and cloud.fields["n"][2].tolist() == [6, 7, 8]


def test_ascii_file_as_pcl_writes_it(tmp_path):
    header = _header(
        FIELDS="x y z rgb label", SIZE="4 4 4 4 4", TYPE="F F F F U", COUNT="1 1 1 1 1",
        DATA="ascii",
    )  # fmt: skip
    path = _write(tmp_path, header, b"1.5 -2 3e2 4.2108e+06 7\n0 0 1 0 4294967295\n")
    cloud = read_pcd(path)
    assert cloud.points.tolist() == [[1.5, -2, 300, 0], [0, 0, 1, 0]]
    assert cloud.fields["label"].dtype == np.uint32 and cloud.fields["label"][1] == 2**32 - 1
    assert cloud.fields["rgb"].dtype == np.float32


def test_organised_cloud_padding_policies(tmp_path):
    grid = np.zeros((2, 3, 4), "<f4")
    grid[0, 0] = [1, 2, 3, 4]
    grid[1, 2] = [5, 6, 7, 8]
    grid[0, 1] = np.nan  # PCL's padding for an organised cloud
    header = _header(WIDTH="3", HEIGHT="2", POINTS="6")
    path = _write(tmp_path, header, grid.tobytes())
    with pytest.raises(DataError, match=r"t\.pcd: 1 point\(s\) have NaN .*nonfinite='drop'"):
        read_pcd(path)
    cloud = read_pcd(path, nonfinite="drop")
    assert cloud.points.tolist() == [[1, 2, 3, 4], [5, 6, 7, 8]]
    assert (cloud.dropped_nonfinite, cloud.dropped_zero) == (1, 3)
    kept = read_pcd(path, nonfinite="drop", zeros="keep")
    assert (len(kept), kept.dropped_zero) == (5, 0)
    with pytest.raises(InvalidArgument, match="zeros='never'"):
        read_pcd(path, zeros="never")


def test_frame_id_and_timestamp_survive_in_comments(tmp_path):
    cloud = PointCloud(np.ones((2, 4)), frame_id="velo top", timestamp=1716000000.123456789)
    path = write_pcd(cloud, tmp_path / "c.pcd")
    assert b"# frame_id velo top\n" in path.read_bytes()
    back = read_pcd(path)
    assert back.frame_id == "velo top" and back.timestamp == cloud.timestamp


@st.composite
def rich_clouds(draw):
    n = draw(st.integers(0, 20))
    finite = st.floats(width=32, allow_nan=False, allow_infinity=False)
    points = draw(hnp.arrays(np.float32, (n, 4), elements=finite))
    fields = {}
    for index in range(draw(st.integers(0, 3))):
        dtype = draw(st.sampled_from(["u1", "i2", "u4", "i8", "u8", "f4", "f8"]))
        shape = (n,) if draw(st.booleans()) else (n, draw(st.integers(2, 3)))
        fields[f"f{index}"] = draw(hnp.arrays(np.dtype(dtype), shape))
    frame_id = draw(
        st.text(st.characters(blacklist_categories=["Cc", "Cs", "Zl", "Zp"]), max_size=8)
    )
    timestamp = draw(st.none() | st.floats(0, 4e9))
    return PointCloud(points, fields=fields, frame_id=frame_id.strip(), timestamp=timestamp)


@given(cloud=rich_clouds(), data=st.sampled_from(["binary", "binary_compressed", "ascii"]))
@settings(max_examples=60)
def test_any_cloud_round_trips(tmp_path_factory, cloud, data):
    path = write_pcd(cloud, tmp_path_factory.mktemp("pcd") / "c.pcd", data=data)
    back = read_pcd(path, zeros="keep")
    # equals() treats NaN != NaN, and NaN may sit in extra fields: compare bit patterns.
    # Text keeps every value but not a NaN's payload bits ("nan"); -0.0 survives as "-0".
    assert np.array_equal(back.points, cloud.points)
    assert (back.frame_id, back.timestamp) == (cloud.frame_id, cloud.timestamp)
    assert list(back.fields) == list(cloud.fields)
    for key, value in cloud.fields.items():
        got = back.fields[key]
        assert got.dtype == value.dtype
        if data == "ascii" and value.dtype.kind == "f":
            assert np.array_equal(got, value, equal_nan=True)
            assert np.array_equal(np.signbit(got), np.signbit(value)) or np.isnan(value).any()
        else:
            assert got.tobytes() == value.tobytes()


def test_write_refusals(tmp_path):
    cloud = PointCloud(np.zeros((1, 4)), fields={"flag": np.array([True])})
    with pytest.raises(InvalidArgument, match="'flag' has dtype bool, which PCD cannot store"):
        write_pcd(cloud, tmp_path / "a.pcd")
    with pytest.raises(InvalidArgument, match="field name 'my field'"):
        write_pcd(PointCloud(np.zeros((1, 4)), fields={"my field": [1]}), tmp_path / "a.pcd")
    with pytest.raises(InvalidArgument, match="line break"):
        write_pcd(PointCloud(np.zeros((1, 4)), frame_id="a\nb"), tmp_path / "a.pcd")
    with pytest.raises(InvalidArgument, match="data='zip'"):
        write_pcd(PointCloud(np.zeros((1, 4))), tmp_path / "a.pcd", data="zip")
    write_pcd(PointCloud(np.zeros((1, 4))), tmp_path / "a.pcd")
    with pytest.raises(InvalidArgument, match="overwrite=True"):
        write_pcd(PointCloud(np.zeros((1, 4))), tmp_path / "a.pcd")


# -- canonical headers of a known layout: one regex match, the same header ---------------


@given(cloud=rich_clouds(), data=st.sampled_from(["binary", "binary_compressed", "ascii"]))
@settings(max_examples=40)
def test_known_canonical_headers_parse_as_line_by_line(tmp_path_factory, cloud, data):
    path = write_pcd(cloud, tmp_path_factory.mktemp("pcd") / "c.pcd", data=data)
    head = path.read_bytes()[: pcd.MAX_HEADER_BYTES]
    reference = pcd._parse_header(head, path, complete=True)
    assert read_pcd_header(path) == reference  # the first read remembers the layout
    match = pcd._CANONICAL.match(head)
    assert match and pcd._parse_canonical(match, path) == reference
    assert read_pcd(path, zeros="keep").frame_id == cloud.frame_id


def test_real_headers_parse_as_line_by_line(shared_data):
    for name in ("fast_gicp/251370668.pcd", VLP16, VLP32):
        path = shared_data / name
        head = path.read_bytes()[:4096]
        reference = pcd._parse_header(head, path, complete=False)
        assert read_pcd_header(path) == read_pcd_header(path) == reference
        assert pcd._parse_canonical(pcd._CANONICAL.match(head), path) == reference


def test_known_layout_still_gets_every_header_check(tmp_path):
    payload = np.zeros(8, "<f4").tobytes()
    read_pcd(_write(tmp_path, _header(), payload))  # the layout is known from here on
    for content, message in [
        (_header(POINTS="3"), r"POINTS 3 differs from WIDTH x HEIGHT = 2"),
        (b"# timestamp soon\n" + _header(), "timestamp comment value 'soon' is not a number"),
        (b"# caf\xe9\n" + _header(), "header line at byte 0 is not text"),
        (_header(WIDTH="3", POINTS="3"), "needs 48 bytes but only 32 follow"),
    ]:
        with pytest.raises(DataError, match=message):
            read_pcd(_write(tmp_path, content, payload, name="again.pcd"))
    cloud = read_pcd(_write(tmp_path, b"# frame_id a b\n" + _header(), payload, name="f.pcd"))
    assert cloud.frame_id == "a b" and len(cloud) == 2


# -- record layouts: the block copy of x, y, z against numpy's own decoding -------------

LAYOUTS = {
    "PointXYZI": ("x y z intensity", "4 4 4 4", "F F F F"),
    "x y z only": ("x y z", "4 4 4", "F F F"),
    "x y z at the end of each record": ("_ x y z", "4 4 4 4", "U F F F"),
    "uint8 intensity, fields after it": ("x y z intensity ring t", "4 4 4 1 2 8", "F F F U U F"),
    "float64 intensity": ("x y z intensity", "4 4 4 8", "F F F F"),
    "padding between z and intensity": ("x y z _ intensity", "4 4 4 4 4", "F F F U F"),
    "not consecutive": ("x z y intensity", "4 4 4 4", "F F F F"),
    "float64 coordinates": ("x y z", "8 8 8", "F F F"),
}


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("n", [0, 1, 2, 257])
def test_record_layouts_decode_like_numpy(tmp_path, layout, n):
    fields, sizes, types = LAYOUTS[layout]
    names = fields.split()
    layout = zip(names, sizes.split(), types.split(), strict=True)
    dtype = np.dtype([
        (name if name != "_" else f"pad{i}", f"<{kind.lower()}{size}")
        for i, (name, size, kind) in enumerate(layout)
    ])  # fmt: skip
    rng = np.random.default_rng(n)
    records = np.zeros(n, dtype)
    for name in dtype.names:
        records[name] = rng.integers(0, 200, n) if dtype[name].kind == "u" else rng.normal(0, 50, n)
    header = _header(FIELDS=fields, SIZE=sizes, TYPE=types, COUNT=" ".join(["1"] * len(names)),
                     WIDTH=str(n), POINTS=str(n))  # fmt: skip
    cloud = read_pcd(_write(tmp_path, header, records.tobytes()), zeros="keep")
    columns = [records[c] if c in names else np.zeros(n) for c in ("x", "y", "z", "intensity")]
    assert np.array_equal(cloud.points, np.stack(columns, axis=1).astype(np.float32))
    extra = [name for name in names if name not in ("x", "y", "z", "intensity", "_")]
    assert list(cloud.fields) == extra
    for name in extra:
        assert cloud.fields[name].dtype == dtype[name]
        assert np.array_equal(cloud.fields[name], records[name])


def test_intensity_beyond_float32_meets_the_nonfinite_policy(tmp_path):
    records = np.zeros(3, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f8")])
    records["x"] = [1, 2, 3]
    records["intensity"] = [1.0, 1e39, 2.0]
    header = _header(SIZE="4 4 4 8", WIDTH="3", POINTS="3")
    path = _write(tmp_path, header, records.tobytes())
    with pytest.raises(
        DataError, match=r"1 point\(s\) have NaN or infinite values \(first at row 1"
    ):
        read_pcd(path)
    assert read_pcd(path, nonfinite="drop").points[:, 3].tolist() == [1.0, 2.0]


def test_fields_are_writable_and_independent(shared_data):
    cloud = read_pcd(shared_data / VLP16)
    before = {key: value.copy() for key, value in cloud.fields.items()}
    points = cloud.points.copy()
    cloud.fields["channel"][:] = 99
    cloud.fields["azimuth"] += 1
    assert cloud.fields["channel"].tolist() == [99] * len(cloud)
    for key in ("return_type", "elevation", "distance", "time_stamp"):
        assert np.array_equal(cloud.fields[key], before[key])
    assert np.array_equal(cloud.points, points)
    again = read_pcd(shared_data / VLP16)
    assert np.array_equal(again.fields["channel"], before["channel"])
    fast = read_pcd(shared_data / "fast_gicp/251370668.pcd")
    assert fast.points.flags.writeable and fast.points.flags.c_contiguous


# -- malformed headers: each one a DataError that names the file and the problem --------

BAD_HEADERS = [
    (b"", "empty file"),
    (b"\x00\x01garbage", "not a PCD file"),
    (b"VERSION 0.7\nFIELDS x y z\n", "no DATA line"),
    (b"\xff\xfe\n", "not text"),
    (_header(FIELDS=None), "no FIELDS line"),
    (_header(HEIGHT=None), "no HEIGHT line"),
    (_header(SIZE="4 4 4"), "SIZE has 3 entries for 4 FIELDS"),
    (_header(COUNT="1 1 1 1 1"), "COUNT has 5 entries"),
    (_header(TYPE="F F F X"), "TYPE 'X'"),
    (_header(SIZE="4 4 4 3"), "TYPE F with SIZE 3"),
    (_header(COUNT="1 1 1 0"), "COUNT 0"),
    (_header(COUNT="1 1 1 999999999"), "bytes per point"),
    (_header(WIDTH="-2"), "WIDTH value '-2' is not a non-negative integer"),
    (_header(WIDTH="2 3"), "WIDTH needs one integer"),
    (_header(WIDTH="\u00b2"), "WIDTH value '\u00b2' is not a non-negative integer"),  # isdigit()
    (_header(POINTS="3"), r"POINTS 3 differs from WIDTH x HEIGHT = 2"),
    (_header(VIEWPOINT="0 0 0"), "VIEWPOINT needs 7"),
    (_header(VIEWPOINT="0 0 0 1 0 0 x"), "VIEWPOINT value 'x'"),
    (_header(DATA="zip"), "DATA 'zip'"),
    (_header(FIELDS="x y x intensity"), "FIELDS repeats a name"),
    (_header(FIELDS="a b c d"), r"no x/y/z field"),
    (_header() + b"FIELDS x\n", None),  # after DATA it is payload, checked by size below
    (b"VERSION 0.7\nVERSION 0.7\n", "two VERSION lines"),
    (b"COLOR red\n", "unknown header line 'COLOR red'"),
]


@pytest.mark.parametrize(("content", "message"), BAD_HEADERS)
def test_malformed_headers(tmp_path, content, message):
    path = _write(tmp_path, content, name="bad.pcd")
    with pytest.raises(DataError) as error:
        read_pcd(path)
    assert str(error.value).startswith(f"{path}: ")
    if message:
        assert error.match(message)


def test_no_data_line_in_a_huge_header(tmp_path):
    path = _write(tmp_path, b"# comment\n" * 10_000, name="long.pcd")
    with pytest.raises(DataError, match="no DATA line in the first 65536 bytes"):
        read_pcd(path)


def test_lying_sizes_are_caught_before_allocation(tmp_path):
    payload = np.zeros(8, "<f4").tobytes()
    huge = _header(WIDTH="4000000000", POINTS="4000000000")
    with pytest.raises(DataError, match=r"needs 64000000000 bytes but only 32 follow"):
        read_pcd(_write(tmp_path, huge, payload))
    short = _header(WIDTH="3", POINTS="3")
    with pytest.raises(DataError, match="needs 48 bytes but only 32 follow"):
        read_pcd(_write(tmp_path, short, payload))
    ascii_ = _header(WIDTH="4000000000", POINTS="4000000000", DATA="ascii")
    with pytest.raises(DataError, match="ascii points needs"):
        read_pcd(_write(tmp_path, ascii_, b"1 2 3 4\n"))


def test_compressed_payload_checks(tmp_path):
    header = _header(DATA="binary_compressed")
    raw = np.arange(8, dtype="<f4").tobytes()
    packed = lzf.compress(raw, 64)

    def sizes(compressed, uncompressed):
        return np.array([compressed, uncompressed], "<u4").tobytes()

    cases = [
        (b"\x01", "compressed-size words"),
        (sizes(len(packed), 31) + packed, "declares 31 bytes but 2 points of 16 bytes need 32"),
        (sizes(10_000, 32) + packed, "compressed payload needs 10000 bytes"),
        (sizes(len(packed), 32) + bytes(len(packed)), "corrupt binary_compressed payload"),
    ]
    for payload, message in cases:
        with pytest.raises(DataError, match=message):
            read_pcd(_write(tmp_path, header, payload))
    big = _header(DATA="binary_compressed", WIDTH="100000", POINTS="100000")
    with pytest.raises(DataError, match="4 LZF bytes cannot expand to the declared 1600000"):
        read_pcd(_write(tmp_path, big, sizes(4, 1_600_000) + b"\x00" * 4))


def test_ascii_payload_checks(tmp_path):
    header = _header(DATA="ascii", TYPE="F F F U", SIZE="4 4 4 1")
    for payload, message in [
        (b"1.000000 2.000000 3.000000 4\n", "has 4 values; 2 points x 4 values need 8"),
        (b"1 2 3 4\n1 2 3 x\n", "field 'intensity' has a value that is not a U1"),
        (b"1 2 3 4\n1 2 3 300\n", "not a U1"),
        (b"1 2 3 4\n1 2 \xff 4\n", "non-ASCII"),
    ]:
        with pytest.raises(DataError, match=message):
            read_pcd(_write(tmp_path, header, payload))


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match=r"nope\.pcd: cannot read PCD file"):
        read_pcd(tmp_path / "nope.pcd")


# -- LZF -----------------------------------------------------------------------------------


def test_fallback_lzf_decoder_agrees_with_liblzf(shared_data):
    raw = (shared_data / VLP16).read_bytes()[:200_000]
    packed = lzf.compress(raw)
    assert _lzf.decompress(packed, len(raw), native=False) == raw
    literal = _lzf.compress(raw, native=False)
    assert lzf.decompress(literal, len(raw)) == raw
    assert _lzf.compress(b"") == b"" and _lzf.decompress(b"", 0) == b""


@given(st.binary(max_size=300), st.integers(1, 4))
@settings(max_examples=60)
def test_lzf_both_ways(data, repeat):
    data = data * repeat  # repetition gives back references, overlapping ones included
    packed = _lzf.compress(data)
    assert _lzf.decompress(packed, len(data)) == data
    assert _lzf.decompress(packed, len(data), native=False) == data


@pytest.mark.parametrize("native", [True, False])
def test_lzf_corruptions_are_value_errors(native):
    packed = lzf.compress(b"abcabcabcabcabcabc" * 10)
    for data, size in [
        (packed, 10),  # declared too small
        (packed, 1000),  # declared too large
        (b"\x05ab", 6),  # literal run past the end
        (b"\x00a\xe0", 10),  # back reference cut off
        (b"\x00a\x20\x05", 10),  # back reference before the start
        (b"abc", 0),
    ]:
        with pytest.raises(ValueError):
            _lzf.decompress(data, size, native=native)
