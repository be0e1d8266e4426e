"""World files (``worlds/*.yaml``): the one source of geometry for simulator, map and tests.

The format is fixed by docs/interfaces.md (World files). All lengths are metres, headings degrees in the file and
radians in code (``yaw`` properties); coordinates are in the map frame.

Movable obstacles come in four shapes (:class:`Cylinder`, :class:`Box`, :class:`Furniture` for
``table`` and ``chair``), which share one interface: ``shape``, ``x``, ``y`` (the centre),
``yaw``, ``radius`` (the cylinder's radius; for the other shapes the radius of the smallest
circle about the centre that holds the whole footprint), ``legs()`` and ``leg_radius`` (what a
laser below a table top sees), ``outline()`` (the footprint polygon), ``solids()`` (the
outlines of what the laser and the base meet: a table's legs) and ``distance(x, y)`` (exact
distance from points to them). :class:`Walker` entries are
people walking a polyline (:mod:`tiago_nav.sim.walkers` moves them). An optional
``world_frame`` names another frame and gives its origin in the map (the simulator publishes
it on /tf_static), e.g. the Gazebo world the file was measured from.
:func:`load_world` validates a file and raises :class:`WorldError` naming the file and the field.
"""
import math
import os
from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np
import yaml

from tiago_nav.geometry import oriented_box_corners


class WorldError(ValueError):
    """A world file is missing or malformed; the message names the file and the field."""


@dataclass(frozen=True)
class Wall:
    """A static box: centre ``(x, y)`` [m], ``length`` along ``yaw_deg``, ``width`` across."""
    x: float
    y: float
    length: float
    width: float
    yaw_deg: float = 0.0

    @property
    def yaw(self):
        return math.radians(self.yaw_deg)

    def corners(self):
        """``(4, 2)`` corners in the world frame, counter-clockwise."""
        return oriented_box_corners(self.x, self.y, self.length, self.width, self.yaw)


