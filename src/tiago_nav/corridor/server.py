"""The corridor_controller node's decisions for one goal, free of ROS: goal checks, the control
loop at ``~control_rate``, sensor freshness, preemption, feedback, the goal's end (stop, wait for
standstill, report) and run-time parameter changes at cycle boundaries. Law:
:mod:`tiago_nav.corridor.law`.

:class:`CorridorServer` talks to the outside through an *io* object (the node
:mod:`tiago_nav.nodes.corridor_controller` wires it to actionlib, tf and the velocity publisher;
the unit tests to fakes):

* ``latest_scan()``: the newest :class:`tiago_nav.scan.Scan`, or None;
* ``lookup(parent, child, stamp=None)``: pose ``(x, y, yaw)`` [m, rad] of ``child`` in ``parent``
  at ROS time ``stamp`` [s] (None: the latest), raising ``LookupError``;
* ``send_cmd(v, w)``: a velocity command to the base [m/s, rad/s];
* ``publish_feedback(feedback)``: a :class:`Feedback`;
* ``preempt_requested()``, ``is_active()`` (the goal has not ended yet);
* ``finish(state, result, text)``: the goal ends with ``state`` (:data:`SUCCEEDED`,
  :data:`ABORTED` or :data:`PREEMPTED`), a :class:`Result` and a status text.

Units: m, rad, s (ROS time), m/s; poses in ``~odom_frame`` unless said otherwise.
"""
import math
from dataclasses import dataclass

from tiago_nav import clock as rclock
# the goal's statuses too (SUCCEEDED for the node's io)
from tiago_nav.corridor.law import (ABORTED, PREEMPTED, SUCCEEDED,  # noqa: F401
                                    CorridorFollower, CorridorParams, GoalJudge)
from tiago_nav.motion import MotionMonitor, wait_until_still
from tiago_nav.params import ParamChanges, ParamError, nested, param, validate

STOP_TIMEOUT = 2.0          # [s] after a stop command, wait at most this long for standstill


@dataclass(frozen=True)
class Feedback:
    """One feedback of a goal: ``distance`` travelled [m]; the distances to the left and right
    walls [m], the lateral offset from the corridor's centre line [m] and the heading error [rad]
    while the walls are known, else 0 (as the message's defaults)."""
    distance: float
    left_distance: float = 0.0
    right_distance: float = 0.0
    lateral_offset: float = 0.0
    heading_error: float = 0.0


@dataclass(frozen=True)
class Result:
    """The result of a goal: ``distance`` travelled [m], the ``reason`` it ended, and
    ``exit_pose`` ``(frame, (x, y, yaw), stamp)`` [m, rad; s ROS time] where the base stands, or
    None when no frame places it."""
    distance: float
    reason: str
    exit_pose: tuple = None


@dataclass(frozen=True)
class Params:
    """The corridor_controller node's private parameters (defaults: config/corridor.yaml).
    Units: m, rad, s (ROS time), m/s.

    The law and its gains are documented in src/tiago_nav/corridor/law.py."""
    law: CorridorParams = nested(CorridorParams)
    control_rate: float = param(20.0, '[Hz, ROS time] commands and feedback', ge=5)
    timeout: float = param(60.0, '[s] abort a goal after this long', gt=0)
    blocked_timeout: float = param(2.0, '[s] abort when blocked ahead for this long', gt=0)
    sensor_timeout: float = param(0.5, '[s] stop the base while the newest usable scan is older '
                                       'than this', gt=0)
    scan_timeout: float = param(1.0, '[s] abort when the newest usable scan is older than this '
                                     '(> sensor_timeout)', gt=0)
    startup_timeout: float = param(30.0, '[s wall] at start-up, wait this long for the first scan '
                                         'and the tf, else exit 1', gt=0)
    scan_topic: str = param('/scan', 'sensor_msgs/LaserScan input', nonempty=True)
    cmd_vel_topic: str = param('/mobile_base_controller/cmd_vel', 'geometry_msgs/Twist output',
                               nonempty=True)
    odom_frame: str = param('odom', 'fixed frame the corridor is tracked in', nonempty=True)
    base_frame: str = param('base_footprint', 'the robot base frame', nonempty=True)
    map_frame: str = param('map', 'frame of the result\'s exit_pose (odom when unavailable)',
                           nonempty=True)

    def __post_init__(self):
        validate(self)
        if self.scan_timeout <= self.sensor_timeout:
            raise ParamError('must be > sensor_timeout (%g s): the base stops first, then the goal '
                             'aborts' % self.sensor_timeout, 'scan_timeout')


