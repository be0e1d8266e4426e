"""Closed loops of the corridor law for tests and benchmarks (no ROS master): the law against the
simulator library (:func:`run_in_simulator`), and a fake robot and I/O standing for the ROS side of
the corridor_controller node in the unit tests of its decisions (:class:`FakeCorridorRobot`,
:class:`FakeCorridorIO`).

Units: metres, radians, seconds of simulated time; poses ``(x, y, yaw)`` in ``odom``.
"""
import math

import numpy as np

from tiago_nav.corridor.law import (ABORTED, PREEMPTED, SUCCEEDED, Command, CorridorFollower,
                                    CorridorParams, GoalJudge)
from tiago_nav.geometry import compose, wrap_angle
from tiago_nav.robot import LASER_OFFSET
from tiago_nav.scan import Scan
from tiago_nav.sim.world import World


def run_in_simulator(sim, params=CorridorParams(), max_speed=None, max_distance=None,
                     timeout=60.0, blocked_timeout=2.0, on_step=None):
    """Closed loop without ROS: ``sim`` (:class:`tiago_nav.sim.simulator.Simulator`) scans at
    its scan rate, the law commands at its odometry rate; the goal ends as the server's does
    (:class:`tiago_nav.corridor.law.GoalJudge`). Returns ``(command, follower)`` with the final
    :class:`Command`; ``on_step(sim, cmd)`` is called after every physics step."""
    f = CorridorFollower(params, max_speed, max_distance)
    judge = GoalJudge(blocked_timeout)
    cfg = sim.config
    laser_cfg = cfg.laser
    cmd = Command()
    t_end = sim.time + timeout
    scan_due, odom_due = True, True
    while sim.time < t_end:
        pose = sim.odom_pose
        if scan_due:
            laser = compose(pose, (laser_cfg.offset, 0.0, 0.0))
            f.update_laser(Scan(sim.scan(), laser_cfg.angle_min, laser_cfg.angle_increment,
                                laser_cfg.range_min, laser_cfg.range_max, sim.time, 'base_laser_link'),
                           laser, pose)
        if scan_due or odom_due:
            cmd = f.command(pose)
            if judge.judge(cmd, sim.time) is not None:
                sim.command(0.0, 0.0)
                break
            sim.command(cmd.v, cmd.omega)
        scan_due, odom_due = sim.step()
        if on_step is not None:
            on_step(sim, cmd)
    else:
        cmd = Command(state='failed', reason='timeout after %.0f s' % timeout)
    sim.command(0.0, 0.0)
    for _ in range(int(cfg.rate)):           # let it brake to a stop
        sim.step()
        if on_step is not None:
            on_step(sim, cmd)
    return cmd, f


def world_segments(world, sides=32):
    """The outlines of a :class:`tiago_nav.sim.world.World`'s walls, static cylinders and
    movable obstacles (what the laser meets of them: a table's legs) as ``(N, 2, 2)``
    segments [m], circles as ``sides``-gons. Walkers move and are left out."""
    polys = [w.corners() for w in world.walls]
    for c in list(world.static_cylinders) + list(world.movable_obstacles):
        polys.extend(c.solids(sides))
    return np.array([(poly[i], poly[(i + 1) % len(poly)]) for poly in polys
                     for i in range(len(poly))], float).reshape(-1, 2, 2)


def ray_cast(origin, angles, segments, max_range):
    """Range [m] along each ray from ``origin`` in the directions ``angles`` [rad] to the nearest
    of ``segments`` (``(N, 2, 2)``); ``inf`` where none is within ``max_range``."""
    d = np.column_stack((np.cos(angles), np.sin(angles)))[:, None, :]       # (B, 1, 2)
    a = segments[None, :, 0, :] - np.asarray(origin, float)[:2]              # (1, N, 2)
    e = (segments[:, 1, :] - segments[:, 0, :])[None, :, :]                  # (1, N, 2)
    den = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    with np.errstate(divide='ignore', invalid='ignore'):
        t = (a[..., 0] * e[..., 1] - a[..., 1] * e[..., 0]) / den
        u = (a[..., 0] * d[..., 1] - a[..., 1] * d[..., 0]) / den
    t = np.where((np.abs(den) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1), t, np.inf)
    r = t.min(axis=1)
    return np.where(r <= max_range, r, np.inf)


