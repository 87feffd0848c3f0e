"""Built-in objects to insert: rendered road users of every size class, and real class sizes.

A recording's own labels give templates of what drove by that day: KITTI's six sweeps hold
cars, a few pedestrians and one cyclist, and no bus. :func:`road_user_templates` renders
the sizes a perception stack must also handle (semLidarFuzz's and MultiTest's point: a
detector tuned on cars meets vans, lorries, buses, articulated trailers, children) on an
empty road with an HDL-64E and cuts them as templates (a row of parked cars as one
object too: a wall of cars a detector may merge into one cluster); insertion re-casts them
for each target frame's sensor, like any other template. An adult, a cyclist and a car
stand 4-7 m from the sensor: a template is placed at 80-150 % of the range it was seen
from, and a VLP-16 in a yard or an Ouster in a hall sees ground only that far.
:data:`CLASS_SIZES` bounds scaling
(:meth:`~pytest_metamorphic.lidar.followups.insert.ObjectTemplate.scaled`) to real sizes.
"""

from __future__ import annotations

import dataclasses
import functools
import math

from pytest_metamorphic.lidar.followups.insert.template import ObjectTemplate, object_templates
from pytest_metamorphic.lidar.model.obstacles import Box, Label
from pytest_metamorphic.lidar.roi import ROI

__all__ = [
    "CLASS_SIZES",
    "ROAD_USERS",
    "SCALES",
    "fits_class",
    "road_user_templates",
    "solid_road_users",
]

SCALES = (1.0, 1.05, 0.95, 1.1, 0.9)
"""Scales an inserted object may take (semLidarFuzz scales vehicles by 105 %), first the
object as it is: shrinking goes there."""

CLASS_SIZES: dict[str, tuple[tuple[float, float], tuple[float, float], tuple[float, float]]] = {
    # (length, width, height) ranges in metres. "car" is KITTI's vehicle class: Car, Van,
    # Truck and Tram, from a small city car to an EU articulated lorry (18.75 m, 2.55 m
    # wide, 4 m high).
    "car": ((2.5, 18.75), (1.4, 2.6), (1.2, 4.2)),
    # Children to tall adults, with or without a bag.
    "pedestrian": ((0.2, 1.2), (0.2, 1.0), (1.0, 2.1)),
    # Bicycles and their riders, a child's to a cargo bike's.
    "cyclist": ((1.2, 2.6), (0.4, 1.0), (1.1, 2.1)),
}
"""Real sizes per class: a scaled template must stay within them."""

# Name, box (centre on flat ground 1.73 m below the sensor, size, heading), label, shape.
# Spread over the road so that none hides another from the sensor.
ROAD_USERS: tuple[tuple[str, tuple[float, float], tuple[float, float, float], float, str], ...] = (
    ("van", (14.0, 6.0), (5.2, 2.0, 2.3), 0.1, "car"),
    ("lorry", (22.0, -7.0), (8.5, 2.5, 3.5), -0.05, "car"),
    ("bus", (30.0, 8.0), (12.0, 2.55, 3.2), 0.0, "car"),
    ("articulated lorry", (36.0, -10.0), (16.5, 2.55, 4.0), 0.05, "car"),
    ("small car", (9.0, -4.0), (3.6, 1.6, 1.45), 0.4, "car"),
    ("child", (7.0, 3.0), (0.4, 0.35, 1.15), 0.0, "pedestrian"),
    # Close by, for sensors whose recordings see ground only a few metres out (a VLP-16
    # in a yard, an Ouster in a hall): a template is placed at 80-150 % of the range it
    # was seen from, so these fit where the others cannot.
    ("adult close by", (-3.0, -3.0), (0.6, 0.5, 1.75), 0.3, "pedestrian"),
    ("cyclist close by", (3.0, -5.5), (1.8, 0.6, 1.7), 0.2, "cyclist"),
    ("car close by", (1.0, 6.5), (4.3, 1.8, 1.5), 0.0, "car"),
)
# (and PARKED_ROW, below)
"""The rendered road users: name, (x, y), (length, width, height), heading, class."""

PARKED_ROW: tuple[tuple[float, float], float, int, tuple[float, float, float], float] = (
    (-16.0, 9.0),
    0.0,
    3,
    (4.2, 1.8, 1.5),
    1.0,
)
"""A row of parked cars, inserted as one object (a wall of cars a detector may merge,
and must not then drop): its centre (x, y), heading, how many cars, each car's size,
and the gap between bumpers (m)."""


