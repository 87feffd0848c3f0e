"""Streets as a real sweep sees them: kerbs, pavements, parked rows, façades, fences, hedges.

:func:`~pytest_metamorphic.lidar.synthetic.layout.random_scene` keeps everything but the
road users off the road and far from it, which is what a relation's source scene needs
(nothing ambiguous near the ROI's edge). A network trained only on such scenes has never
seen a wall, a hedge or a row of parked cars, and on a real sweep it calls them cars.
:func:`street_scene` builds the clutter a real street has, from the parts the renderer
already knows (cuboids, poles, trees), laid out along a straight road or a crossroads:

* pavements: slabs 8-20 cm high beside the road, so the ground steps up at the kerb;
* parked rows: cars and vans along either kerb, nose to tail (vans are ``car``s, as
  Apollo has one VEHICLE type and :mod:`~pytest_metamorphic.lidar.io.kitti` reads KITTI's
  Van and Truck as ``car``);
* frontages: façades of buildings with gaps between them, fences and low walls (thin
  cuboids), hedges (clumps of small cuboids of varied height, as foliage returns come
  from several depths), trees and poles along the pavement, and sometimes nothing;
* loose wall pieces (``StreetOptions.loose_walls``, none by default): free-standing
  walls a car's length or so beyond the pavement;
* street furniture (``StreetOptions.furniture``, none by default): free-standing things
  up to a car's size that are not cars (cabinets, bins and skips, planters, benches,
  shrubs) on the pavement and beyond it;
* road users: cars, vans, cyclists and pedestrians on the road, pedestrians on the
  pavements (standing on them).

Everything is drawn from a seeded :class:`numpy.random.Generator`, so a scene is
reproducible from its seed. Road users never overlap each other or a clutter object
(their labels would be wrong); clutter may overlap clutter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import SIZE_PRIORS, Box, Label
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic.description import BackgroundObject, Obstacle, Scene

__all__ = ["StreetOptions", "street_scene"]

_VAN = ((4.6, 1.8, 1.9), (6.2, 2.2, 2.7))  # vans and small lorries, labelled car
_ROAD_LENGTH = 150.0  # metres each way from the sensor: past any grid's reach


@dataclass(frozen=True)
class StreetOptions:
    """How busy and how cluttered :func:`street_scene`'s streets are.

    Attributes
    ----------
    road_width : (float, float)
        Kerb to kerb, metres.
    junction : float
        Chance of a crossroads instead of a straight road.
    road_users : (int, int)
        Moving cars, cyclists and pedestrians, inclusive range.
    parked : float
        Chance that a kerb has a parked row.
    reach : float
        Clutter and road users are placed within this distance of the sensor (metres).
    loose_walls : float
        Mean number (Poisson) of free-standing wall pieces per kerb side: 2-7 m long,
        0.05-0.4 m thick, 0.4-2.2 m tall, 0.5-15 m beyond the pavement, along the road
        six times in ten and at any heading otherwise (garden walls, hoardings: hard
        negatives for a learned detector, which calls a piece of fence a car's length a
        car on real sweeps when it has not seen one).
    furniture : float
        Mean number (Poisson) of pieces of street furniture per kerb side, from the kerb to
        15 m beyond the pavement: boxes (cabinets, bins and skips, planters, benches) 0.4-3.5
        m long, 0.3-2.2 m wide and 0.3-2.2 m tall, at the road's heading or across it
        mostly, or shrubs (foliage clumps 1-3.5 m across). Hard negatives, as loose wall
        pieces are: things of a car's size or less that are not road users.
    """

    road_width: tuple[float, float] = (6.0, 16.0)
    junction: float = 0.25
    road_users: tuple[int, int] = (0, 10)
    parked: float = 0.6
    reach: float = 75.0
    loose_walls: float = 0.0
    furniture: float = 0.0

    def __post_init__(self) -> None:
        low, high = self.road_width
        if not 3.0 <= low <= high <= 40.0:
            raise InvalidArgument(f"road_width={self.road_width!r} must be 3 <= low <= high <= 40")
        if not (0.0 <= self.junction <= 1.0 and 0.0 <= self.parked <= 1.0):
            raise InvalidArgument("junction and parked are chances in [0, 1]")
        if not 0 <= self.road_users[0] <= self.road_users[1]:
            raise InvalidArgument(f"road_users={self.road_users!r} must be 0 <= low <= high")
        if not 10.0 <= self.reach <= 150.0:
            raise InvalidArgument(f"reach={self.reach!r} must be in [10, 150] m")
        for name in ("loose_walls", "furniture"):
            mean = getattr(self, name)
            if isinstance(mean, bool) or not isinstance(mean, int | float) or not 0 <= mean <= 50:
                raise InvalidArgument(f"{name}={mean!r} must be a number in [0, 50]")


@dataclass
class _Street:
    """What has been placed so far, in the sensor frame."""

    rng: np.random.Generator
    ground: float  # z of the road
    reach: float
    obstacles: list[Obstacle] = field(default_factory=list)
    background: list[BackgroundObject] = field(default_factory=list)
    taken: list[tuple[float, float, float]] = field(default_factory=list)  # x, y, radius
    roads: ROI | None = None  # clutter never stands on a road
    slabs: list[tuple[float, float, float, float, float]] = field(default_factory=list)

    def free(self, x: float, y: float, radius: float) -> bool:
        if math.hypot(x, y) < 3.5 + radius or math.hypot(x, y) > self.reach:
            return False  # the ego vehicle, or beyond the scene's reach
        return all(math.hypot(x - a, y - b) > radius + r for a, b, r in self.taken)

    def road_user(self, box: Box, *, reflectivity: float | None = None) -> bool:
        radius = math.hypot(box.size[0], box.size[1]) / 2.0
        if not self.free(box.center[0], box.center[1], radius):
            return False
        self.taken.append((box.center[0], box.center[1], radius))
        if reflectivity is None:
            reflectivity = float(self.rng.uniform(0.05, 0.9))
        self.obstacles.append(Obstacle(box, reflectivity=reflectivity))
        return True

    def clutter(self, kind: str, x: float, y: float, size: tuple[float, float, float],
                yaw: float = 0.0, *, solid: bool = True) -> None:  # fmt: skip
        if math.hypot(x, y) > self.reach + 20.0:
            return
        if self._touches(x, y, size, yaw) or self._on_road(x, y, size, yaw):
            return  # never over a road user, a pole or a tree, or across a road
        radius = math.hypot(size[0], size[1]) / 2.0
        self.background.append(BackgroundObject(kind, (x, y), size, yaw=yaw))  # type: ignore[arg-type]
        if solid and radius < 4.0:
            self.taken.append((x, y, radius))

    def pavement(self, x: float, y: float, size: tuple[float, float, float], yaw: float) -> bool:
        """A pavement slab, under road users if need be; False where it would cross a road."""
        if math.hypot(x, y) > self.reach + 20.0 or self._on_road(x, y, size, yaw):
            return False
        self.background.append(BackgroundObject("building", (x, y), size, yaw=yaw))
        self.slabs.append((x, y, size[0], size[1], yaw))
        return True

    def on_pavement(self, x: float, y: float) -> bool:
        """Whether a pavement slab lies under ``(x, y)``."""
        for a, b, length, width, yaw in self.slabs:
            c, s = math.cos(yaw), math.sin(yaw)
            along, across = c * (x - a) + s * (y - b), -s * (x - a) + c * (y - b)
            if abs(along) <= length / 2 and abs(across) <= width / 2:
                return True
        return False

    def _touches(self, x: float, y: float, size: tuple[float, float, float], yaw: float) -> bool:
        """Whether the footprint comes within any taken circle."""
        if not self.taken:
            return False
        taken = np.asarray(self.taken)
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = taken[:, 0] - x, taken[:, 1] - y
        along, across = np.abs(c * dx + s * dy), np.abs(-s * dx + c * dy)
        gap = np.hypot(np.maximum(along - size[0] / 2, 0), np.maximum(across - size[1] / 2, 0))
        return bool(np.any(gap < taken[:, 2]))

    def _on_road(self, x: float, y: float, size: tuple[float, float, float], yaw: float) -> bool:
        if self.roads is None:
            return False
        # Sample points of the footprint at most 1.5 m apart (the narrowest road is 3 m),
        # kept 5 cm inside its edges so a kerbside footprint does not count as on the road.
        along = np.linspace(-0.5, 0.5, max(math.ceil(size[0] / 1.5) + 1, 3))
        across = np.linspace(-0.5, 0.5, max(math.ceil(size[1] / 1.5) + 1, 3))
        inset = np.array([max(size[0] - 0.1, 0.0), max(size[1] - 0.1, 0.0)])
        a, b = np.meshgrid(along * inset[0], across * inset[1], indexing="ij")
        c, s = math.cos(yaw), math.sin(yaw)
        xy = np.stack([x + c * a.ravel() - s * b.ravel(), y + s * a.ravel() + c * b.ravel()], 1)
        return bool(np.any(self.roads.contains(xy, method="exact")))


def _to_sensor(
    u: float, v: float, origin: NDArray[np.float64], heading: float
) -> tuple[float, float]:
    c, s = math.cos(heading), math.sin(heading)
    return float(origin[0] + c * u - s * v), float(origin[1] + s * u + c * v)


def _size(rng: np.random.Generator, label: Label) -> tuple[float, float, float]:
    prior = SIZE_PRIORS[label]
    return tuple(float(rng.uniform(lo, hi)) for lo, hi in zip(prior.low, prior.high, strict=True))  # type: ignore[return-value]


def _vehicle(rng: np.random.Generator, van: float) -> tuple[float, float, float]:
    """A car's size, or with chance ``van`` a van's or small lorry's (both label ``car``)."""
    if rng.random() < van:
        low, high = _VAN
        return tuple(float(rng.uniform(a, b)) for a, b in zip(low, high, strict=True))  # type: ignore[return-value]
    return _size(rng, "car")


