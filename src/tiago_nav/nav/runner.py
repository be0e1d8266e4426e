"""One move_base goal from acceptance to its end, free of ROS: goal checks, the fixed-rate
control loop, sensor freshness, preemption, feedback, plan republishing, and a stop command on
every end.

The runner talks to the outside through an *io* object (the ``move_base`` node wires it to
actionlib, tf and publishers; :mod:`tiago_nav_tools.testing.navigation` to the in-process simulator;
the unit tests to fakes):

* ``clock``: a :mod:`tiago_nav.clock` clock (``now`` in ROS time [s]);
* ``pose()``: ``((x, y, yaw), stamp)`` of base_footprint in ``map`` [m, rad; s], or raises
  :class:`PoseUnavailable`;
* ``to_map(frame, pose)``: a pose ``(x, y, yaw)`` in ``frame`` → ``map``, or raises
  :class:`GoalError`;
* ``send_cmd(v, w)`` [m/s, rad/s], ``publish_plan(path)`` (``(K, 2)`` in map or None),
  ``publish_feedback(pose)``;
* ``preempt_requested()``; ``finish(status, text)`` with status :data:`SUCCEEDED`,
  :data:`ABORTED` or :data:`PREEMPTED` (called exactly once per goal).
"""
import math
import threading

from tiago_nav.clock import Ticker
from tiago_nav.geometry import quaternion_to_yaw
from tiago_nav.goal import ABORTED, ACTIVE, PREEMPTED, SUCCEEDED, GoalError, Outcome  # noqa: F401
from tiago_nav.nav.planner import PlanError


class PoseUnavailable(RuntimeError):
    """The robot's pose cannot be had now (no transform); the message says why."""


def no_transform(error, source, target, why):
    """The ``error`` (:class:`GoalError` for a goal's frame, :class:`PoseUnavailable` for the
    robot's pose) for a missing transform ``source -> target``, ``why`` being tf's reason: one
    wording for the node and the test doubles that stand for it."""
    return error('no transform %s -> %s: %s' % (source, target, why))


def frame_or(frame, map_frame):
    """A goal's frame as the node looks it up: without a leading slash; empty means
    ``map_frame``."""
    return frame.lstrip('/') or map_frame


def goal_pose(position, orientation):
    """A goal's ``position (x, y, z)`` [m] and ``orientation (x, y, z, w)`` quaternion →
    ``(x, y, yaw)``. Raises :class:`GoalError` for a non-finite field or a quaternion that
    cannot be normalised (length about 0)."""
    names = ('position.x', 'position.y', 'position.z', 'orientation.x', 'orientation.y',
             'orientation.z', 'orientation.w')
    values = [float(v) for v in tuple(position) + tuple(orientation)]
    bad = ['%s=%r' % (n, v) for n, v in zip(names, values) if not math.isfinite(v)]
    if bad:
        raise GoalError('goal has a non-finite field (%s)' % ', '.join(bad))
    q = values[3:]
    norm = math.sqrt(sum(v * v for v in q))
    if norm < 1e-3:
        raise GoalError('goal orientation (%g, %g, %g, %g) cannot be normalised (length %.2g): '
                        'give a unit quaternion, e.g. w: 1 for yaw 0' % (*q, norm))
    return values[0], values[1], quaternion_to_yaw(*(v / norm for v in q))


def _fmt(pose):
    return '(%.2f, %.2f, %.0f deg)' % (pose[0], pose[1], math.degrees(pose[2]))


