"""KITTI labels/calibration and Apollo's text formats, on the real files."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.lidar.io import (
    read_apollo_clusters,
    read_apollo_poly,
    read_apollo_pose,
    read_apollo_roi_points,
    read_bin,
    read_kitti_calibration,
    read_kitti_dont_care,
    read_kitti_labels,
    read_kitti_objects,
)
from pytest_metamorphic.lidar.io.kitti import KITTI_LABELS, KittiDontCare, sensor_calibration
from pytest_metamorphic.lidar.model.obstacles import Box

TRAINING = "kitti_openpcdet/training"


def _frame(shared_data, number):
    root = shared_data / TRAINING
    return root / "label_2" / f"{number}.txt", root / "calib" / f"{number}.txt"


def _openpcdet_box(line, calib):
    """OpenPCDet's conversion (centre through R0/Tr, yaw = -(ry + pi/2)): a second opinion."""
    values = [float(v) for v in line.split()[1:]]
    h, w, length, x, y, z, ry = values[7:14]
    rect = np.array([x, y, z, 1.0])
    r0 = np.eye(4)
    r0[:3, :3] = calib.R0_rect
    v2c = np.eye(4)
    v2c[:3] = calib.Tr_velo_to_cam
    lidar = np.linalg.inv(r0 @ v2c) @ rect
    return (lidar[0], lidar[1], lidar[2] + h / 2), (length, w, h), -(ry + np.pi / 2)


def _inside(box, xyz):
    local = xyz - np.array(box.center)
    c, s = math.cos(-box.yaw), math.sin(-box.yaw)
    u = c * local[:, 0] - s * local[:, 1]
    v = s * local[:, 0] + c * local[:, 1]
    length, width, height = box.size
    return (abs(u) <= length / 2) & (abs(v) <= width / 2) & (abs(local[:, 2]) <= height / 2)


def test_labels_of_the_six_training_frames(shared_data):
    found = {n: read_kitti_objects(*_frame(shared_data, f"00000{n}")) for n in range(6)}
    assert [o.type for o in found[0]] == ["Pedestrian"]
    assert [o.type for o in found[1]] == ["Truck", "Car", "Cyclist"]  # 4 DontCare skipped
    assert [o.box.label for o in found[1]] == ["car", "car", "cyclist"]
    assert "Misc" in [o.type for o in found[2]]
    assert {o.box.label for objects in found.values() for o in objects} == {
        "car", "pedestrian", "cyclist", "unknown",
    }  # fmt: skip
    pedestrian = found[0][0]
    assert pedestrian.bbox == (712.40, 143.00, 810.73, 307.92)
    assert pedestrian.box.size == pytest.approx((1.20, 0.48, 1.89))
    assert pedestrian.box.score is None


def test_boxes_agree_with_openpcdets_conversion(shared_data):
    for number in range(6):
        label, calib_path = _frame(shared_data, f"00000{number}")
        calib = read_kitti_calibration(calib_path)
        lines = [ln for ln in label.read_text().splitlines() if not ln.startswith("DontCare")]
        for line, box in zip(lines, read_kitti_labels(label, calib_path), strict=True):
            centre, size, yaw = _openpcdet_box(line, calib)
            # The exact transform and the approximation differ by the tiny R0/Tr tilt.
            assert box.center == pytest.approx(centre, abs=0.05)
            assert box.size == pytest.approx(size)
            assert math.remainder(box.yaw - yaw, 2 * math.pi) == pytest.approx(0, abs=0.02)


def test_ground_truth_boxes_hold_lidar_points(shared_data):
    # A physical check of the conversion: near objects are hit by many laser returns.
    for number in ("000000", "000001", "000003"):
        xyz = read_bin(shared_data / TRAINING / "velodyne" / f"{number}.bin").xyz
        for box in read_kitti_labels(*_frame(shared_data, number)):
            if math.hypot(*box.center[:2]) < 50:
                assert np.count_nonzero(_inside(box, xyz)) >= 10, (number, box)


