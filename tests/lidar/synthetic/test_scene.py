"""HDL-64E layout and the synthetic scene renderer: determinism, geometry, engines, meshes."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E, HDL64E_ELEVATIONS, BeamLayout
from pytest_metamorphic.lidar.model.obstacles import SIZE_PRIORS, Box
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic import (
    BACKGROUND_INSTANCE,
    GROUND_INSTANCE,
    BackgroundObject,
    MeshShape,
    Obstacle,
    Scene,
    cast_rays,
    default_engine,
    render,
    scene_mesh,
)

HEIGHT = 1.73
ROAD = ROI.from_polygons([[[-110, -7], [110, -7], [110, 7], [-110, 7]]])
FRONT = (-math.pi / 4, math.pi / 4)  # a quarter sweep keeps tests fast
needs_embree = pytest.mark.skipif(default_engine() != "embree", reason="embreex not installed")


def _on_ground(x, y, label, yaw=0.0, size=None):
    size = size or SIZE_PRIORS[label].mean
    return Obstacle(Box((x, y, -HEIGHT + size[2] / 2), size, yaw, label))


SCENE = Scene(
    roi=ROAD,
    obstacles=(
        _on_ground(12, 2, "car", 0.2),
        _on_ground(9, -3, "pedestrian"),
        _on_ground(20, -1, "cyclist", 1.0),
        _on_ground(7, 4, "unknown"),
    ),
    background=(
        BackgroundObject("building", (25, 22), (14, 10, 8), yaw=0.3),
        BackgroundObject("pole", (15, -9), (0.3, 0.3, 6)),
        BackgroundObject("tree", (30, -14), (4, 4, 7)),
    ),
    name="street",
)


def test_hdl64e_layout_is_the_real_calibration():
    assert HDL64E.lasers == 64
    upper, lower = np.degrees(HDL64E_ELEVATIONS[:32]), np.degrees(HDL64E_ELEVATIONS[32:])
    assert upper.max() == pytest.approx(1.96, abs=0.01)
    assert upper.min() == pytest.approx(-8.56, abs=0.01)
    assert lower.max() == pytest.approx(-8.77, abs=0.01)
    assert lower.min() == pytest.approx(-24.56, abs=0.01)
    # Non-uniform: the upper block is about 0.34 degrees apart, the lower about 0.5.
    assert np.diff(np.sort(upper)).mean() == pytest.approx(0.34, abs=0.02)
    assert np.diff(np.sort(lower)).mean() == pytest.approx(0.51, abs=0.02)
    assert math.degrees(HDL64E.azimuth_step) == pytest.approx(0.1728, abs=1e-4)
    assert HDL64E.max_range == 120.0
    rays = HDL64E.rays()
    assert len(rays) == 64 * 2083
    assert np.allclose(np.linalg.norm(rays.directions, axis=1), 1.0)
    # Ring 0 is the lowest beam, ring 63 the highest.
    assert rays.directions[rays.ring == 0, 2].max() < rays.directions[rays.ring == 63, 2].min()
    assert sorted(np.unique(rays.ring)) == list(range(64))
    front = HDL64E.rays(azimuth_range=FRONT)
    assert len(front) == 64 * 521


def test_beam_layout_validation():
    with pytest.raises(InvalidArgument, match="azimuth_offsets"):
        BeamLayout("x", elevations=[0.0, 0.1], azimuth_offsets=[0.0])
    with pytest.raises(InvalidArgument, match="firings_per_revolution"):
        BeamLayout("x", elevations=[0.0], azimuth_offsets=[0.0], firings_per_revolution=0)
    with pytest.raises(InvalidArgument, match="min_range"):
        BeamLayout("x", elevations=[0.0], azimuth_offsets=[0.0], min_range=5, max_range=1)
    with pytest.raises(InvalidArgument, match="azimuth_range"):
        HDL64E.rays(azimuth_range=(1.0, 0.5))


@pytest.fixture(scope="module")
def street() -> Frame:
    return render(SCENE, seed=3)


def test_render_is_a_kitti_like_frame_with_ground_truth(street):
    cloud = street.cloud
    assert isinstance(street, Frame)
    assert 95_000 < len(cloud) < 135_000  # KITTI: ~120k points per sweep
    assert street.roi is ROAD
    assert street.source == "synthetic:street"
    assert cloud.fields["ring"].dtype == np.uint8
    instance = cloud.fields["instance"]
    assert [box.points for box in street.boxes] == [
        int(np.count_nonzero(instance == i)) for i in range(4)
    ]
    assert all(box.points > 20 for box in street.boxes)
    assert street.boxes[0] == SCENE.obstacles[0].box  # points is not compared
    assert (instance == BACKGROUND_INSTANCE).sum() > 500
    rng = np.linalg.norm(cloud.xyz, axis=1)
    assert rng.max() <= 120.0
    assert rng.min() >= 0.9
    assert cloud.intensity.min() >= 0.0
    assert cloud.intensity.max() <= 0.6
    assert cloud.intensity[instance == GROUND_INSTANCE].max() <= 0.12


def test_render_is_deterministic_and_seeded(street):
    again = render(SCENE, seed=3)
    assert again.cloud.equals(street.cloud)
    other = render(SCENE, seed=4)
    assert not other.cloud.equals(street.cloud)
    # The seed only moves points along their rays (range noise of 2 cm).
    assert abs(len(other.cloud) - len(street.cloud)) < 50


def test_points_lie_on_their_objects(street):
    cloud = street.cloud
    instance = cloud.fields["instance"]
    for index, box in enumerate(street.boxes):
        grown = Box(box.center, tuple(s + 0.2 for s in box.size), box.yaw)  # 2 cm noise
        assert grown.contains(cloud.points[instance == index]).all()
    ground = cloud.points[instance == GROUND_INSTANCE]
    assert np.abs(ground[:, 2] + HEIGHT).max() < 0.1
    # Obstacles are in the ROI, background objects outside it.
    assert ROAD.contains(cloud.points[instance >= 0]).mean() > 0.95
    assert not ROAD.contains(cloud.points[instance == BACKGROUND_INSTANCE]).any()


def test_noiseless_points_are_exactly_on_the_mesh_triangles():
    frame = render(SCENE, range_noise=0.0, azimuth_range=FRONT)
    mesh = scene_mesh(SCENE, ground_extent=130.0)
    rays = HDL64E.rays(azimuth_range=FRONT)
    ray, face, distance = cast_rays(mesh, rays.directions, max_distance=121.0)
    keep = (distance >= HDL64E.min_range) & (distance <= HDL64E.max_range)
    ray, face = ray[keep], face[keep]
    points = frame.cloud.xyz.astype(np.float64)
    assert len(points) == len(ray)
    triangles = mesh.vertices[mesh.faces[face]]
    closest = trimesh.triangles.closest_point(triangles, points)
    assert np.linalg.norm(closest - points, axis=1).max() < 1e-4  # float32 rounding
    assert np.array_equal(frame.cloud.fields["instance"], mesh.face_instance[face])


def test_occlusion_hides_what_is_behind():
    # A van taller than the sensor hides a pedestrian behind it (over a car roof the
    # pedestrian's head would still show, as it does in real scans).
    front = _on_ground(10, 0, "unknown", size=(4, 2, 2.4))
    hidden = _on_ground(20, 0, "pedestrian")
    alone = render(Scene(obstacles=(hidden,)), azimuth_range=FRONT)
    both = render(Scene(obstacles=(front, hidden)), azimuth_range=FRONT)
    assert alone.boxes[0].points > 30
    assert both.boxes[1].points == 0
    # The car's shadow on the ground is empty too.
    xyz = both.cloud.xyz
    shadow = (xyz[:, 0] > 13) & (xyz[:, 0] < 18) & (np.abs(xyz[:, 1]) < 0.5)
    assert not shadow.any()


def test_numpy_engine_matches_embree():
    mesh = scene_mesh(SCENE)
    directions = HDL64E.rays(azimuth_range=(0.0, 0.6)).directions
    numpy_hits = cast_rays(mesh, directions, max_distance=121.0, engine="numpy")
    assert len(numpy_hits[0]) > 5000
    if default_engine() != "embree":
        pytest.skip("embreex not installed: nothing to compare against")
    embree_hits = cast_rays(mesh, directions, max_distance=121.0, engine="embree")
    assert np.array_equal(numpy_hits[0], embree_hits[0])
    assert np.allclose(numpy_hits[2], embree_hits[2], atol=1e-6)
    # Only rays through shared triangle edges may report the neighbouring triangle.
    assert np.mean(numpy_hits[1] != embree_hits[1]) < 1e-3


def test_render_through_numpy_engine_equals_auto():
    scene = Scene(obstacles=(_on_ground(8, 1, "car"),))
    a = render(scene, azimuth_range=(-0.3, 0.3), engine="numpy")
    b = render(scene, azimuth_range=(-0.3, 0.3))
    assert len(a.cloud) == len(b.cloud)
    assert np.allclose(a.cloud.points, b.cloud.points, atol=1e-4)


def test_cast_rays_without_hits_and_bad_engine():
    empty = scene_mesh(Scene(ground=False))
    hit = cast_rays(empty, np.array([[1.0, 0, 0]]))
    assert all(len(part) == 0 for part in hit)
    with pytest.raises(InvalidArgument, match="engine"):
        cast_rays(scene_mesh(SCENE), np.array([[1.0, 0, 0]]), engine="optix")
    # Straight up from the sensor hits nothing; straight down hits the ground.
    ray, _, distance = cast_rays(scene_mesh(Scene()), np.array([[0, 0, 1.0], [0, 0, -1.0]]))
    assert ray.tolist() == [1]
    assert distance[0] == pytest.approx(HEIGHT)


def test_user_mesh_from_file_fills_the_box(tmp_path):
    path = tmp_path / "barrel.stl"
    trimesh.creation.cylinder(radius=3.0, height=10.0, sections=12).export(path)
    shape = MeshShape.from_file(path)
    assert shape.name == "barrel"
    box = Box((10, -2, -HEIGHT + 0.5), (0.6, 0.6, 1.0), label="unknown")
    frame = render(Scene(obstacles=(Obstacle(box, shape=shape),)), azimuth_range=FRONT)
    points = frame.cloud.points[frame.cloud.fields["instance"] == 0]
    assert len(points) > 30
    grown = Box(box.center, (0.7, 0.7, 1.1))
    assert grown.contains(points).all()
    # A round barrel: points hug the cylinder's surface.
    radial = np.hypot(points[:, 0] - 10, points[:, 1] + 2)
    assert ((radial > 0.2) & (radial < 0.32)).mean() > 0.9
    assert shape == MeshShape.from_file(path)
    assert Obstacle(box, shape=shape).describe().endswith("(barrel)")


def test_bad_mesh_files_name_the_file(tmp_path):
    with pytest.raises(DataError, match="no such mesh file"):
        MeshShape.from_file(tmp_path / "missing.obj")
    junk = tmp_path / "junk.obj"
    junk.write_text("this is not a mesh\n")
    with pytest.raises(DataError, match=r"junk\.obj"):
        MeshShape.from_file(junk)
    with pytest.raises(DataError, match="flat"):
        MeshShape.from_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(DataError, match="faces index"):
        MeshShape.from_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 1]], [[0, 1, 5]])


def test_scene_validation():
    box = Box((5, 0, -1), (1, 1, 1))
    with pytest.raises(InvalidArgument, match="sensor_height"):
        Scene(sensor_height=-1)
    with pytest.raises(InvalidArgument, match=r"obstacles\[0\] is Box"):
        Scene(obstacles=(box,))
    with pytest.raises(InvalidArgument, match="shape"):
        Obstacle(box, shape="spaceship")
    with pytest.raises(InvalidArgument, match="reflectivity"):
        Obstacle(box, reflectivity=2)
    with pytest.raises(InvalidArgument, match="kind"):
        BackgroundObject("volcano", (0, 0), (1, 1, 1))
    with pytest.raises(InvalidArgument, match="seed"):
        render(Scene(), seed=-1)
    with pytest.raises(InvalidArgument, match="scene"):
        render("street")
    assert "car at (12.0, 2.0)" in SCENE.describe()
    assert SCENE.boxes[1].label == "pedestrian"


def test_reflectivity_and_incidence_drive_intensity():
    bright = Obstacle(Box((10, 0, -HEIGHT + 1), (1, 4, 2)), reflectivity=1.0)
    dark = Obstacle(Box((10, 0, -HEIGHT + 1), (1, 4, 2)), reflectivity=0.2)
    a = render(Scene(obstacles=(bright,), ground=False), azimuth_range=(-0.2, 0.2), seed=1)
    b = render(Scene(obstacles=(dark,), ground=False), azimuth_range=(-0.2, 0.2), seed=1)
    assert np.allclose(a.cloud.intensity * 0.2, b.cloud.intensity, atol=1e-6)
    # A wall facing the sensor: intensity falls with the angle of incidence.
    xyz = a.cloud.xyz
    cos_incidence = xyz[:, 0] / np.linalg.norm(xyz, axis=1)
    assert np.allclose(a.cloud.intensity, cos_incidence, atol=2e-3)