def _parked_row(street: _Street, origin: NDArray[np.float64], heading: float, side: float,
                half_width: float) -> None:  # fmt: skip
    rng = street.rng
    u = float(rng.uniform(-street.reach, -street.reach + 10.0))
    across = rng.random() < 0.15  # bays across the kerb
    while u < street.reach:
        size = _vehicle(rng, 0.15)
        length = size[1] if across else size[0]
        depth = size[0] if across else size[1]
        u += length / 2.0
        v = side * (half_width - depth / 2.0 - float(rng.uniform(0.1, 0.5)))
        if rng.random() < 0.8:
            x, y = _to_sensor(u, v, origin, heading)
            yaw = heading + (math.pi / 2 if across else 0.0) + float(rng.normal(0.0, 0.04))
            yaw += math.pi * float(rng.integers(2))
            box = Box((x, y, street.ground + size[2] / 2.0), size, yaw, "car")
            street.road_user(box)
        u += length / 2.0 + float(
            rng.uniform(0.4, 3.0) if rng.random() < 0.8 else rng.uniform(4, 15)
        )


def _frontage(street: _Street, origin: NDArray[np.float64], heading: float, side: float,
              edge: float) -> None:  # fmt: skip
    """Façades, fences, hedges or open ground from ``edge`` (metres from the axis) outward."""
    rng = street.rng
    kind = rng.choice(["facades", "fence", "hedge", "open"], p=[0.45, 0.2, 0.2, 0.15])
    setback = edge + float(rng.uniform(0.0, 6.0))
    u = -street.reach
    while u < street.reach:
        if kind == "facades":
            length, depth = float(rng.uniform(6, 40)), float(rng.uniform(6, 15))
            height = float(rng.uniform(3, 20))
            v = side * (setback + depth / 2.0 + float(rng.uniform(0, 1.5)))
            x, y = _to_sensor(u + length / 2.0, v, origin, heading)
            street.clutter("building", x, y, (length, depth, height), heading)
            u += length + (float(rng.uniform(2, 15)) if rng.random() < 0.4 else 0.0)
        elif kind == "fence":
            length = float(rng.uniform(5, 30))
            thick, height = float(rng.uniform(0.03, 0.3)), float(rng.uniform(0.5, 2.2))
            x, y = _to_sensor(u + length / 2.0, side * setback, origin, heading)
            street.clutter("building", x, y, (length, thick, height), heading)
            u += length + (float(rng.uniform(1, 6)) if rng.random() < 0.3 else 0.0)
        elif kind == "hedge":
            length = float(rng.uniform(4, 20))
            _hedge(street, origin, heading, u, length, side * (setback + 0.8), 1.6)
            u += length + (float(rng.uniform(1, 5)) if rng.random() < 0.4 else 0.0)
        else:  # open ground with a bush now and then
            u += float(rng.uniform(5, 25))
            if rng.random() < 0.5:
                _hedge(street, origin, heading, u, float(rng.uniform(1.5, 5)),
                       side * (setback + float(rng.uniform(1, 10))), 3.0)  # fmt: skip