def test_pointpillars_validation_labels(shared_data):
    folder = shared_data / "kitti_pointpillars_demo/val"
    objects = read_kitti_objects(folder / "000134_gt.txt", folder / "000134.txt")
    text = (folder / "000134_gt.txt").read_text().splitlines()
    assert len(objects) == sum(1 for line in text if not line.startswith("DontCare"))
    assert {o.type for o in objects} <= {"Car", "Cyclist", "Pedestrian"}
    xyz = read_bin(folder / "000134.bin").xyz
    visible = [o.box for o in objects if o.occluded == 0 and o.truncated == 0]
    assert len(visible) >= 5
    assert all(np.count_nonzero(_inside(box, xyz)) >= 30 for box in visible)


def test_detections_carry_a_score(tmp_path, shared_data):
    label = tmp_path / "det.txt"
    label.write_text("Car 0 0 -1.3 1 2 3 4 1.5 1.8 3.7 -3.3 1.5 12.7 -1.57 0.93\n")
    (box,) = read_kitti_labels(label, _frame(shared_data, "000000")[1])
    assert box.score == pytest.approx(0.93) and box.label == "car"


def test_class_mapping_is_complete():
    assert KITTI_LABELS["Van"] == "car" and KITTI_LABELS["Person_sitting"] == "pedestrian"
    assert set(KITTI_LABELS.values()) == {"car", "pedestrian", "cyclist", "unknown"}


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("Car 0 0\n", "line 1 has 3 values, expected 15 or 16"),
        ("Bus 0 0 0 1 2 3 4 1 1 1 0 0 5 0\n", "unknown KITTI type 'Bus'"),
        ("Car 0 0 0 1 2 3 4 1 x 1 0 0 5 0\n", "line 1: non-numeric value"),
        ("Car 0 0 0 1 2 3 4 1 0 1 0 0 5 0\n", "box size h=1.0 w=0.0"),
        ("Car 0 0 0 1 2 3 4 1 nan 1 0 0 5 0\n", "non-finite"),
        ("\n\nDontCare -1 -1 -10 1 2 3 4 -1 -1 -1 -1000 -1000 -1000 -10\n", None),
    ],
)
def test_bad_labels(tmp_path, shared_data, content, message):
    label = tmp_path / "label.txt"
    label.write_text(content)
    calib = _frame(shared_data, "000000")[1]
    if message is None:
        assert read_kitti_labels(label, calib) == []
        return
    with pytest.raises(DataError, match=message) as error:
        read_kitti_labels(label, calib)
    assert str(label) in str(error.value)


def test_dont_care_regions_of_a_training_frame(shared_data):
    regions = read_kitti_dont_care(*_frame(shared_data, "000001"))
    assert len(regions.regions) == 4
    assert regions.regions[0] == (503.89, 169.71, 590.61, 190.13)
    # A car 62 m ahead, 4.4 m to the left (the road rising 1 m), projects into the first
    # (widest) region;
    # the same car 20 m to the right, or near, does not.
    far = Box((62.0, 4.4, -0.4), (4.0, 1.8, 1.5), 0.0, "car")
    left, top, right, bottom = regions.image_rectangle(far)
    assert 503.89 < (left + right) / 2 < 590.61 and 169.71 < (top + bottom) / 2 < 190.13
    assert regions.covers(far)
    assert not regions.covers(Box((62.0, -20.0, -0.9), (4.0, 1.8, 1.5), 0.0, "car"))
    assert not regions.covers(Box((12.0, 4.4, -0.9), (4.0, 1.8, 1.5), 0.0, "car"))
    assert read_kitti_dont_care(*_frame(shared_data, "000000")).regions == ()


def test_dont_care_cover_is_the_share_of_the_detection_inside():
    calib = sensor_calibration()
    box = Box((20.0, 0.0, 0.0), (2.0, 2.0, 2.0), 0.0, "car")
    left, top, right, bottom = KittiDontCare((), calib).image_rectangle(box)
    middle = (left + right) / 2
    # A region over the left 60 % of the box's image covers it; over 40 % it does not.
    for share, covered in ((0.6, True), (0.4, False)):
        edge = left + share * (right - left)
        assert KittiDontCare(((left - 5, top - 5, edge, bottom + 5),), calib).covers(box) is covered
    assert not KittiDontCare(((middle, top, right, bottom),), calib).covers(box, share=0.6)
    behind = Box((-20.0, 0.0, 0.0), (2.0, 2.0, 2.0), 0.0, "car")
    assert KittiDontCare(((0, 0, 2000, 2000),), calib).image_rectangle(behind) is None
    assert not KittiDontCare(((0, 0, 2000, 2000),), calib).covers(behind)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("DontCare -1 -1 -10 1 2\n", "line 1: DontCare has no 2-D box"),
        ("\nDontCare -1 -1 -10 9 2 3 4 -1 -1 -1 -1000 -1000 -1000 -10\n", "line 2: DontCare box"),
        ("DontCare -1 -1 -10 1 2 x 4 -1 -1 -1 -1000 -1000 -1000 -10\n", "non-numeric"),
    ],
)
def test_bad_dont_care_lines(tmp_path, shared_data, content, message):
    label = tmp_path / "label.txt"
    label.write_text(content)
    with pytest.raises(DataError, match=message) as error:
        read_kitti_dont_care(label, _frame(shared_data, "000000")[1])
    assert str(label) in str(error.value)