class GoalRunner:
    """Runs goals on a :class:`~tiago_nav.nav.navigator.Navigator` through ``io`` (see the
    module docstring) at ``period`` [s] of ROS time. ``lock`` guards the navigator against the
    scan callback; ``log(level, text)`` with level ``'info'`` or ``'warn'``.

    ``ticker``: the node's cycle source shared by every goal (a lockstep participant, with
    ``tick()`` like :class:`~tiago_nav.clock.Ticker`); a goal then starts at its first cycle,
    so that its plan and first command use that cycle's pose and scans, and each cycle calls
    ``io.sense()`` (if the io has it) to take them in. None: a :class:`Ticker` per goal,
    starting at once.

    ``changes``: the node's :class:`tiago_nav.params.ParamChanges` (dynamic_reconfigure), told
    when a goal's cycles begin and end and called at each boundary between two cycles, so that
    a change comes in force between cycles, never within one.
    """

    def __init__(self, nav, io, period, lock=None, log=None, ticker=None, changes=None):
        self.nav, self.io, self.period = nav, io, float(period)
        self.lock = lock or threading.Lock()
        self.log = log or (lambda level, text: None)
        self.ticker = ticker
        self.changes = changes

    def run(self, frame, position, orientation):
        """Run one goal (``frame`` of the pose, ``position``, ``orientation`` quaternion) to its
        end; returns the :class:`Outcome` it reported through ``io.finish``."""
        try:
            return self._run(frame, position, orientation)
        except Exception as e:         # a bug or a broken io: still stop and say what happened
            return self._end(ABORTED, 'unexpected error: %s: %s' % (type(e).__name__, e))

    def _end(self, status, text):
        """Reports the outcome, then sends the stop command. In that order: in lockstep the
        stop command answers the cycle, after which simulated time may move on, and the result
        would carry the stamp of whichever time this node had seen by then."""
        with self.lock:
            self.nav.cancel()
        self.log('info' if status == SUCCEEDED else 'warn', 'goal %s: %s' % (status, text))
        self.io.finish(status, text)
        self.io.send_cmd(0.0, 0.0)
        if self.changes is not None:
            self.changes.end()
        return Outcome(status, text)

    def _tick(self, ticker):
        """The next cycle; the text of the abort when there is none (shutting down, or ROS time
        stopped with its source dead: the ticker's ``reason``), else ''."""
        if ticker.tick():
            if self.changes is not None:
                self.changes.boundary()
            getattr(self.io, 'sense', lambda: None)()
            return ''
        return 'node shutting down' if self.io.clock.shutdown() else \
            getattr(ticker, 'reason', '') or 'ROS time stopped advancing'

    def _run(self, frame, position, orientation):
        io, nav = self.io, self.nav
        clock = io.clock
        ticker = self.ticker or Ticker(clock, self.period)
        if self.changes is not None:
            self.changes.begin()
        stopped = self._tick(ticker) if self.ticker is not None else ''
        if stopped:
            return self._end(ABORTED, stopped)
        try:
            target = io.to_map(frame, goal_pose(position, orientation))
            pose, _ = io.pose()
            with self.lock:
                path = nav.start(target, pose, clock.now())
        except (GoalError, PlanError, PoseUnavailable) as e:
            return self._end(ABORTED, 'goal rejected: %s' % e)
        self.log('info', 'goal %s in map' % _fmt(target))
        io.publish_plan(path)
        watch = SensorWatch(nav.cfg, clock.now())
        while True:
            if io.preempt_requested():
                return self._end(PREEMPTED, 'preempted')
            t = clock.now()
            try:
                pose, stamp = io.pose()
                watch.pose_seen(stamp)
            except PoseUnavailable as e:
                pose = None
                watch.pose_error = str(e)
            stale, fatal = watch.check(t, nav.scan_stamp)
            if fatal:
                return self._end(ABORTED, fatal)
            lost = watch.lost(t, getattr(io, 'localisation_lost', lambda: '')())
            if lost and t - watch.lost_since > nav.cfg.localisation_patience:
                return self._end(ABORTED, 'localisation lost for %.1f s (longer than '
                                 'localisation_patience): %s' % (t - watch.lost_since, lost))
            if lost and not stale:
                stale = 'localisation lost: %s; waiting for it to relocalise' % lost
                if watch.lost_since == t:
                    self.log('warn', 'base stopped: %s' % stale)
            if stale:
                io.send_cmd(0.0, 0.0)
                with self.lock:
                    nav.hold(t)
                if watch.stale_cycles == 1:
                    self.log('warn', 'base stopped: %s' % stale)
            else:
                with self.lock:
                    v, w, state, reason = nav.step(pose, t, self.period)
                    new_path = nav.path
                if state != ACTIVE:
                    return self._end(state, reason)
                io.send_cmd(v, w)
                if new_path is not path:
                    io.publish_plan(new_path)
                    path = new_path
            if pose is not None:
                io.publish_feedback(pose)
            stopped = self._tick(ticker)
            if stopped:
                return self._end(ABORTED, stopped)


class SensorWatch:
    """Freshness of the laser and the pose during one goal (``NavConfig.sensor_timeout`` and
    ``sensor_abort_timeout``, ROS time [s]). A sensor not seen yet during the goal counts from
    the goal's start ``t0``."""

    def __init__(self, cfg, t0):
        self.cfg, self.t0 = cfg, t0
        self.pose_stamp = None
        self.pose_error = ''
        self.stale_cycles = 0
        self.lost_since = None      # [s] ROS time since when the localisation says it is lost

    def lost(self, t, reason):
        """The localisation's word at ``t``: ``reason`` ('' when not lost); keeps
        :attr:`lost_since`."""
        if not reason:
            self.lost_since = None
        elif self.lost_since is None:
            self.lost_since = t
        return reason

    def pose_seen(self, stamp):
        self.pose_stamp, self.pose_error = stamp, ''

    def check(self, t, scan_stamp):
        """``(stale, fatal)``: a sentence when the newest scan or pose is older than
        ``sensor_timeout`` or the pose is missing now (the base must stop), and one when a
        sensor has stayed older than ``sensor_abort_timeout`` for two cycles in a row (the goal
        aborts); '' otherwise."""
        cfg = self.cfg
        scan_age = t - (self.t0 if scan_stamp is None else scan_stamp)
        pose_age = t - (self.t0 if self.pose_stamp is None else self.pose_stamp)
        items = []
        if scan_age > cfg.sensor_timeout:
            items.append(('no laser data for %.1f s' % scan_age, scan_age))
        if self.pose_error or pose_age > cfg.sensor_timeout:
            items.append(('no odometry/pose for %.1f s%s' % (
                pose_age, ' (%s)' % self.pose_error if self.pose_error else ''), pose_age))
        if not items:
            self.stale_cycles = 0
            return '', ''
        self.stale_cycles += 1
        fatal = [text for text, age in items if age > cfg.sensor_abort_timeout]
        return '; '.join(text for text, _ in items), \
            '; '.join(fatal) if fatal and self.stale_cycles >= 2 else ''