def _loose_walls(street: _Street, origin: NDArray[np.float64], heading: float, side: float,
                 edge: float, mean: float) -> None:  # fmt: skip
    """Free-standing wall pieces a car's length or so (``StreetOptions.loose_walls``)."""
    if mean <= 0:
        return
    rng = street.rng
    for _ in range(int(rng.poisson(mean))):
        u = float(rng.uniform(-street.reach, street.reach))
        v = side * (edge + float(rng.uniform(0.5, 15.0)))
        x, y = _to_sensor(u, v, origin, heading)
        yaw = heading if rng.random() < 0.6 else float(rng.uniform(0, math.pi))
        size = (float(rng.uniform(2.0, 7.0)), float(rng.uniform(0.05, 0.4)),
                float(rng.uniform(0.4, 2.2)))  # fmt: skip
        street.clutter("building", x, y, size, yaw)


def _furniture(street: _Street, origin: NDArray[np.float64], heading: float, side: float,
               kerb: float, pavement: float, mean: float) -> None:  # fmt: skip
    """Street furniture from the kerb outward (``StreetOptions.furniture``)."""
    if mean <= 0:
        return
    rng = street.rng
    for _ in range(int(rng.poisson(mean))):
        u = float(rng.uniform(-street.reach, street.reach))
        v = side * (kerb + float(rng.uniform(0.3, pavement + 15.0)))
        if rng.random() < 0.3:  # a shrub
            across = float(rng.uniform(1.0, 3.5))
            _hedge(street, origin, heading, u - across / 2, across, v, across)
            continue
        x, y = _to_sensor(u, v, origin, heading)
        length = float(rng.uniform(0.4, 3.5))
        size = (length, float(rng.uniform(0.3, min(length, 2.2))), float(rng.uniform(0.3, 2.2)))
        yaw = heading + (math.pi / 2 if rng.random() < 0.3 else 0.0)
        if rng.random() < 0.3:
            yaw = float(rng.uniform(0, math.pi))
        street.clutter("building", x, y, size, yaw)