_NO_LEGS = np.zeros((0, 2))


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder: centre ``(x, y)`` [m] and ``radius`` [m] (static, or the movable
    shape ``cylinder``)."""
    x: float
    y: float
    radius: float

    shape = 'cylinder'
    yaw = 0.0
    leg_radius = 0.0

    @property
    def centre(self):
        return (self.x, self.y)

    def legs(self):
        """Leg centres ``(0, 2)``: a cylinder has none."""
        return _NO_LEGS

    def outline(self, sides=32):
        """``(sides, 2)`` points of the circle, counter-clockwise [m]."""
        t = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
        return np.column_stack((self.x + self.radius * np.cos(t), self.y + self.radius * np.sin(t)))

    def distance(self, x, y):
        """Distance [m] from the points ``(x, y)`` (arrays) to the surface; negative inside."""
        return np.hypot(np.asarray(x, float) - self.x, np.asarray(y, float) - self.y) - self.radius

    def solids(self, sides=32):
        """Outlines ``[(n, 2), ...]`` [m] of what the laser and the base meet: the circle as a
        ``sides``-gon."""
        return [self.outline(sides)]


class _Rectangle:
    """What the rectangular movable shapes (:class:`Box`, :class:`Furniture`) share: the
    heading [rad] of their length and their centre [m]."""

    @property
    def yaw(self):
        return math.radians(self.yaw_deg)

    @property
    def centre(self):
        return (self.x, self.y)


@dataclass(frozen=True)
class Box(_Rectangle):
    """The movable shape ``box``: a ``length`` × ``width`` [m] rectangle centred at ``(x, y)``
    [m], its length along ``yaw_deg``; solid from the floor up (the laser sees its faces)."""
    x: float
    y: float
    length: float
    width: float
    yaw_deg: float = 0.0

    shape = 'box'
    leg_radius = 0.0

    @property
    def radius(self):
        """[m] Radius of the smallest circle about the centre holding the box (half its diagonal)."""
        return 0.5 * math.hypot(self.length, self.width)

    def corners(self):
        """``(4, 2)`` corners in the world frame, counter-clockwise."""
        return oriented_box_corners(self.x, self.y, self.length, self.width, self.yaw)

    def legs(self):
        """Leg centres ``(0, 2)``: a box has none."""
        return _NO_LEGS

    def outline(self):
        """The footprint: :meth:`corners`."""
        return self.corners()

    def distance(self, x, y):
        """Distance [m] from the points ``(x, y)`` (arrays) to the box; negative inside."""
        return _box_distance(x, y, self.x, self.y, self.length, self.width, self.yaw)

    def solids(self, sides=32):
        """Outlines ``[(4, 2)]`` [m] of what the laser and the base meet: the box."""
        return [self.corners()]


FURNITURE_LEG_RADIUS = {'table': 0.03, 'chair': 0.015}   # [m] defaults of leg_radius


@dataclass(frozen=True)
class Furniture(_Rectangle):
    """The movable shapes ``table`` and ``chair``: four vertical legs of ``leg_radius`` [m]
    centred on the corners of a ``length`` × ``width`` [m] rectangle centred at ``(x, y)``,
    its length along ``yaw_deg``, under a top higher than the laser and the robot's base
    (:mod:`tiago_nav.sim.scene`): the laser and the base meet only the legs."""
    shape: str
    x: float
    y: float
    length: float
    width: float
    yaw_deg: float = 0.0
    leg_radius: float = 0.03

    @property
    def radius(self):
        """[m] Radius of the smallest circle about the centre holding the legs."""
        return 0.5 * math.hypot(self.length, self.width) + self.leg_radius

    def legs(self):
        """``(4, 2)`` leg centres [m] in the world frame (the corners, counter-clockwise)."""
        return oriented_box_corners(self.x, self.y, self.length, self.width, self.yaw)

    def outline(self):
        """The footprint: the rectangle that holds the legs, ``(4, 2)`` counter-clockwise."""
        d = 2.0 * self.leg_radius
        return oriented_box_corners(self.x, self.y, self.length + d, self.width + d, self.yaw)

    def distance(self, x, y):
        """Distance [m] from the points ``(x, y)`` (arrays) to the nearest leg (the top is
        above the base); negative inside a leg."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        return np.min([np.hypot(x - lx, y - ly) for lx, ly in self.legs()], axis=0) - self.leg_radius

    def solids(self, sides=32):
        """Outlines ``[(sides, 2)] * 4`` [m] of what the laser and the base meet: the legs."""
        return [Cylinder(float(lx), float(ly), self.leg_radius).outline(sides) for lx, ly in self.legs()]


@dataclass(frozen=True)
class Walker:
    """A person walking the polyline ``path`` (``((x, y), ...)`` [m]) at ``speed`` [m/s],
    starting ``start_delay`` [s of simulated time] after the simulator starts; with ``loop``
    the path closes back to its first point and repeats, otherwise the walker stops at its
    last point. :mod:`tiago_nav.sim.walkers` gives its legs and its motion."""
    path: Tuple[Tuple[float, float], ...]
    speed: float
    loop: bool = False
    start_delay: float = 0.0

    shape = 'walker'


def _box_distance(x, y, cx, cy, length, width, yaw):
    """Signed distance [m] from points ``(x, y)`` to a ``length`` × ``width`` rectangle
    centred at ``(cx, cy)`` along ``yaw`` [rad]: > 0 outside, < 0 inside."""
    dx, dy = np.asarray(x, float) - cx, np.asarray(y, float) - cy
    c, s = math.cos(yaw), math.sin(yaw)
    qx = np.abs(dx * c + dy * s) - length / 2.0
    qy = np.abs(-dx * s + dy * c) - width / 2.0
    return np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0)) + np.minimum(np.maximum(qx, qy), 0.0)


@dataclass(frozen=True)
class Corridor:
    """Documents a narrow corridor: ``entry`` and ``exit`` points [m] and its ``width`` [m]."""
    entry: Tuple[float, float]
    exit: Tuple[float, float]
    width: float


