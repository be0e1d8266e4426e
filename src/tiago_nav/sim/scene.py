"""The pybullet scene of a world: static bodies, movable obstacles (cylinders, boxes, tables
and chairs), walkers' legs, a TIAGo-like base and its 2-D laser, ray cast with pybullet's
batch ray test.

A table's or a chair's body is its four legs under a top at :data:`TOP_HEIGHT` (above the base
and the laser: both meet only the legs). Each walker is two leg bodies, moved kinematically
(:meth:`Scene.set_walker_legs`).

Frames: the world frame is the map frame; the base pose ``(x, y, yaw)`` is base_footprint's;
the laser (base_laser_link) sits ``laser_offset`` [m] ahead of the base centre, at
``laser_height`` above the floor (above the base's collision body, so beams never hit it).
"""
import contextlib
import ctypes
import math
import os
import sys
from dataclasses import dataclass

import numpy as np

from tiago_nav.geometry import compose
from tiago_nav.params import ParamError, param, validate
from tiago_nav.robot import LASER_HEIGHT, LASER_OFFSET, ROBOT_RADIUS
from tiago_nav.scan import hits


@contextlib.contextmanager
def _silenced(fd):
    """Send what is written to file descriptor ``fd`` inside the block to /dev/null: pybullet's
    C code prints a build banner on stderr at import and its argv on stdout at connect."""
    try:
        saved = os.dup(fd)
    except OSError:          # no such descriptor: nothing to silence
        yield
        return
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        with open(os.devnull, 'w') as null:
            os.dup2(null.fileno(), fd)
            try:
                yield
            finally:
                _LIBC.fflush(None)           # C stdio buffers go to /dev/null too
    finally:
        os.dup2(saved, fd)
        os.close(saved)


_LIBC = ctypes.CDLL(None)
with _silenced(2):
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

WALL_HEIGHT = 1.0          # [m] every static and movable body spans the floor to this height
ROBOT_HEIGHT = 0.25        # [m] the base's collision body, floor to this height
TOP_HEIGHT = {'table': 0.75, 'chair': 0.45}   # [m] the top of a table or seat of a chair
TOP_THICKNESS = 0.03       # [m] of that top
WALKER_HEIGHT = 0.9        # [m] a walker's legs span the floor to this height


@dataclass(frozen=True)
class LaserConfig:
    """A TIAGo-like planar laser: 666 beams over ±110°, 0.05–25 m (angles [rad], ranges [m])."""
    num_beams: int = param(666, 'laser beams per scan', ge=2, name='laser_beams')
    angle_min: float = param(-math.radians(110.0), '[rad] first beam, in base_laser_link',
                             name='laser_angle_min')
    angle_max: float = param(math.radians(110.0), '[rad] last beam, in base_laser_link; > laser_angle_min',
                             name='laser_angle_max')
    range_min: float = param(0.05, '[m] nearer is too close to measure (-inf)', ge=0,
                             name='laser_range_min')
    range_max: float = param(25.0, '[m] nothing within it is no return (+inf); > laser_range_min',
                             name='laser_range_max')
    offset: float = param(LASER_OFFSET, '[m] base_laser_link ahead of the base centre',
                          name='laser_offset')
    height: float = param(LASER_HEIGHT, '[m] base_laser_link above the floor, above the base body',
                          gt=ROBOT_HEIGHT, lt=WALL_HEIGHT, name='laser_height')

    def __post_init__(self):
        validate(self)
        if not self.angle_min < self.angle_max:
            raise ParamError('must be > laser_angle_min (%g rad), got %g' % (self.angle_min, self.angle_max),
                             'laser_angle_max')
        if not self.range_min < self.range_max:
            raise ParamError('must be > laser_range_min (%g m), got %g' % (self.range_min, self.range_max),
                             'laser_range_max')

    @property
    def angle_increment(self):
        return (self.angle_max - self.angle_min) / (self.num_beams - 1)

    def angles(self):
        """Beam angles [rad] in base_laser_link, from ``angle_min`` to ``angle_max``."""
        return np.linspace(self.angle_min, self.angle_max, self.num_beams)


