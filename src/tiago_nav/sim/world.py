"""World files (``worlds/*.yaml``): the one source of geometry for simulator, map and tests.

The format is fixed by docs/interfaces.md (World files). All lengths are metres, headings degrees in the file and
radians in code (``yaw`` properties); coordinates are in the map frame. An optional
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


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder: centre ``(x, y)`` [m] and ``radius`` [m]."""
    x: float
    y: float
    radius: float


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
    movable_obstacles: List[Cylinder] = field(default_factory=list)
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
             'movable_obstacles', 'corridor', 'world_frame')


def clearance(world, xy, robot_radius=0.0, cylinders=True):
    """The smallest gap [m], exact, between a disc of ``robot_radius`` [m] centred on any of the
    map positions ``xy`` ((N, 2), or poses whose first two entries are x, y) and the ``world``'s
    walls (their boxes' edges) and, with ``cylinders``, its static and movable cylinders;
    negative where they overlap; None without positions."""
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
        for cyl in list(world.static_cylinders) + list(world.movable_obstacles):
            best = min(best, float(np.hypot(p[:, 0] - cyl.x, p[:, 1] - cyl.y).min()) - cyl.radius)
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
                 movable_obstacles=_cylinders(src, data, 'movable_obstacles'),
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
