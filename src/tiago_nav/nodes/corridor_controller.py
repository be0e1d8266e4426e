"""Action server ``corridor_controller`` (tiago_nav/CorridorAction): drives the narrow corridor
ahead from the laser alone (no map, no plan) and stops at its end. Law: :mod:`tiago_nav.corridor.law`;
the goal's decisions: :class:`tiago_nav.corridor.server.CorridorServer`.

Subscribes ``~scan_topic``; publishes ``~cmd_vel_topic``; uses tf ``~odom_frame`` ->
``~base_frame`` and -> the scan's frame (``~map_frame`` for the result's exit pose). Feedback at
``~control_rate``; SUCCEEDED at the corridor's end (or after the goal's max_distance), ABORTED
with the reason, PREEMPTED on cancel. The base is told to stop whenever a goal ends.

This module is the node's wiring: :class:`RosIO` converts between ROS (the action server, the
scan subscription, tf, the velocity publisher) and the plain values and records the decisions
work with (:mod:`tiago_nav.corridor.server`); :func:`build` and :func:`main` put the node
together.

Under ``/use_lockstep`` the control loop is a lockstep participant
(:mod:`tiago_nav.ros.lockstep`): each cycle uses exactly the cycle's scan and the pose at the
cycle's odometry stamp, and answers with its command (idle: at once, without one).

Its speed, turn rate and clearances can be changed while it runs (dynamic_reconfigure,
cfg/CorridorController.cfg): during a goal a change comes in force between two control cycles.
"""
import sys
import threading

import rospy
import tf2_ros
from geometry_msgs.msg import Twist
from sensor_msgs.msg import LaserScan

from tiago_nav.corridor.inputs import missing_inputs, wait_ready
from tiago_nav.cfg import CorridorControllerConfig
from tiago_nav.corridor.server import (ABORTED, PREEMPTED, SUCCEEDED, CorridorServer,
                                       Params)  # noqa: F401 (Params: the node's parameters)
from tiago_nav.msg import CorridorAction, CorridorFeedback, CorridorResult
from tiago_nav.ros.clock import RosClock
from tiago_nav.ros.conversions import pose_from_transform, pose_stamped, scan_from_msg
from tiago_nav.ros.lockstep import (ClaimingActionServer, LockstepParticipant, held, held_tf,
                                    ScanCache, goal_since, lookup_at)
from tiago_nav.ros.params import read_or_exit
from tiago_nav.ros import reconfigure
from tiago_nav.ros.tcpros import concurrent_handshakes
from tiago_nav.ros.reset import NodeReset, adopt, persistent
from tiago_nav.ros.topics import Subscription

NODE = 'corridor_controller'


class RosIO:
    """The ROS side of :class:`CorridorServer`'s ``io``: the newest scan from ``~scan_topic``
    and tf lookups (never waiting: a stopped /clock cannot block the loop), the commands as
    geometry_msgs/Twist on ``cmd_pub``, feedback and results as CorridorFeedback and
    CorridorResult on the action ``server``, and :meth:`execute`, the action's execute callback
    (set ``corridor``, ``server`` and ``cmd_pub`` before the first goal).

    With a ``participant`` in lockstep, during a cycle held by the simulator: the cycle's scan
    (stamped the tick's ``scan_stamp``), transforms at exactly their stamp and "the latest" pose
    at the tick's ``odom_stamp``, each waited for while its source lives
    (:func:`~tiago_nav.ros.lockstep.held`); each
    command is the cycle's answer, and a goal's cycles are claimed for it."""

    def __init__(self, params, participant=None):
        self.corridor = self.server = self.cmd_pub = None
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
            msg = self.cache.wait_for_scan(self.participant.scan_stamp, held()) \
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
                tf = lookup_at(self.tf, parent, child, t, held_tf(self.tf, parent, child))
            else:
                tf = self.tf.lookup_transform(parent, child, t, rospy.Duration(0.0))
        except tf2_ros.TransformException as e:
            raise LookupError(str(e)) from None
        return pose_from_transform(tf.transform)

    def send_cmd(self, v, w):
        twist = Twist()
        twist.linear.x, twist.angular.z = float(v), float(w)
        self.cmd_pub.publish(twist)
        if self.participant is not None:
            self.participant.answer(twist)      # this cycle's command, applied at its stamp

    def publish_feedback(self, fb):
        self.server.publish_feedback(CorridorFeedback(
            distance=fb.distance, left_distance=fb.left_distance, right_distance=fb.right_distance,
            lateral_offset=fb.lateral_offset, heading_error=fb.heading_error))

    def preempt_requested(self):
        return self.server.is_preempt_requested()

    def is_active(self):
        return self.server.is_active()

    def finish(self, state, result, text):
        msg = CorridorResult(distance=result.distance, reason=result.reason)
        if result.exit_pose is not None:
            frame, pose, stamp = result.exit_pose
            msg.exit_pose = pose_stamped(pose, frame, rospy.Time.from_sec(stamp))
        {SUCCEEDED: self.server.set_succeeded, ABORTED: self.server.set_aborted,
         PREEMPTED: self.server.set_preempted}[state](msg, text)

    def execute(self, goal):
        """The execute callback: runs ``goal`` (a CorridorGoal) on :attr:`corridor`, its cycles
        claimed by the participant (those after its stamp, however late it arrived)."""
        if self.participant is not None:
            self.participant.claim(goal_since(self.server.current_goal.get_goal_id().stamp,
                                              self.participant.now()))
        try:
            self.corridor.execute(goal.max_speed, goal.max_distance)
        finally:
            if self.participant is not None:
                self.participant.release()


def build(params, server=None):
    """The node's state, a :class:`RosIO` (with a participant, the scan and tf inputs, the
    decisions as ``corridor``), ready as at start, serving goals through ``server`` (an earlier
    state's, kept by a reset) or a new action server. Raises RuntimeError when the inputs do not
    come within ``startup_timeout``."""
    participant = LockstepParticipant(1.0 / params.control_rate)
    io, clock = RosIO(params, participant), RosClock()
    participant.inputs = lambda: not missing_inputs(params, io)
    missing = wait_ready(params, clock, io, params.startup_timeout)
    if missing:
        raise RuntimeError(missing)
    participant.wait_joined(params.startup_timeout)
    io.cmd_pub = rospy.Publisher(params.cmd_vel_topic, Twist, queue_size=1)
    io.corridor = CorridorServer(params, clock, io, participant)
    if server is None:
        with persistent():
            server = ClaimingActionServer(NODE, CorridorAction, io.execute, participant)
        server.start()
    io.server = adopt(server, io.execute, participant)
    return io


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
        io = build(read_or_exit(Params, NODE), server)
        reconfigure.show(dynamic[0] if dynamic else None, io.corridor.p)
        return io
    reset.build = rebuild
    dynamic.append(reconfigure.serve(
        CorridorControllerConfig, Params,
        lambda: reset.state.corridor.changes if reset.state is not None else None, NODE))
    rospy.loginfo('%s ready (max_speed %.2f m/s, look-ahead %.1f m)', NODE,
                  params.law.max_speed, params.law.look_ahead)
    rospy.spin()