class Scene:
    """A world built in its own pybullet client (DIRECT by default, GUI on request).

    Use as a context manager or call :meth:`close`. Several scenes may coexist.
    """

    def __init__(self, world, robot_radius=ROBOT_RADIUS, laser=LaserConfig(), gui=False):
        self.world = world
        self.laser = laser
        self.robot_radius = float(robot_radius)
        # one client per scene: every call is bound to it, so scenes never talk to each other's worlds
        with _silenced(1):
            p = self._p = BulletClient(pybullet.GUI if gui else pybullet.DIRECT)
        if not p.isConnected():
            self._p = None
            raise RuntimeError('pybullet could not connect (%s mode)' % ('GUI' if gui else 'DIRECT'))
        if gui:
            p.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
        # Static geometry is one triangle mesh and each movable cylinder one more, for the
        # laser's ray casts (rather than pybullet's box and cylinder primitives).
        self.static_id = None
        if world.walls or world.static_cylinders:
            mesh = _Mesh()
            for w in world.walls:
                mesh.box(w.corners())
            for c in world.static_cylinders:
                mesh.cylinder(c.x, c.y, c.radius)
            self.static_id = self._mesh_body(mesh, (0.6, 0.6, 0.6, 1))
        self.movable_ids = []
        for c in world.movable_obstacles:
            mesh = _Mesh()
            if c.shape == 'cylinder':
                mesh.cylinder(c.x, c.y, c.radius)
            elif c.shape == 'box':
                mesh.box(c.corners())
            else:
                for lx, ly in c.legs():
                    mesh.cylinder(lx, ly, c.leg_radius, top=TOP_HEIGHT[c.shape])
                top = TOP_HEIGHT[c.shape]
                mesh.prism(c.outline(), top - TOP_THICKNESS, top)
            self.movable_ids.append(self._mesh_body(mesh, (0.9, 0.3, 0.2, 1)))
        # walkers: one body per leg, a cylinder about its own origin, placed by set_walker_legs
        self.walker_leg_ids = []
        self._legs_due = {}
        self._legs_placed = set()
        if world.walkers:
            from tiago_nav.sim.walkers import LEG_RADIUS
            leg = _Mesh()
            leg.cylinder(0.0, 0.0, LEG_RADIUS, top=WALKER_HEIGHT)
            for _ in world.walkers:
                self.walker_leg_ids.append(tuple(self._mesh_body(leg, (0.9, 0.7, 0.2, 1))
                                                 for _ in range(2)))
            self.walkers_away()
        col = p.createCollisionShape(pybullet.GEOM_CYLINDER, radius=self.robot_radius,
                                     height=ROBOT_HEIGHT)
        vis = p.createVisualShape(pybullet.GEOM_CYLINDER, radius=self.robot_radius,
                                  length=ROBOT_HEIGHT, rgbaColor=(0.2, 0.4, 0.9, 1))
        # mass > 0 so that pybullet computes its contacts with the static bodies; the base is
        # moved kinematically (reset each step), never by the physics.
        self.robot_id = p.createMultiBody(1.0, col, vis, basePosition=(0, 0, ROBOT_HEIGHT / 2))
        self._bounds = world.bounds
        self._pose = None
        self.set_robot_pose(world.start_pose)
        self._body_to_movable = {b: i for i, b in enumerate(self.movable_ids)}

    # --- building -------------------------------------------------------------------------
    def _mesh_body(self, mesh, rgba):
        p = self._p
        col = p.createCollisionShape(pybullet.GEOM_MESH, vertices=mesh.vertices, indices=mesh.indices,
                                     flags=pybullet.GEOM_FORCE_CONCAVE_TRIMESH)
        vis = p.createVisualShape(pybullet.GEOM_MESH, vertices=mesh.vertices, indices=mesh.indices,
                                  rgbaColor=rgba)
        return p.createMultiBody(0, col, vis)

    def set_walker_legs(self, i, legs):
        """Place walker ``i``'s two legs at the ``(2, 2)`` centres ``legs`` [m]. The bodies
        move when something looks: a ray cast moves all of them, a contact test those near the
        base (a pybullet call per leg and step cost more than the rest of a step); the first
        placement is made at once."""
        self._legs_due[i] = legs
        if i not in self._legs_placed:
            self._legs_placed.add(i)
            self._place_legs((legs[0][0], legs[0][1], 0.0))

    def walkers_away(self):
        """Put every walker's legs outside the world's bounds, where no beam and no base reaches
        (where they stand until :meth:`set_walker_legs` places them)."""
        xmin, ymin = self.world.bounds[:2]
        for i in range(len(self.walker_leg_ids)):
            self._legs_due[i] = [(xmin - 100.0 - 2.0 * i, ymin - 100.0),
                                 (xmin - 101.0 - 2.0 * i, ymin - 100.0)]
        self._place_legs()

    def _place_legs(self, near=None):
        """Move the walkers' leg bodies to their last :meth:`set_walker_legs` (with ``near``
        ``(x, y, reach)``: only the walkers with a leg within ``reach`` [m] of ``(x, y)``)."""
        if not self._legs_due:
            return
        reset = self._p.resetBasePositionAndOrientation
        for i in list(self._legs_due):
            legs = self._legs_due[i]
            if near is not None and min(math.hypot(x - near[0], y - near[1]) for x, y in legs) > near[2]:
                continue
            del self._legs_due[i]
            for body, (x, y) in zip(self.walker_leg_ids[i], legs):
                reset(body, (float(x), float(y), 0.0), (0, 0, 0, 1))

    # --- robot ----------------------------------------------------------------------------
    def set_robot_pose(self, pose):
        """Place the base at ``pose`` ``(x, y, yaw)`` (no collision check)."""
        x, y, yaw = (float(v) for v in pose)
        self._pose = (x, y, yaw)
        self._p.resetBasePositionAndOrientation(
            self.robot_id, (x, y, ROBOT_HEIGHT / 2.0 + 0.001),
            pybullet.getQuaternionFromEuler((0, 0, yaw)))

    def robot_contacts(self):
        """Body ids the base touches or penetrates at its current pose."""
        p = self._p
        if self._legs_due:
            self._place_legs((self._pose[0], self._pose[1], self.robot_radius + 0.5))
        p.performCollisionDetection()
        return sorted({c[2] for c in p.getContactPoints(bodyA=self.robot_id) if c[8] <= 1e-4})

    def robot_clear_of(self, bodies, margin):
        """True when the base is more than ``margin`` [m] away from every body in ``bodies``."""
        return not any(self._p.getClosestPoints(self.robot_id, b, margin) for b in bodies)

    # --- laser ----------------------------------------------------------------------------
    def laser_pose(self, base_pose=None):
        """Pose ``(x, y, yaw)`` of base_laser_link in the world for a base pose (default: the
        current one)."""
        return compose(base_pose or self._pose, (self.laser.offset, 0.0, 0.0))

    def cast(self, base_pose=None):
        """Noise-free ray cast of the laser from ``base_pose`` (default: the current pose).

        Returns ``(ranges, body_ids)``: ranges [m] measured from base_laser_link (``inf`` where
        nothing is hit within ``range_max``, REP 117) and the pybullet body id hit by each beam
        (-1 for none). The robot's own body lies below the beams and is never hit.
        """
        self._place_legs()
        lx, ly, lyaw = self.laser_pose(base_pose)
        cfg = self.laser
        ang = lyaw + cfg.angles()
        c, s = np.cos(ang), np.sin(ang)
        # Nothing lies outside the world's bounds: stop each ray where it leaves them (plus a
        # margin), which makes pybullet's ray test several times faster than 25 m rays.
        length = np.minimum(cfg.range_max, _exit_distance(self._bounds, lx, ly, c, s) + 0.5)
        z = cfg.height
        start = np.empty((ang.size, 3))
        start[:] = (lx, ly, z)
        end = np.column_stack((lx + length * c, ly + length * s, np.full(ang.size, z)))
        res = self._p.rayTestBatch(start, end, numThreads=1)
        ids = np.fromiter((r[0] for r in res), dtype=int, count=len(res))
        frac = np.fromiter((r[2] for r in res), dtype=float, count=len(res))
        ranges = np.where(ids >= 0, frac * length, np.inf)
        return ranges, ids

    # --- life cycle -----------------------------------------------------------------------
    def close(self):
        p, self._p = getattr(self, '_p', None), None
        if p is not None:
            try:
                p.disconnect()
            except pybullet.error:
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        self.close()