def test_bad_calibrations(tmp_path, shared_data):
    with pytest.raises(DataError, match=r"no P2 matrix \(keys present: \['721.5377'\]\)"):
        read_kitti_calibration(shared_data / "mmdet3d_demo/kitti/000008.txt")
    good = _frame(shared_data, "000001")[1].read_text()
    cases = [
        (good.replace("R0_rect: 9.999239000000e-01 ", "R0_rect: "), "R0_rect has 8 numbers"),
        (good.replace("Tr_velo_to_cam", "Tr_velo_to_imu"), "no Tr_velo_to_cam"),
        (good.replace("P2: 7.2", "P2: x7.2"), "non-numeric"),
        (
            "R0_rect: 0 0 0 0 0 0 0 0 0\n" + good.split("R0_rect")[0]
            + "Tr_velo_to_cam: 1 0 0 0 0 1 0 0 0 0 1 0\n",
            "R0_rect is singular",
        ),
    ]  # fmt: skip
    for text, message in cases:
        path = tmp_path / "calib.txt"
        path.write_text(text)
        with pytest.raises(DataError, match=message):
            read_kitti_calibration(path)
    path.write_bytes(b"\xff\xfe")
    with pytest.raises(DataError, match="not text"):
        read_kitti_calibration(path)
    with pytest.raises(DataError, match="cannot read calibration"):
        read_kitti_calibration(tmp_path / "none.txt")


def test_tracking_style_calibration_without_colons(tmp_path, shared_data):
    good = _frame(shared_data, "000001")[1].read_text()
    tracking = good.replace("R0_rect:", "R_rect").replace("Tr_velo_to_cam:", "Tr_velo_cam")
    path = tmp_path / "calib.txt"
    path.write_text(tracking)
    assert np.array_equal(
        read_kitti_calibration(path).Tr_velo_to_cam,
        read_kitti_calibration(_frame(shared_data, "000001")[1]).Tr_velo_to_cam,
    )


# -- Apollo -----------------------------------------------------------------------------------


def test_apollo_poly(shared_data):
    polygons = read_apollo_poly(shared_data / "apollo/hdmap_roi_filter/poly_mask_ut.poly")
    assert [p.shape for p in polygons] == [(100, 3), (61, 3)]
    xy = np.concatenate(polygons)[:, :2]
    assert xy[:, 0].min() == pytest.approx(-58, abs=1.5) and xy[:, 0].max() == pytest.approx(
        75, abs=1.5
    )
    assert xy[:, 1].min() == pytest.approx(-51, abs=1.5) and xy[:, 1].max() == pytest.approx(
        85, abs=1.5
    )
    assert polygons[0][0].tolist() == [-56.797295, 21.719618, -35.257153]


def test_apollo_roi_points(shared_data):
    path = shared_data / "apollo/hdmap_roi_filter/poly_mask_ut_pcd_first676.txt"
    with pytest.raises(
        DataError, match="declares 10000 points but holds 676; pass allow_truncated"
    ):
        read_apollo_roi_points(path)
    xy, labels = read_apollo_roi_points(path, allow_truncated=True)
    assert xy.shape == (676, 2) and labels.dtype == np.int8
    assert np.count_nonzero(labels == 1) == 86 and set(labels.tolist()) == {-1, 1}
    assert xy[0].tolist() == [83.926048, 96.889954]