def _hedge(street: _Street, origin: NDArray[np.float64], heading: float, u: float, length: float,
           v: float, depth: float) -> None:  # fmt: skip
    """Foliage: clumps of small cuboids of varied height over a strip ``length`` long."""
    rng = street.rng
    height = float(rng.uniform(0.6, 2.5))
    clumps = max(int(length * depth * float(rng.uniform(2.0, 5.0))), 3)
    for _ in range(clumps):
        du, dv = float(rng.uniform(0, length)), float(rng.uniform(-depth / 2, depth / 2))
        x, y = _to_sensor(u + du, v + dv, origin, heading)
        side = float(rng.uniform(0.15, 0.6))
        tall = height * float(rng.uniform(0.5, 1.1))
        street.clutter("building", x, y, (side, side, tall), float(rng.uniform(0, math.pi)),
                       solid=False)  # fmt: skip


def _pavement_furniture(street: _Street, origin: NDArray[np.float64], heading: float,
                        side: float, v: float) -> None:  # fmt: skip
    rng = street.rng
    trees = rng.random() < 0.5
    u = -street.reach + float(rng.uniform(0, 10))
    while u < street.reach:
        x, y = _to_sensor(u, side * v, origin, heading)
        if trees:
            crown = float(rng.uniform(2, 7))
            street.clutter("tree", x, y, (crown, crown, float(rng.uniform(4, 12))))
            u += float(rng.uniform(5, 15))
        else:
            d = float(rng.uniform(0.1, 0.4))
            street.clutter("pole", x, y, (d, d, float(rng.uniform(2.5, 9))))
            u += float(rng.uniform(8, 40))


def _pavement(street: _Street, origin: NDArray[np.float64], heading: float, u: float, v: float,
              size: tuple[float, float]) -> None:  # fmt: skip
    """A 10 m pavement slab from ``u``, or where that would cross a road, 2 m pieces of it."""
    for length in (10.0, 2.0):
        pieces = [street.pavement(*_to_sensor(u + k + length / 2, v, origin, heading),
                                  (length, *size), heading)
                  for k in np.arange(0.0, 10.0, length)]  # fmt: skip
        if all(pieces) or length == 2.0:
            return