@dataclass(frozen=True)
class WorldFrame:
    """Another named frame of the world, e.g. the frame of the Gazebo world a world file was
    measured from: ``name`` and ``offset`` ``(x [m], y [m], yaw [deg])``, the pose of its
    origin in the map frame (so a point ``p_map = offset ∘ p_world``)."""
    name: str
    offset: Tuple[float, float, float]

    @property
    def pose(self):
        """``offset`` as ``(x, y, yaw)`` in metres and radians."""
        x, y, yaw_deg = self.offset
        return (x, y, math.radians(yaw_deg))


@dataclass
class World:
    name: str
    resolution: float
    bounds: Tuple[float, float, float, float]
    robot_start: Tuple[float, float, float]  # x [m], y [m], yaw [deg]
    walls: List[Wall] = field(default_factory=list)
    static_cylinders: List[Cylinder] = field(default_factory=list)
    movable_obstacles: list = field(default_factory=list)   # Cylinder, Box or Furniture
    walkers: List[Walker] = field(default_factory=list)
    corridor: Optional[Corridor] = None
    world_frame: Optional[WorldFrame] = None
    source: str = '<dict>'

    @property
    def start_pose(self):
        """The robot's start pose ``(x, y, yaw)`` in metres and radians."""
        x, y, yaw_deg = self.robot_start
        return (x, y, math.radians(yaw_deg))

    @classmethod
    def from_dict(cls, data, source='<dict>'):
        """Build and validate a world from the parsed YAML mapping ``data``."""
        return _parse(data, source)


_TOP_KEYS = ('name', 'resolution', 'bounds', 'robot_start', 'walls', 'static_cylinders',
             'movable_obstacles', 'walkers', 'corridor', 'world_frame')
MOVABLE_SHAPES = ('cylinder', 'box', 'table', 'chair')