class FakeCorridorRobot:
    """A TIAGo-like base in a world, for unit tests of the corridor_controller node without ROS:
    the sensing part of the node's ``io`` (``latest_scan``, ``lookup``); it obeys the newest
    velocity command given to :meth:`command` (recorded in ``commands`` as ``(v, w)``), moving
    whenever ``clock`` (a FakeClock) advances.

    The base reaches the commanded velocities within ``accel`` [m/s^2] (and 2 ``accel`` rad/s^2);
    a laser (666 beams over +-110 deg, 0.05-25 m, ``LASER_OFFSET`` ahead of the base, an exact
    cast plus ``noise`` [m] of seeded Gaussian range noise: a live laser is never bit-identical
    twice) scans every ``scan_period`` [s]; ``map`` and ``odom`` coincide. Faults for the tests:
    ``laser_on`` False stops the scans, ``corrupt(ranges)`` rewrites each scan's ranges,
    ``tf_ok`` False makes every lookup fail. ``track`` records ``(t, x, y, yaw, v_cmd)``.
    """
    FRAMES = ('map', 'odom')

    def __init__(self, world, clock, pose=None, scan_period=1.0 / 15.0, accel=1.0,
                 corrupt=None, noise=0.005, seed=0):
        self.world = world if isinstance(world, World) else World.from_dict(world)
        self.segments = world_segments(self.world)
        self.clock = clock
        self.commands = []
        self.pose = tuple(pose) if pose is not None else self.world.start_pose
        self.v = self.w = 0.0
        self.scan_period, self.accel = scan_period, accel
        self.angles = np.linspace(-math.radians(110.0), math.radians(110.0), 666)
        self.laser_on, self.tf_ok, self.corrupt = True, True, corrupt
        self.noise, self.rng = noise, np.random.default_rng(seed)
        self.scan = None
        self.history = [(clock.now(), self.pose)]
        self.track = []
        self._since_scan = scan_period
        clock.on_advance(self.advance)
        self.advance(0.0)

    def advance(self, dt):
        v_cmd, w_cmd = self.commands[-1] if self.commands else (0.0, 0.0)
        self.v += max(-self.accel * dt, min(self.accel * dt, v_cmd - self.v))
        self.w += max(-2 * self.accel * dt, min(2 * self.accel * dt, w_cmd - self.w))
        x, y, yaw = self.pose
        self.pose = (x + self.v * math.cos(yaw) * dt, y + self.v * math.sin(yaw) * dt,
                     float(wrap_angle(yaw + self.w * dt)))
        t = self.clock.now()
        self.history = self.history[-400:] + [(t, self.pose)]
        self.track.append((t,) + self.pose + (v_cmd,))
        self._since_scan += dt
        if self._since_scan >= self.scan_period - 1e-9 and self.laser_on:
            self._since_scan = 0.0
            laser = compose(self.pose, (LASER_OFFSET, 0.0, 0.0))
            r = ray_cast(laser, self.angles + laser[2], self.segments, 25.0)
            finite = np.isfinite(r)
            r[finite] += self.rng.normal(0.0, self.noise, int(finite.sum()))
            r[r < 0.05] = -np.inf
            if self.corrupt is not None:
                r = self.corrupt(r)
            self.scan = Scan(r, float(self.angles[0]), float(self.angles[1] - self.angles[0]), 0.05,
                             25.0, t, 'base_laser_link')

    def command(self, v, w):
        """A velocity command [m/s, rad/s], obeyed from now on."""
        self.commands.append((float(v), float(w)))

    def latest_scan(self):
        return self.scan

    def lookup(self, parent, child, stamp=None):
        """Pose of ``child`` (base_footprint or base_laser_link) in ``parent`` (map or odom) at
        ``stamp`` [s] (None: now); ``LookupError`` otherwise."""
        if not self.tf_ok or parent not in self.FRAMES:
            raise LookupError('"%s" passed to lookupTransform argument target_frame does not '
                              'exist' % parent)
        pose = self.pose
        if stamp is not None:
            older = [p for t, p in self.history if t <= stamp + 1e-9]
            if not older:
                raise LookupError('extrapolation into the past: %.3f' % stamp)
            pose = older[-1]
        if child == 'base_footprint':
            return pose
        if child == 'base_laser_link':
            return compose(pose, (LASER_OFFSET, 0.0, 0.0))
        raise LookupError('"%s" passed to lookupTransform argument source_frame does not exist'
                          % child)

    @property
    def speed(self):
        """``(v [m/s], w [rad/s])`` of the base now."""
        return self.v, self.w


class FakeCorridorIO:
    """The ``io`` of :class:`tiago_nav.corridor.server.CorridorServer` without ROS: scans, tf and
    commands from and to ``robot`` (a :class:`FakeCorridorRobot`), the goal's feedback, preemption
    and end on ``server`` (a :class:`tiago_nav_tools.testing.fakes.FakeActionServer`, which
    records the :class:`~tiago_nav.corridor.server.Feedback` and
    :class:`~tiago_nav.corridor.server.Result` records as given). Each call goes to the robot's or
    server's method as it is at the call, so that a test can replace one."""

    def __init__(self, robot, server):
        self.robot, self.server = robot, server

    def latest_scan(self):
        return self.robot.latest_scan()

    def lookup(self, parent, child, stamp=None):
        return self.robot.lookup(parent, child, stamp)

    def send_cmd(self, v, w):
        self.robot.command(v, w)

    def publish_feedback(self, fb):
        self.server.publish_feedback(fb)

    def preempt_requested(self):
        return self.server.is_preempt_requested()

    def is_active(self):
        return self.server.is_active()

    def finish(self, state, result, text):
        {SUCCEEDED: self.server.set_succeeded, ABORTED: self.server.set_aborted,
         PREEMPTED: self.server.set_preempted}[state](result, text)
