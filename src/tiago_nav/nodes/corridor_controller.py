"""Action server ``corridor_controller`` (tiago_nav/CorridorAction): drives the narrow corridor
ahead from the laser alone (no map, no plan) and stops at its end. Law: :mod:`tiago_nav.corridor.law`.

Subscribes ``~scan_topic``; publishes ``~cmd_vel_topic``; uses tf ``~odom_frame`` ->
``~base_frame`` and -> the scan's frame (``~map_frame`` for the result's exit pose). Feedback at
``~control_rate``; SUCCEEDED at the corridor's end (or after the goal's max_distance), ABORTED
with the reason, PREEMPTED on cancel. The base is told to stop whenever a goal ends.

:class:`CorridorServer` holds the decisions of one goal and talks to ROS only through the
objects it is given (a clock, the action server, the velocity publisher and a small I/O object:
:class:`RosIO` here, fakes in the unit tests).

Under ``/use_lockstep`` the control loop is a lockstep participant
(:mod:`tiago_nav.ros.lockstep`): each cycle uses exactly the cycle's scan and the pose at the
cycle's odometry stamp, and answers with its command (idle: at once, without one).

Its speed, turn rate and clearances can be changed while it runs (dynamic_reconfigure,
cfg/CorridorController.cfg): during a goal a change comes in force between two control cycles.
"""
import math
import sys
import threading
from dataclasses import dataclass

import rospy
import tf2_ros
from geometry_msgs.msg import Twist
from sensor_msgs.msg import LaserScan

from tiago_nav import clock as rclock
from tiago_nav.corridor.inputs import missing_inputs, wait_ready
from tiago_nav.cfg import CorridorControllerConfig
from tiago_nav.corridor.law import (ABORTED, PREEMPTED, SUCCEEDED, CorridorFollower, CorridorParams,
                                GoalJudge)
from tiago_nav.motion import MotionMonitor, wait_until_still
from tiago_nav.msg import CorridorAction, CorridorFeedback, CorridorResult
from tiago_nav.params import ParamChanges, ParamError, nested, param, validate
from tiago_nav.ros.clock import RosClock
from tiago_nav.ros.conversions import pose_from_transform, pose_stamped, scan_from_msg
from tiago_nav.ros.lockstep import (CYCLE_WAIT, ClaimingActionServer, LockstepParticipant,
                                    ScanCache, goal_since, lookup_at)
from tiago_nav.ros.params import read_or_exit
from tiago_nav.ros import reconfigure
from tiago_nav.ros.tcpros import concurrent_handshakes
from tiago_nav.ros.reset import NodeReset, adopt, persistent
from tiago_nav.ros.topics import Subscription

NODE = 'corridor_controller'
STOP_TIMEOUT = 2.0          # [s] after a stop command, wait at most this long for standstill


