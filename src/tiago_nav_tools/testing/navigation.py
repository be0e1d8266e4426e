"""The navigation closed loop without ROS: :class:`tiago_nav.nav.runner.GoalRunner` (the code
the ``move_base`` node runs per goal) drives :class:`tiago_nav.sim.simulator.Simulator` in
simulated time, for the unit tests and bench/bench_navigation.py.

Ground truth is the simulator's: its pose (map frame) and its contact count. Scans reach the
navigator as the node's scan callback would deliver them (laser pose at the scan's time);
``scan_filter`` and ``laser_dead`` inject laser faults. The runner sees the robot as the node
does through tf: the newest odometry (published at the simulator's ``odom_rate``) after the
simulator's map -> odom, stamped with the odometry's time; ``pose_lost`` takes that transform
away (the node then fails with :class:`PoseUnavailable`). Goals in a frame other than the map
(or odom, which the simulator publishes) are rejected with the node's :class:`GoalError`.
"""
import math

import numpy as np

from tiago_nav.geometry import compose, inverse, wrap_angle, yaw_to_quaternion
from tiago_nav.nav.costmap import MapScan
from tiago_nav.nav.navigator import NavConfig, Navigator
from tiago_nav.nav.runner import (ABORTED, PREEMPTED, SUCCEEDED, GoalError, GoalRunner,
                                  PoseUnavailable, frame_or, no_transform)
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.walkers import LEG_RADIUS
from tiago_nav_tools.evaluate.ghosts import seen_free as seen_free_by
from tiago_nav_tools.testing.fakes import FakeActionServer

EPS = 1e-9     # [s] now() runs this far ahead so that a Ticker's summed periods land on steps
MAP, ODOM, BASE = 'map', 'odom', 'base_footprint'   # the node's frames (its defaults)


class SimClock:
    """A :mod:`tiago_nav.clock` clock whose time is the simulator's: ``sleep(dt)`` steps the
    simulator until its time reaches the sleeper's target, calling ``on_step(scan_due,
    odom_due)`` after each step. ``stalled``: time stands still (a slow simulator; with
    ``dead``, the reason ``source_dead()`` gives, a dead one); ``shutdown_at``: ROS time at
    which ``shutdown()`` turns True."""

    def __init__(self, sim, on_step):
        self.sim, self.on_step = sim, on_step
        self.w = 0.0
        self.target = sim.time
        self.stalled = False
        self.dead = ''
        self.shutdown_at = None

    def source_dead(self):
        """``dead``: ``''`` (a stalled clock then stands for a slow simulator) or the reason
        its source is dead."""
        return self.dead

    def now(self):
        return self.sim.time + EPS

    def wall(self):
        return self.w

    def sleep(self, dt):
        self.w += dt
        if self.stalled:
            return
        self.target = max(self.target, self.sim.time) + dt
        while self.sim.time + EPS < self.target:
            self.on_step(*self.sim.step())

    def shutdown(self):
        return self.shutdown_at is not None and self.sim.time >= self.shutdown_at


class SimIO:
    """The runner's io over the simulator; the goal's terminal state goes to ``server`` (a
    :class:`~tiago_nav_tools.testing.fakes.FakeActionServer`)."""

    def __init__(self, loop):
        self.loop = loop
        self.clock = loop.clock
        self.server = None
        self.cmds, self.plans, self.feedback = [], [], []

    def pose(self):
        """The node's pose: the newest odometry in map, at its stamp; :class:`PoseUnavailable`
        in the node's words while ``loop.pose_lost``."""
        if self.loop.pose_lost:
            raise no_transform(PoseUnavailable, MAP, BASE, 'Lookup would require extrapolation '
                               'into the future (the transform stopped coming)')
        return self.loop.odom

    def to_map(self, frame, pose):
        """The node's goal frames: the map (also ``''`` and ``/map``) as it is, ``odom``
        through the simulator's map -> odom; any other frame a :class:`GoalError` in the node's
        words."""
        frame = frame_or(frame, MAP)
        if frame == MAP:
            return pose
        if frame == ODOM:
            return compose(self.loop.sim.map_to_odom, pose)
        raise no_transform(GoalError, frame, MAP, '"%s" passed to lookupTransform argument '
                           'target_frame does not exist. ' % frame)

    def send_cmd(self, v, w):
        self.cmds.append((self.loop.sim.time, v, w))
        self.loop.sim.command(v, w)

    def publish_plan(self, path):
        self.plans.append(path)

    def publish_feedback(self, pose):
        self.feedback.append((self.loop.sim.time, pose))

    def preempt_requested(self):
        return self.server.is_preempt_requested()

    def finish(self, status, text):
        {SUCCEEDED: self.server.set_succeeded, ABORTED: self.server.set_aborted,
         PREEMPTED: self.server.set_preempted}[status](None, text)


