"""The bird's-eye PNG shows what it should: read the pixels back where things were drawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.roi import ROI

matplotlib = pytest.importorskip("matplotlib")
from matplotlib.colors import to_rgb  # noqa: E402
from matplotlib.image import imread  # noqa: E402

from pytest_metamorphic.reports.birdseye import COLORS, draw_birdseye  # noqa: E402

ROAD = ROI.from_polygons([[(-10.0, -5.0), (50.0, -5.0), (50.0, 5.0), (-10.0, 5.0)]])
CAR = Box((20.0, 1.0, -0.9), (4.2, 1.8, 1.5), 0.3, "car")
WALKER = Box((8.0, -2.0, -0.8), (0.6, 0.6, 1.7), 0.0, "pedestrian")
MINIMAL = np.array([[30.0, 25.0, -1.5, 0.2], [-20.0, -30.0, -1.6, 0.4]], dtype=np.float32)


def frame() -> Frame:
    rng = np.random.default_rng(0)
    ground = np.column_stack(
        [rng.uniform(-40, 60, 4000), rng.uniform(-40, 40, 4000), np.full(4000, -1.7)]
    )
    car = np.column_stack(
        [rng.uniform(18.5, 21.5, 300), rng.uniform(0.4, 1.6, 300), rng.uniform(-1.6, -0.2, 300)]
    )
    return Frame(PointCloud(np.concatenate([ground, car])), roi=ROAD)


def rgb(image: np.ndarray, pixel: tuple[float, float]) -> np.ndarray:
    column, row = (round(v) for v in pixel)
    return image[row, column, :3]


def near(color: np.ndarray, name: str, tolerance: float = 0.12) -> bool:
    return bool(np.abs(color - np.array(to_rgb(COLORS[name]))).max() <= tolerance)


def draw(tmp_path: Path, **overrides) -> tuple[object, np.ndarray]:
    options = {
        "source": frame(),
        "source_boxes": [CAR, WALKER],
        "followup_boxes": [WALKER],
        "hidden": [CAR],
        "injected": np.concatenate([MINIMAL, [[0.0, 30.0, -1.0, 0.1]]]),
        "minimal": MINIMAL,
        "title": "MR1 violated: car hidden",
    }
    options.update(overrides)
    picture = draw_birdseye(tmp_path / "view.png", **options)
    return picture, imread(picture.path)


def test_hidden_obstacle_minimal_points_and_sensor_are_where_they_belong(tmp_path: Path) -> None:
    picture, image = draw(tmp_path)
    assert image.shape[1::-1] == picture.size and picture.size == (1600, 850)
    (hidden,) = picture.hidden
    red = rgb(image, hidden)
    # Filled translucent red over the car's dark-red points: red dominates.
    assert red[0] > 0.35 and red[0] > 1.5 * red[1] and red[0] > 1.5 * red[2]
    assert len(picture.minimal) == 2
    for pixel in picture.minimal:
        assert near(rgb(image, pixel), "minimal")
    assert rgb(image, picture.sensor).max() < 0.2  # the black sensor marker
    # The ROI is drawn (its fill covers a visible share of the picture).
    roi = np.abs(image[:, :, :3] - np.array(to_rgb(COLORS["roi"]))).max(axis=2) < 0.03
    assert roi.mean() > 0.05


def test_without_hidden_obstacles_or_minimal_points_nothing_is_highlighted(
    tmp_path: Path,
) -> None:
    highlighted, _ = draw(tmp_path)
    picture, image = draw(tmp_path, hidden=[], minimal=None, followup_boxes=[CAR, WALKER])
    assert picture.hidden == [] and picture.minimal == []
    # The same places, drawn without highlights: no red, no magenta there.
    for pixel in highlighted.minimal:
        assert not near(rgb(image, pixel), "minimal")
    red_pixels = np.all(np.abs(image[:, :, :3] - to_rgb(COLORS["hidden"])) < 0.1, axis=2)
    assert not red_pixels.any()


def test_close_up_frames_the_hidden_obstacle(tmp_path: Path) -> None:
    picture, _ = draw(tmp_path)
    width, height = picture.size
    column, row = picture.hidden[0]
    # The close-up is the right panel; the obstacle sits in its middle.
    assert width * 0.55 < column < width * 0.98 and height * 0.2 < row < height * 0.9


def test_bad_point_arrays_are_named(tmp_path: Path) -> None:
    with pytest.raises(InvalidArgument, match="minimal must have shape"):
        draw(tmp_path, minimal=np.zeros(3))


def test_obstacles_outside_the_scope_are_hatched_grey_and_named_in_the_legend(
    tmp_path: Path,
) -> None:
    outside = Box((20.0, 20.0, -0.9), (6.0, 4.0, 1.5), 0.0, "unknown")
    picture, image = draw(
        tmp_path, source_boxes=[CAR, WALKER, outside], unjudged=[outside], scope="wholly in ROI"
    )
    (pixel,) = picture.unjudged
    around = [
        rgb(image, (pixel[0] + dx, pixel[1] + dy)) for dx in range(-4, 5) for dy in (-3, 0, 3)
    ]
    grey = [color for color in around if np.ptp(color) < 0.08 and color.max() < 0.93]
    assert len(grey) >= 10  # the hatched grey fill, not the white background
    bare, plain = draw(tmp_path, source_boxes=[CAR, WALKER, outside])
    assert not bare.unjudged
    assert np.abs(plain.astype(float) - image.astype(float)).sum() > 0


def test_the_close_up_shows_the_minimal_points_when_nothing_was_hidden() -> None:
    # An inserted object not detected 46 m away hides no source obstacle: the close-up
    # must show its returns, not the near obstacles.
    from pytest_metamorphic.reports.birdseye import _zoom_limits

    near = [Box((8.0, 2.0, -1.0), (4.0, 1.8, 1.5), 0.0, "car")]
    inserted = np.array([[-2.3, -45.2], [-2.0, -46.6], [-3.3, -44.9]])
    x0, x1, y0, y1 = _zoom_limits([], inserted, near)
    assert x0 < -2.3 < x1 and y0 < -46.6 < y1 and y1 < 0  # around it, the near car outside
    x0, x1, y0, y1 = _zoom_limits(near, inserted, near)  # hidden obstacles come first
    assert x0 < 8.0 < x1 and y0 < 2.0 < y1