class CorridorServer:
    """The execute loop of the corridor_controller action server, for one goal at a time.

    Args:
        params: :class:`Params`.
        clock: a :mod:`tiago_nav.clock` clock (ROS time).
        io: the goal's inputs and outputs (see the module docstring).
        participant: the lockstep participant (``enabled``, ``tick``, ``reason``,
            ``wait_until_still``) that paces the loop; None: a :class:`Ticker` per goal. The
            node claims the goal's cycles for it before :meth:`execute` and releases them after.

    ``changes`` (:class:`tiago_nav.params.ParamChanges`) takes run-time changes of the
    parameters (dynamic_reconfigure): during a goal they come in force at the boundary between
    two control cycles (after a tick, before the cycle's scan and command), never within one.
    """

    def __init__(self, params, clock, io, participant=None):
        self.p, self.clock, self.io = params, clock, io
        self.participant = participant
        self.follower = None
        self.changes = ParamChanges(params, self._apply)

    def _apply(self, params):
        """Put ``params`` in force (:attr:`changes` calls it between cycles or while idle)."""
        self.p = params
        if self.follower is not None:
            self.follower.reconfigure(params.law)

    # --- outputs ------------------------------------------------------------------------------
    def publish(self, v=0.0, omega=0.0):
        self.io.send_cmd(float(v), float(omega))

    def stop(self):
        self.publish(0.0, 0.0)

    def feedback(self, follower, cmd):
        if math.isfinite(cmd.lateral_offset):   # walls known (not searching, scan usable)
            fb = Feedback(follower.travelled, cmd.left_distance, cmd.right_distance,
                          cmd.lateral_offset, cmd.heading_error)
        else:
            fb = Feedback(follower.travelled)
        self.io.publish_feedback(fb)

    def result(self, follower, reason):
        """The :class:`Result`: distance travelled and where the base stands (``~map_frame``,
        else ``~odom_frame``, else no pose)."""
        exit_pose = None
        for frame in (self.p.map_frame, self.p.odom_frame):
            try:
                pose = self.io.lookup(frame, self.p.base_frame)
            except LookupError:
                continue
            exit_pose = (frame, pose, self.clock.now())
            break
        return Result(follower.travelled if follower else 0.0, reason, exit_pose)

    # --- the goal -----------------------------------------------------------------------------
    def base_pose(self):
        """The base's latest odom pose, or None when tf has none."""
        try:
            return self.io.lookup(self.p.odom_frame, self.p.base_frame)
        except LookupError:
            return None

    def finish(self, follower, state, reason):
        """End the goal: stop the base, wait until it stands still, then report ``state``
        (SUCCEEDED, ABORTED or PREEMPTED) with ``reason`` as result and status text."""
        self.stop()
        monitor = MotionMonitor(window=0.2, speed_threshold=0.02, turn_threshold=0.02)
        if self.participant is not None:        # stops on cycles (its cmd_vel is ignored)
            self.participant.wait_until_still(self.base_pose, self.stop, monitor, STOP_TIMEOUT)
        else:
            wait_until_still(self.clock, self.base_pose, self.stop, monitor, STOP_TIMEOUT,
                             stall=rclock.STALL)
        pose = self.base_pose()
        if follower is not None and pose is not None:
            follower.moved_to(pose)             # the braking distance counts too
        self.io.finish(state, self.result(follower, reason), reason)

    def execute(self, max_speed, max_distance):
        """Runs a goal (``max_speed`` [m/s], ``max_distance`` [m]; 0: the defaults) to its end.
        An unexpected error stops the base and aborts the goal with the error's type and
        text."""
        follower = None
        self.changes.begin()        # from here on, changes wait for a cycle boundary
        try:
            if not (math.isfinite(max_speed) and max_speed >= 0
                    and math.isfinite(max_distance) and max_distance >= 0):
                self.finish(None, ABORTED, 'invalid goal: max_speed and max_distance must be >= 0')
                return
            follower = self.follower = CorridorFollower(self.p.law, max_speed or None,
                                                        max_distance or None)
            self.finish(follower, *self.run(follower))
        except Exception as e:           # noqa: BLE001  (any error ends the goal, loudly)
            self.crashed(follower, '%s: %s' % (type(e).__name__, e))
        finally:
            self.stop()
            self.follower = None
            self.changes.end()

    def crashed(self, follower, reason):
        """End the goal after an unexpected error: ABORTED with ``reason``, even when reporting
        where the robot stands fails too."""
        self.stop()
        if not self.io.is_active():
            return
        try:
            self.finish(follower, ABORTED, reason)
        except Exception:                # noqa: BLE001
            if self.io.is_active():
                self.io.finish(ABORTED, Result(0.0, reason), reason)

    def run(self, follower):
        """Drive until the goal ends; returns ``(state, reason)``.

        Each tick: the newest scan (once, when it is new and tf places it) updates the law; the
        base's latest odom pose gives the command. The base is held still while the newest usable
        scan is older than ``sensor_timeout``; the goal aborts when it is older than
        ``scan_timeout``, when the base's pose is unknown that long, on ``timeout``, when the
        law fails or stays blocked longer than ``blocked_timeout``, and when ROS time stops with
        its source dead (a slow simulator is waited for)."""
        p = self.p
        judge = GoalJudge(p.blocked_timeout)
        ticker = self.participant or rclock.Ticker(self.clock, 1.0 / p.control_rate)
        if self.participant is not None and self.participant.enabled:
            if not ticker.tick():
                return self.stopped(ticker)     # lockstep: the goal starts at its first cycle
            self.changes.boundary()
        start = self.clock.now()
        used, tf_error, no_pose_since = None, '', None
        while True:
            if self.io.preempt_requested():
                return PREEMPTED, 'cancelled'
            now = self.clock.now()
            if now - start > p.timeout:
                return ABORTED, 'timeout after %.0f s' % p.timeout
            scan = self.io.latest_scan()
            if scan is not None and (used is None or scan.stamp != used):
                try:
                    laser = self.io.lookup(p.odom_frame, scan.frame_id, scan.stamp)
                    base = self.io.lookup(p.odom_frame, p.base_frame, scan.stamp)
                    follower.update_laser(scan, laser, base)
                    used, tf_error = scan.stamp, ''
                except LookupError as e:
                    tf_error = ' (the newest scan has no tf: %s)' % e   # retried at the next tick
            age = now - (start if used is None else min(used, now))
            if age > p.scan_timeout:
                return ABORTED, 'no laser data for %.1f s%s' % (age, tf_error)
            try:
                pose, no_pose_since = self.io.lookup(p.odom_frame, p.base_frame), None
            except LookupError as e:
                pose, no_pose_since = None, now if no_pose_since is None else no_pose_since
                if now - no_pose_since > p.scan_timeout:
                    return ABORTED, 'no tf %s -> %s for %.1f s: %s' % (
                        p.odom_frame, p.base_frame, now - no_pose_since, e)
            if pose is None:
                self.stop()
            else:
                cmd = follower.command(pose)
                end = judge.judge(cmd, now)
                if end is not None:
                    return end
                if age > p.sensor_timeout:
                    self.stop()                 # blind: hold still until a fresh scan
                else:
                    self.publish(cmd.v, cmd.omega)
                self.feedback(follower, cmd)
            if not ticker.tick():
                return self.stopped(ticker)
            self.changes.boundary()

    def stopped(self, ticker):
        """``(ABORTED, reason)`` when the loop gets no next cycle: shutting down, or ROS time
        stopped with its source dead (``ticker.reason`` names why)."""
        return ABORTED, ('node shutting down' if self.clock.shutdown()
                         else ticker.reason or 'ROS time stopped advancing')