def clearance(world, xy, robot_radius=0.0, cylinders=True):
    """The smallest gap [m], exact, between a disc of ``robot_radius`` [m] centred on any of the
    map positions ``xy`` ((N, 2), or poses whose first two entries are x, y) and the ``world``'s
    walls (their boxes' edges) and, with ``cylinders``, its static cylinders and its movable
    obstacles of any shape (what the base can touch of them: a table's legs); negative where
    they overlap; None without positions. Walkers move and are not included."""
    p = np.asarray([q[:2] for q in xy], float).reshape(-1, 2)
    if not len(p):
        return None
    best = np.inf
    for w in world.walls:
        c = w.corners()
        for a, b in zip(c, np.roll(c, -1, axis=0)):
            ab = b - a
            t = np.clip(((p - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
            best = min(best, float(np.hypot(*(p - (a + t[:, None] * ab)).T).min()))
    if cylinders:
        for obj in list(world.static_cylinders) + list(world.movable_obstacles):
            best = min(best, float(np.min(obj.distance(p[:, 0], p[:, 1]))))
    return best - robot_radius

def load_world(path):
    """Load and validate the world file at ``path``; raise :class:`WorldError` on any problem."""
    if not path:
        raise WorldError('no world file given')
    if not os.path.isfile(path):
        raise WorldError('%s: world file not found' % path)
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise WorldError('%s: not valid YAML: %s' % (path, e)) from None
    return _parse(data, path)


def _number(src, where, value, positive=False, nonneg=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise WorldError('%s: %s must be a finite number, got %r' % (src, where, value))
    if positive and value <= 0:
        raise WorldError('%s: %s must be > 0, got %r' % (src, where, value))
    if nonneg and value < 0:
        raise WorldError('%s: %s must be >= 0, got %r' % (src, where, value))
    return float(value)


def _vector(src, where, value, n):
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise WorldError('%s: %s must be a list of %d numbers, got %r' % (src, where, n, value))
    return tuple(_number(src, '%s[%d]' % (where, i), v) for i, v in enumerate(value))


def _record(src, where, item, required, optional=()):
    if not isinstance(item, dict):
        raise WorldError('%s: %s must be a mapping with keys %s, got %r'
                         % (src, where, ', '.join(required), item))
    unknown = sorted(set(item) - set(required) - set(optional))
    if unknown:
        raise WorldError('%s: %s has unknown key(s) %s' % (src, where, ', '.join(map(str, unknown))))
    for k in required:
        if k not in item:
            raise WorldError('%s: %s is missing %r' % (src, where, k))


def _list(src, data, key):
    value = data.get(key)
    if value is None:
        return []
    if not isinstance(value, list):
        raise WorldError('%s: %s must be a list, got %r' % (src, key, value))
    return value


def _cylinders(src, data, key):
    out = []
    for i, c in enumerate(_list(src, data, key)):
        where = '%s[%d]' % (key, i)
        _record(src, where, c, ('x', 'y', 'radius'))
        out.append(Cylinder(_number(src, where + '.x', c['x']), _number(src, where + '.y', c['y']),
                            _number(src, where + '.radius', c['radius'], positive=True)))
    return out


def _movables(src, data):
    """``movable_obstacles``: each a mapping with an optional ``shape`` (default cylinder)."""
    out = []
    for i, c in enumerate(_list(src, data, 'movable_obstacles')):
        where = 'movable_obstacles[%d]' % i
        shape = c.get('shape', 'cylinder') if isinstance(c, dict) else 'cylinder'
        if shape not in MOVABLE_SHAPES:
            raise WorldError('%s: %s.shape must be one of %s, got %r'
                             % (src, where, ', '.join(MOVABLE_SHAPES), shape))
        if shape == 'cylinder':
            _record(src, where, c, ('x', 'y', 'radius'), ('shape',))
            out.append(Cylinder(_number(src, where + '.x', c['x']), _number(src, where + '.y', c['y']),
                                _number(src, where + '.radius', c['radius'], positive=True)))
            continue
        extra = ('shape', 'yaw_deg') + (('leg_radius',) if shape != 'box' else ())
        _record(src, where, c, ('x', 'y', 'length', 'width'), extra)
        x, y = _number(src, where + '.x', c['x']), _number(src, where + '.y', c['y'])
        length = _number(src, where + '.length', c['length'], positive=True)
        width = _number(src, where + '.width', c['width'], positive=True)
        yaw_deg = _number(src, where + '.yaw_deg', c.get('yaw_deg', 0.0))
        if shape == 'box':
            out.append(Box(x, y, length, width, yaw_deg))
            continue
        leg = _number(src, where + '.leg_radius', c.get('leg_radius', FURNITURE_LEG_RADIUS[shape]),
                      positive=True)
        if 2.0 * leg >= min(length, width):
            raise WorldError('%s: %s.leg_radius must be less than half of length and width (the '
                             'legs would touch), got %r' % (src, where, leg))
        out.append(Furniture(shape, x, y, length, width, yaw_deg, leg))
    return out


def _walkers(src, data, bounds):
    """``walkers``: ``{path: [[x, y], ...], speed, loop, start_delay}`` each, every point
    within ``bounds``."""
    out = []
    for i, w in enumerate(_list(src, data, 'walkers')):
        where = 'walkers[%d]' % i
        _record(src, where, w, ('path', 'speed'), ('loop', 'start_delay'))
        path = w['path']
        if not isinstance(path, list) or len(path) < 2:
            raise WorldError('%s: %s.path must be a list of at least 2 points [x, y], got %r'
                             % (src, where, path))
        pts = tuple(_vector(src, '%s.path[%d]' % (where, k), q, 2) for k, q in enumerate(path))
        for k, (x, y) in enumerate(pts):
            if not (bounds[0] <= x <= bounds[2] and bounds[1] <= y <= bounds[3]):
                raise WorldError('%s: %s.path[%d] %r lies outside bounds %r'
                                 % (src, where, k, [x, y], list(bounds)))
        for k in range(1, len(pts)):
            if pts[k] == pts[k - 1]:
                raise WorldError('%s: %s.path[%d] repeats the point before it, got %r'
                                 % (src, where, k, list(pts[k])))
        loop = w.get('loop', False)
        if not isinstance(loop, bool):
            raise WorldError('%s: %s.loop must be true or false, got %r' % (src, where, loop))
        out.append(Walker(pts, _number(src, where + '.speed', w['speed'], positive=True), loop,
                          _number(src, where + '.start_delay', w.get('start_delay', 0.0), nonneg=True)))
    return out


def _parse(data, src):
    if not isinstance(data, dict):
        raise WorldError('%s: a world file must be a YAML mapping, got %r' % (src, type(data).__name__))
    unknown = sorted(set(map(str, data)) - set(_TOP_KEYS))
    if unknown:
        raise WorldError('%s: unknown key(s) %s (expected some of %s)'
                         % (src, ', '.join(unknown), ', '.join(_TOP_KEYS)))
    for k in ('name', 'resolution', 'bounds', 'robot_start'):
        if k not in data:
            raise WorldError('%s: missing required field %r' % (src, k))
    name = data['name']
    if not isinstance(name, str) or not name:
        raise WorldError('%s: name must be a non-empty string, got %r' % (src, name))
    resolution = _number(src, 'resolution', data['resolution'], positive=True)
    bounds = _vector(src, 'bounds', data['bounds'], 4)
    if not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
        raise WorldError('%s: bounds must be [xmin, ymin, xmax, ymax] with xmin < xmax and '
                         'ymin < ymax, got %r' % (src, list(bounds)))
    if (bounds[2] - bounds[0]) / resolution * (bounds[3] - bounds[1]) / resolution > 4e7:
        raise WorldError('%s: bounds / resolution make a map of more than 40 million cells' % src)
    start = _vector(src, 'robot_start', data['robot_start'], 3)
    if not (bounds[0] <= start[0] <= bounds[2] and bounds[1] <= start[1] <= bounds[3]):
        raise WorldError('%s: robot_start %r lies outside bounds %r' % (src, list(start), list(bounds)))

    walls = []
    for i, w in enumerate(_list(src, data, 'walls')):
        where = 'walls[%d]' % i
        _record(src, where, w, ('x', 'y', 'length', 'width'), ('yaw_deg',))
        walls.append(Wall(_number(src, where + '.x', w['x']), _number(src, where + '.y', w['y']),
                          _number(src, where + '.length', w['length'], positive=True),
                          _number(src, where + '.width', w['width'], positive=True),
                          _number(src, where + '.yaw_deg', w.get('yaw_deg', 0.0))))
    corridor = None
    if data.get('corridor') is not None:
        c = data['corridor']
        _record(src, 'corridor', c, ('entry', 'exit', 'width'))
        corridor = Corridor(_vector(src, 'corridor.entry', c['entry'], 2),
                            _vector(src, 'corridor.exit', c['exit'], 2),
                            _number(src, 'corridor.width', c['width'], positive=True))
    return World(name=name, resolution=resolution, bounds=bounds, robot_start=start, walls=walls,
                 static_cylinders=_cylinders(src, data, 'static_cylinders'),
                 movable_obstacles=_movables(src, data), walkers=_walkers(src, data, bounds),
                 corridor=corridor, world_frame=_world_frame(src, data.get('world_frame')),
                 source=src)


def _world_frame(src, wf):
    """The optional ``world_frame: {name: NAME, offset: [x, y, yaw_deg]}``: a tf frame name
    (no spaces, no leading '/') and the pose of its origin in the map frame."""
    if wf is None:
        return None
    _record(src, 'world_frame', wf, ('name', 'offset'))
    name = wf['name']
    if not isinstance(name, str) or not name or name != name.strip() or any(c.isspace() for c in name) \
            or name.startswith('/'):
        raise WorldError('%s: world_frame.name must be a tf frame name (not empty, no spaces, no '
                         'leading /), got %r' % (src, name))
    return WorldFrame(name, _vector(src, 'world_frame.offset', wf['offset'], 3))