def ghost_ages(costmap, scan, seen_free):
    """The oldest ghost [s] after ``scan`` went into ``costmap``: a cell the laser marked
    that a scan saw free where the costmap would clear it
    (:func:`tiago_nav_tools.evaluate.ghosts.seen_free`) is a ghost from that scan's stamp on,
    for as long as it stays marked. ``seen_free`` (cell -> stamp) carries the ghosts from scan
    to scan."""
    rc = np.argwhere(costmap.obstacles)
    marked = set(map(tuple, rc))
    for cell in list(seen_free):
        if cell not in marked:
            del seen_free[cell]
    if len(rc):
        xy = costmap.grid.cell_to_world(rc)
        free = seen_free_by(scan, xy, costmap.resolution, costmap.raytrace_range)
        for cell in map(tuple, rc[free]):
            seen_free.setdefault(cell, scan.stamp)
    return max((scan.stamp - t for t in seen_free.values()), default=0.0)


class ClosedLoop:
    """A navigator, its goal runner and the simulator in one world. ``config``: the
    :class:`NavConfig`; ``period``: control period [s]; ``laser``: the simulator's
    :class:`tiago_nav.sim.laser.LaserModel` (default: the library's, ``ideal``)."""

    def __init__(self, world, config=None, seed=3, start=None, period=0.1, laser=None):
        self.world = world
        sim_config = SimConfig(seed=seed) if laser is None else SimConfig(seed=seed, laser_model=laser)
        self.sim = Simulator(world, sim_config, start_pose=start)
        self.grid = rasterise_world(world)
        self.nav = Navigator(self.grid, config or NavConfig())
        self.clock = SimClock(self.sim, self._on_step)
        self.io = SimIO(self)
        self.runner = GoalRunner(self.nav, self.io, period)
        self.scan_filter = None     # ranges -> ranges (fault injection); None: pass through
        self.laser_dead = False     # no scans at all
        self.pose_lost = False      # no transform map -> base_footprint (io.pose() fails)
        self.odom = None            # (pose in map, stamp) of the newest odometry
        self.odometry()
        self.on_control = []        # hooks called after every simulator step
        self.last_scan = None       # the MapScan the navigator was given last
        self.scan()

    def scan(self):
        """Give the navigator one scan from the current pose."""
        if self.laser_dead:
            return
        laser = self.sim.config.laser
        ranges = self.sim.scan()
        if self.scan_filter is not None:
            ranges = self.scan_filter(np.array(ranges, dtype=float))
        self.last_scan = MapScan(self.sim.scene.laser_pose(), ranges, laser.angle_min,
                                 laser.angle_increment, laser.range_min, laser.range_max,
                                 self.sim.time, compose(inverse(self.sim.pose),
                                                        self.sim.scene.laser_pose()))
        self.nav.add_scan(self.last_scan)

    def odometry(self):
        """The odometry the node would receive now, placed in the map as it places it."""
        self.odom = (compose(self.sim.map_to_odom, self.sim.odom_pose), self.sim.time)

    def _on_step(self, scan_due, odom_due=False):
        if odom_due:
            self.odometry()
        if scan_due:
            self.scan()
        for hook in self.on_control:
            hook()

    def run_goal(self, goal, limit=60.0, frame=MAP):
        """Run one goal ``(x, y, yaw)`` in ``frame`` (the map by default) to its end or for at most ``limit`` [s] of
        simulated time (then it is preempted and reported as ``'timeout'``). Returns a dict:
        ``state`` (``'succeeded'``, ``'aborted'``, ``'preempted'``, ``'timeout'``), ``reason``,
        ``pose`` (true, at the end), ``collisions`` (during the goal), ``time`` [s],
        ``trail`` (poses per simulator step), ``t_xy`` (time to within 0.15 m, or None),
        ``closest`` (smallest gap [m] to a movable obstacle), ``closest_walker`` (smallest gap
        [m] between the base's footprint and a walker's leg), ``waiting`` (simulated time [s]
        the base stood still, under 0.02 m/s and 0.02 rad/s, farther than 0.15 m from the
        goal), ``ghost_age`` (the longest
        time [s] a cell the laser marked stayed marked after a scan saw it free:
        :meth:`tiago_nav.nav.costmap.MapScan.seen_beyond` its centre)."""
        t0, c0 = self.sim.time, self.sim.collisions
        self.io.server = FakeActionServer(self.clock, preempt_at=t0 + limit)
        trail, closest, t_xy = [self.sim.pose], [math.inf], [None]
        people = dict(closest=math.inf, waiting=0.0, ghost_age=0.0, last=self.sim.time)
        seen_free = {}      # marked cell -> the time a scan first saw it free
        radius = self.sim.config.robot_radius

        def track():
            p = self.sim.pose
            trail.append(p)
            for c in self.world.movable_obstacles:
                closest[0] = min(closest[0], float(c.distance(p[0], p[1])))
            if t_xy[0] is None and math.hypot(p[0] - goal[0], p[1] - goal[1]) <= 0.15:
                t_xy[0] = self.sim.time - t0
            walkers = self.sim.walkers
            for i in range(len(walkers)):
                legs = walkers.legs(i)
                gap = np.hypot(legs[:, 0] - p[0], legs[:, 1] - p[1]) - radius - LEG_RADIUS
                people['closest'] = min(people['closest'], float(gap.min()))
            dt, people['last'] = self.sim.time - people['last'], self.sim.time
            q = trail[-2]
            if math.hypot(p[0] - q[0], p[1] - q[1]) < 0.02 * dt \
                    and abs(wrap_angle(p[2] - q[2])) < 0.02 * dt \
                    and math.hypot(p[0] - goal[0], p[1] - goal[1]) > 0.15:
                people['waiting'] += dt
            if self.last_scan is not None and self.last_scan is not people.get('scan'):
                people['scan'] = scan = self.last_scan
                people['ghost_age'] = max(people['ghost_age'],
                                          ghost_ages(self.nav.costmap, scan, seen_free))
        self.on_control.append(track)
        try:
            self.runner.run(frame, (goal[0], goal[1], 0.0), yaw_to_quaternion(goal[2]))
        finally:
            self.on_control.remove(track)
        server = self.io.server
        state = server.state
        if state == PREEMPTED and server.is_preempt_requested():
            state = 'timeout'
        return dict(state=state, reason=server.text, pose=self.sim.pose,
                    collisions=self.sim.collisions - c0, time=self.sim.time - t0,
                    trail=np.array(trail)[:, :2], t_xy=t_xy[0], closest=closest[0],
                    closest_walker=people['closest'], waiting=people['waiting'],
                    ghost_age=people['ghost_age'])

    def settle(self, steps=30):
        """Step the simulator with a zero command (let the base come to rest)."""
        self.sim.command(0.0, 0.0)
        for _ in range(steps):
            self._on_step(*self.sim.step())

    def close(self):
        self.sim.close()