@dataclass(frozen=True)
class Params:
    """Defaults of nodes/corridor_controller (private parameters). Units: m, rad, s (ROS time), m/s.

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
    """The execute loop of the action server, for one goal at a time.

    Args:
        params: :class:`Params`.
        clock: a :mod:`tiago_nav.clock` clock (ROS time).
        server: the SimpleActionServer (``is_preempt_requested``, ``publish_feedback``,
            ``set_succeeded/aborted/preempted(result, text)``, ``is_active``).
        cmd_pub: publisher of geometry_msgs/Twist to the base.
        io: ``latest_scan()`` -> the newest :class:`tiago_nav.scan.Scan` or None;
            ``lookup(parent, child, stamp=None)`` -> pose ``(x, y, yaw)`` of ``child`` in
            ``parent`` at ROS time ``stamp`` [s] (None: the latest), raising ``LookupError``.
        participant: the lockstep participant (``tick``, ``answer``, ``claim``, ``release``,
            ``wait_until_still``) that paces the loop; None: a :class:`Ticker` per goal.

    ``changes`` (:class:`tiago_nav.params.ParamChanges`) takes run-time changes of the
    parameters (dynamic_reconfigure): during a goal they come in force at the boundary between
    two control cycles (after a tick, before the cycle's scan and command), never within one.
    """

    def __init__(self, params, clock, server, cmd_pub, io, participant=None):
        self.p, self.clock, self.server, self.cmd_pub, self.io = params, clock, server, cmd_pub, io
        self.participant = participant
        self.follower = None
        self.changes = ParamChanges(params, self._apply)

    def _apply(self, params):
        """Put ``params`` in force (:attr:`changes` calls it between cycles or while idle)."""
        self.p = params
        if self.follower is not None:
            self.follower.reconfigure(params.law)

    # --- ROS messages -------------------------------------------------------------------------
    def publish(self, v=0.0, omega=0.0):
        twist = Twist()
        twist.linear.x, twist.angular.z = float(v), float(omega)
        self.cmd_pub.publish(twist)
        if self.participant is not None:
            self.participant.answer(twist)      # this cycle's command, applied at its stamp

    def stop(self):
        self.publish(0.0, 0.0)

    def feedback(self, follower, cmd):
        fb = CorridorFeedback(distance=follower.travelled)
        if math.isfinite(cmd.lateral_offset):   # walls known (not searching, scan usable)
            fb.left_distance, fb.right_distance = cmd.left_distance, cmd.right_distance
            fb.lateral_offset, fb.heading_error = cmd.lateral_offset, cmd.heading_error
        self.server.publish_feedback(fb)

    def result(self, follower, reason):
        """The CorridorResult: distance travelled and where the base stands (``~map_frame``, else
        ``~odom_frame``, else no pose)."""
        res = CorridorResult(distance=follower.travelled if follower else 0.0, reason=reason)
        for frame in (self.p.map_frame, self.p.odom_frame):
            try:
                pose = self.io.lookup(frame, self.p.base_frame)
            except LookupError:
                continue
            res.exit_pose = pose_stamped(pose, frame, rospy.Time.from_sec(self.clock.now()))
            break
        return res

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
        result = self.result(follower, reason)
        {SUCCEEDED: self.server.set_succeeded, ABORTED: self.server.set_aborted,
         PREEMPTED: self.server.set_preempted}[state](result, reason)

    def execute(self, goal):
        """The execute callback: runs ``goal`` (a CorridorGoal) to its end. An unexpected error
        stops the base and aborts the goal with the error's type and text."""
        follower = None
        if self.participant is not None:
            # the goal's cycles are those after its stamp, however late it arrived
            self.participant.claim(goal_since(self.server.current_goal.get_goal_id().stamp,
                                              self.participant.now()))
        self.changes.begin()        # from here on, changes wait for a cycle boundary
        try:
            if not (math.isfinite(goal.max_speed) and goal.max_speed >= 0
                    and math.isfinite(goal.max_distance) and goal.max_distance >= 0):
                self.finish(None, ABORTED, 'invalid goal: max_speed and max_distance must be >= 0')
                return
            follower = self.follower = CorridorFollower(self.p.law, goal.max_speed or None,
                                                        goal.max_distance or None)
            self.finish(follower, *self.run(follower))
        except Exception as e:           # noqa: BLE001  (any error ends the goal, loudly)
            self.crashed(follower, '%s: %s' % (type(e).__name__, e))
        finally:
            self.stop()
            self.follower = None
            self.changes.end()
            if self.participant is not None:
                self.participant.release()

    def crashed(self, follower, reason):
        """End the goal after an unexpected error: ABORTED with ``reason``, even when reporting
        where the robot stands fails too."""
        self.stop()
        if not self.server.is_active():
            return
        try:
            self.finish(follower, ABORTED, reason)
        except Exception:                # noqa: BLE001
            if self.server.is_active():
                self.server.set_aborted(CorridorResult(reason=reason), reason)

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
            if self.server.is_preempt_requested():
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


class RosIO:
    """The ROS side of :class:`CorridorServer`'s ``io``: the newest scan from ``~scan_topic``
    and tf lookups (never waiting: a stopped /clock cannot block the loop).

    With a ``participant`` in lockstep, during a cycle held by the simulator: the cycle's scan
    (stamped the tick's ``scan_stamp``), transforms at exactly their stamp and "the latest" pose
    at the tick's ``odom_stamp``, each waited for up to :data:`CYCLE_WAIT` wall seconds."""

    def __init__(self, params, participant=None):
        self.tf = tf2_ros.Buffer(rospy.Duration(10.0))
        self.listener = tf2_ros.TransformListener(self.tf)
        self.lock = threading.Lock()
        self.scan = None
        self.participant = participant
        self.cache = None
        if participant is not None and participant.enabled:
            self.cache = ScanCache(params.scan_topic, size=8)
        else:
            Subscription(params.scan_topic, LaserScan, self.on_scan, queue_size=1)

    def _held(self):
        return self.cache is not None and self.participant.lockstep

    def on_scan(self, msg):
        scan = scan_from_msg(msg)
        with self.lock:
            # the newest by stamp; an older stamp only after ROS time went back (a restart)
            if self.scan is None or scan.stamp >= self.scan.stamp \
                    or rospy.get_time() < self.scan.stamp:
                self.scan = scan

    def latest_scan(self):
        if self.cache is not None:
            msg = self.cache.wait_for_scan(self.participant.scan_stamp, CYCLE_WAIT) \
                if self._held() else self.cache.latest()
            return None if msg is None else scan_from_msg(msg)
        with self.lock:
            return self.scan

    def lookup(self, parent, child, stamp=None):
        held = self._held()
        if held and stamp is None:
            t = self.participant.odom_stamp
        else:
            t = rospy.Time(0) if stamp is None else rospy.Time.from_sec(stamp)
        try:
            if held:
                tf = lookup_at(self.tf, parent, child, t, CYCLE_WAIT)
            else:
                tf = self.tf.lookup_transform(parent, child, t, rospy.Duration(0.0))
        except tf2_ros.TransformException as e:
            raise LookupError(str(e)) from None
        return pose_from_transform(tf.transform)


def build(params, server=None):
    """The node's state (a participant, the scan and tf inputs, the execute loop), ready as at
    start, serving goals through ``server`` (an earlier state's, kept by a reset) or a new
    action server. Raises RuntimeError when the inputs do not come within ``startup_timeout``."""
    participant = LockstepParticipant(1.0 / params.control_rate)
    io, clock = RosIO(params, participant), RosClock()
    participant.inputs = lambda: not missing_inputs(params, io)
    missing = wait_ready(params, clock, io, params.startup_timeout)
    if missing:
        raise RuntimeError(missing)
    participant.wait_joined(params.startup_timeout)
    cmd_pub = rospy.Publisher(params.cmd_vel_topic, Twist, queue_size=1)
    node = CorridorServer(params, clock, None, cmd_pub, io, participant)
    if server is None:
        with persistent():
            server = ClaimingActionServer(NODE, CorridorAction, node.execute, participant)
        server.start()
    node.server = adopt(server, node.execute, participant)
    return node


def main():
    concurrent_handshakes()
    rospy.init_node(NODE)
    params = read_or_exit(Params, NODE)
    try:
        reset = NodeReset(lambda: build(params))
    except RuntimeError as e:
        rospy.logfatal('%s: %s; not starting the action server', NODE, e)
        sys.exit(1)
    server = reset.state.server
    dynamic = []        # the dynamic_reconfigure server, made once

    def rebuild():
        """A reset: the parameters as they are now, the same action server."""
        node = build(read_or_exit(Params, NODE), server)
        reconfigure.show(dynamic[0] if dynamic else None, node.p)
        return node
    reset.build = rebuild
    dynamic.append(reconfigure.serve(CorridorControllerConfig, Params,
                                     lambda: getattr(reset.state, 'changes', None), NODE))
    rospy.loginfo('%s ready (max_speed %.2f m/s, look-ahead %.1f m)', NODE,
                  params.law.max_speed, params.law.look_ahead)
    rospy.spin()