def _exit_distance(bounds, x, y, c, s):
    """Distance [m] along unit directions ``(c, s)`` from ``(x, y)`` to the edge of the box
    ``bounds`` (0 where the point is already outside in that direction)."""
    xmin, ymin, xmax, ymax = bounds
    with np.errstate(divide='ignore', invalid='ignore'):
        tx = np.where(c > 0, (xmax - x) / c, np.where(c < 0, (xmin - x) / c, np.inf))
        ty = np.where(s > 0, (ymax - y) / s, np.where(s < 0, (ymin - y) / s, np.inf))
    return np.maximum(np.minimum(tx, ty), 0.0)


def noisy(ranges, std, rng, range_min, range_max):
    """What the laser reports for the true ``ranges`` [m] (``inf``: nothing hit), in REP 117
    values (:mod:`tiago_nav.scan`): Gaussian noise of ``std`` [m] on every true range within
    ``[range_min, range_max]``; a true or noisy range below ``range_min`` reads ``-inf`` (too
    close), nothing within ``range_max`` (true or after the noise) reads ``+inf`` (no return)."""
    r = np.array(ranges, dtype=float)
    with np.errstate(invalid='ignore'):
        r[r < range_min] = -np.inf
        r[r > range_max] = np.inf
    hit = hits(r, range_min, range_max)
    if std > 0:
        r[hit] += rng.normal(0.0, std, int(hit.sum()))
        r[hit & (r < range_min)] = -np.inf
        r[hit & (r > range_max)] = np.inf
    return r