def test_apollo_clusters(shared_data):
    path = shared_data / "apollo/min_box_object_builder/QB9178_3_1461381834_1461382134_30651.pcd"
    clusters = read_apollo_clusters(path)
    assert [len(c) for c in clusters] == [3, 76, 4, 7, 11]
    assert clusters[0].points[0].tolist() == pytest.approx([14.1913, -63.8893, 1.10654, 195])
    intensities = np.concatenate([c.intensity for c in clusters])
    assert intensities.min() >= 0 and intensities.max() == 255


def test_apollo_poses(shared_data):
    pose = read_apollo_pose(shared_data / "apollo/poses/000012.pose")
    assert pose.frame_id == 12 and pose.timestamp == 1505524892.3845
    assert pose.translation.tolist() == [427609.69918917, 4437469.1163239, 37.586158139651]
    matrix = pose.matrix()
    assert np.allclose(matrix[:3, :3] @ matrix[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(matrix[:3, :3]) == pytest.approx(1)
    for name in (
        "ARZ034_12_1493073496_1493073796_2330.pose",
        "QN68P2_12_1476265365_1476265665_2.pose",
    ):
        other = read_apollo_pose(shared_data / "apollo/poses" / name)
        # Heading of the sensor's x axis: a yaw, roll and pitch near 0 (a car on a road).
        assert abs(other.matrix()[2, 2]) == pytest.approx(1, abs=0.01)
    assert read_apollo_pose(shared_data / "apollo/poses" / name).frame_id == 11989


@pytest.mark.parametrize(
    ("reader", "content", "message"),
    [
        (read_apollo_poly, "", "empty polygon file"),
        (read_apollo_poly, "2\n3\n0 0 0\n1 0 0\n0 1 0\n", "declares 2 polygons but ends after 1"),
        (read_apollo_poly, "1\n4\n0 0 0\n1 0 0\n", "declares 4 vertices but the file ends after 2"),
        (read_apollo_poly, "1\n2\n0 0\n1 0\n", "polygon 0 has 2 vertices"),
        (read_apollo_poly, "1\n3\n0 0 0\n1 0\n0 1 0\n", "line 4: vertex of polygon 0 has 2 values"),
        (read_apollo_poly, "1\n3\n0 0\n1 0\n0 1\n9\n", r"1 unexpected line\(s\)"),
        (read_apollo_poly, "1.5\n", "expected the polygon count"),
        (read_apollo_poly, "99999999999\n", "declares 99999999999 polygons but ends after 0"),
        (read_apollo_poly, "1\n3\n0 0\n1 0\n0 inf\n", "non-finite"),
        (read_apollo_roi_points, "2\n1 2 1\n", "declares 2 points but holds 1"),
        (read_apollo_roi_points, "1\n1 2 1\n3 4 -1\n", "declares 1 points but holds 2"),
        (read_apollo_roi_points, "1\n1 2 0\n", "label '0' is not"),
        (read_apollo_roi_points, "1\n1 2\n", "2 values, expected x y label"),
        (read_apollo_clusters, "2 1 2 3 4\n", "declares 2 points .* holds 4 values"),
        (read_apollo_clusters, "1 1 2 3 x\n", "non-numeric"),
        (read_apollo_clusters, "-1 1 2 3 4\n", "expected the point count"),
        (read_apollo_pose, "1 2 3\n", "got 3 values"),
        (read_apollo_pose, "1 2 3 4 5 0 0 0 2\n", "norm 2.000000, not 1"),
        (read_apollo_pose, "a 2 3 4 5 0 0 0 1\n", "expected the frame id"),
    ],
)
def test_bad_apollo_files(tmp_path, reader, content, message):
    path = tmp_path / "bad.txt"
    path.write_text(content)
    with pytest.raises(DataError, match=message) as error:
        reader(path)
    assert str(error.value).startswith(str(path))


def test_apollo_readers_refuse_binary_and_missing_files(tmp_path):
    binary = tmp_path / "x.poly"
    binary.write_bytes(b"\x00\xff\xfe")
    for reader in (
        read_apollo_poly,
        read_apollo_roi_points,
        read_apollo_clusters,
        read_apollo_pose,
    ):
        with pytest.raises(DataError, match="not text"):
            reader(binary)
        with pytest.raises(DataError, match="cannot read"):
            reader(tmp_path / "missing")