def _users(street: _Street, origin: NDArray[np.float64], heading: float, half_width: float,
           pavement: float, kerb: float, count: int) -> None:  # fmt: skip
    rng = street.rng
    for _ in range(count * 4):
        if count <= 0:
            return
        label: Label = rng.choice(["car", "car", "cyclist", "pedestrian", "pedestrian"])
        u = float(rng.uniform(-street.reach, street.reach))
        z = street.ground
        on_pavement = label == "pedestrian" and rng.random() < 0.6 and pavement > 0
        if on_pavement:
            v = float(rng.choice([-1.0, 1.0])) * (half_width + float(rng.uniform(0.4, pavement)))
            yaw = float(rng.uniform(0, 2 * math.pi))
            z += kerb + 0.02  # standing on the pavement, feet clear of its top
        else:
            v = float(rng.uniform(-half_width + 1.0, half_width - 1.0))
            yaw = heading + math.pi * float(rng.integers(2)) + float(rng.normal(0, 0.15))
            if rng.random() < 0.15:
                yaw = float(rng.uniform(0, 2 * math.pi))
        x, y = _to_sensor(u, v, origin, heading)
        if on_pavement and not street.on_pavement(x, y):
            continue  # that stretch of pavement was left out (it would cross a road)
        size = _vehicle(rng, 0.15) if label == "car" else _size(rng, label)
        if street.road_user(Box((x, y, z + size[2] / 2.0), size, yaw, label)):
            count -= 1


def street_scene(
    rng: np.random.Generator,
    *,
    options: StreetOptions | None = None,
    sensor_height: float | None = None,
    name: str = "street",
) -> Scene:
    """A random street with the clutter of a real one (see the module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
    options : StreetOptions, optional
    sensor_height : float, optional
        Metres above the road; 1.6-1.95 m at random by default (KITTI's HDL-64E: 1.73).
    name : str

    Returns
    -------
    Scene
        ``roi``: the road (and the crossing road at a junction), kerb to kerb; road users
        and parked vehicles are obstacles, the rest background.
    """
    if not isinstance(rng, np.random.Generator):
        raise InvalidArgument(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    options = options or StreetOptions()
    height = float(rng.uniform(1.6, 1.95)) if sensor_height is None else float(sensor_height)
    street = _Street(rng, ground=-height, reach=options.reach)
    width = float(rng.uniform(*options.road_width))
    heading = float(rng.uniform(0, 2 * math.pi))
    offset = float(rng.uniform(-width / 2 + 1.0, width / 2 - 1.0))
    # The road's axis passes `offset` metres to the sensor's side.
    origin = np.array(_to_sensor(0.0, -offset, np.zeros(2), heading))
    roads = [(origin, heading)]
    if rng.random() < options.junction:
        ahead = float(rng.uniform(-20, 40))
        cross = heading + math.pi / 2 + float(rng.normal(0, 0.2))
        roads.append((np.array(_to_sensor(ahead, 0.0, origin, heading)), cross))
    polygons = []
    for road_origin, road_heading in roads:
        half = width / 2.0
        corners = [(-_ROAD_LENGTH, -half), (_ROAD_LENGTH, -half), (_ROAD_LENGTH, half),
                   (-_ROAD_LENGTH, half)]  # fmt: skip
        polygons.append(np.array([_to_sensor(u, v, road_origin, road_heading) for u, v in corners]))
    street.roads = ROI.from_polygons(polygons, raster_range=120.0)
    count = int(rng.integers(options.road_users[0], options.road_users[1] + 1))
    for index, (road_origin, road_heading) in enumerate(roads):
        half = width / 2.0
        share = count if index == 0 else count // 2
        pavement = float(rng.uniform(1.5, 5.0)) if rng.random() < 0.8 else 0.0
        kerb = float(rng.uniform(0.08, 0.2))
        for side in (-1.0, 1.0):
            if rng.random() < options.parked:
                _parked_row(street, road_origin, road_heading, side, half)
            for u in np.arange(-street.reach, street.reach, 10.0) if pavement else ():
                _pavement(street, road_origin, road_heading, u, side * (half + pavement / 2),
                          (pavement, kerb))  # fmt: skip
        _users(street, road_origin, road_heading, half, pavement, kerb, share)
        for side in (-1.0, 1.0):
            if pavement and rng.random() < 0.7:
                inset = float(rng.uniform(0.4, max(pavement - 0.3, 0.5)))
                _pavement_furniture(street, road_origin, road_heading, side, half + inset)
            _frontage(street, road_origin, road_heading, side, half + pavement)
            _loose_walls(
                street, road_origin, road_heading, side, half + pavement, options.loose_walls
            )
            _furniture(street, road_origin, road_heading, side, half, pavement, options.furniture)
    return Scene(
        sensor_height=round(height, 4),
        roi=street.roads,
        obstacles=tuple(street.obstacles),
        background=tuple(street.background),
        name=name,
    )