class _Mesh:
    """Vertical prisms (boxes, cylinders), by default from the floor to ``WALL_HEIGHT``, as one
    triangle mesh."""
    CYLINDER_SIDES = 96

    def __init__(self):
        self.vertices = []
        self.indices = []

    def prism(self, outline, bottom=0.0, top=WALL_HEIGHT):
        """A prism over a convex ``(n, 2)`` counter-clockwise outline [m], from ``bottom`` to
        ``top`` [m] above the floor."""
        n = len(outline)
        b = len(self.vertices)
        for z in (bottom, top):
            self.vertices.extend([float(x), float(y), z] for x, y in outline)
        for i in range(n):
            j = (i + 1) % n
            self.indices += [b + i, b + j, b + n + j, b + i, b + n + j, b + n + i]   # side
        for i in range(1, n - 1):
            self.indices += [b, b + i + 1, b + i]                                   # bottom
            self.indices += [b + n, b + n + i, b + n + i + 1]                       # top

    def box(self, corners):
        self.prism(corners)

    def cylinder(self, x, y, radius, top=WALL_HEIGHT):
        """A regular polygon whose sides touch the circle (error < 0.1 mm at r = 0.2 m), from
        the floor to ``top`` [m]."""
        n = self.CYLINDER_SIDES
        t = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
        big = radius / math.cos(math.pi / n)
        self.prism(np.column_stack((x + big * np.cos(t), y + big * np.sin(t))), top=top)