def fits_class(size: tuple[float, float, float], label: Label) -> bool:
    """Whether a box of ``size`` is a real size for ``label`` (:data:`CLASS_SIZES`;
    ``unknown`` objects have no class size and always fit)."""
    bounds = CLASS_SIZES.get(label)
    if bounds is None:
        return True
    return all(low <= value <= high for value, (low, high) in zip(size, bounds, strict=True))


@functools.cache
def road_user_templates() -> tuple[ObjectTemplate, ...]:
    """Templates of :data:`ROAD_USERS`, rendered with the HDL-64E on an empty road (one
    sweep, seed 0; cut as any labelled object is, :func:`object_templates`), nearest
    first. Each keeps its name in its source (``road users#0 [bus]``)."""
    from pytest_metamorphic.lidar.synthetic import Obstacle, Scene, render

    ground = -1.73
    obstacles = [
        Obstacle(
            Box((x, y, ground + size[2] / 2), size, yaw, label),  # type: ignore[arg-type]
            shape="box" if size[0] > 6 else "auto",
        )
        for _, (x, y), size, yaw, label in ROAD_USERS
    ]
    row = _parked_row(ground)
    obstacles += [Obstacle(car) for car in row]
    road = ROI.from_polygons([[(-30.0, -20.0), (60.0, -20.0), (60.0, 20.0), (-30.0, 20.0)]])
    frame = render(Scene(roi=road, obstacles=tuple(obstacles), name="road users"))
    named = []
    for template in object_templates(frame, min_returns=30):
        x = template.range * math.cos(template.bearing)
        y = template.range * math.sin(template.bearing)
        name, where, *_ = min(ROAD_USERS, key=lambda user: math.dist(user[1], (x, y)))
        if math.dist(where, (x, y)) < 1.0:  # a road user, not a car of the parked row
            named.append(dataclasses.replace(template, source=f"road users#0 [{name}]"))
    # The row as one object: every return between its first bumper and its last.
    (x, y), yaw, count, size, gap = PARKED_ROW
    length = count * size[0] + (count - 1) * gap
    whole = Box((x, y, ground + size[2] / 2), (length, size[1], size[2]), yaw, "car")
    template = ObjectTemplate.from_frame(frame, whole)
    named.append(dataclasses.replace(template, source="road users#0 [row of parked cars]"))
    return tuple(sorted(named, key=lambda t: t.range))


@functools.cache
def solid_road_users() -> tuple[ObjectTemplate, ...]:
    """The road users of :data:`ROAD_USERS` as whole meshes (solid templates,
    :meth:`~pytest_metamorphic.lidar.followups.insert.ObjectTemplate.from_mesh`): what the
    near field needs. A recording's template holds the faces one sensor saw from several
    metres away; a metre or two from the car the sensor looks down onto its roof and
    shoulders, and beams would pass through the roof the template lacks to ground inside
    the object. Each keeps its name in its source (``rendered road users [bus]``)."""
    from pytest_metamorphic.lidar.synthetic import Obstacle
    from pytest_metamorphic.lidar.synthetic.meshes import obstacle_geometry

    templates = []
    for name, (x, y), size, _, label in ROAD_USERS:
        box = Box((0.0, 0.0, size[2] / 2), size, 0.0, label)  # type: ignore[arg-type]
        obstacle = Obstacle(box, shape="box" if size[0] > 6 else "auto")
        vertices, faces, reflectivity = obstacle_geometry(obstacle)
        templates.append(
            ObjectTemplate.from_mesh(
                vertices,
                faces,
                label=obstacle.label,
                reflectivity=reflectivity,
                source=f"rendered road users [{name}]",
                seen_range=math.hypot(x, y),
            )
        )
    return tuple(templates)


def _parked_row(ground: float) -> list[Box]:
    """The cars of :data:`PARKED_ROW`."""
    (x, y), yaw, count, size, gap = PARKED_ROW
    step = size[0] + gap
    first = -(count - 1) * step / 2
    c, s = math.cos(yaw), math.sin(yaw)
    return [
        Box(
            (x + (first + i * step) * c, y + (first + i * step) * s, ground + size[2] / 2),
            size,
            yaw,
            "car",
        )
        for i in range(count)
    ]
