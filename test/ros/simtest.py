"""Shared pieces of the rostests: the set-up of those that run against the simulator (a test
node, the world file every assertion is checked against, the robot's true pose from
/sim/ground_truth), :func:`pose_at` and :class:`LocalisationErrors` (the localisation's
estimates against that truth) and :func:`distinct_states` for the mission tests."""
import bisect
import math
import threading
import time
import unittest

import rospy
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry

from tiago_nav.geometry import wrap_angle
from tiago_nav.ros.conversions import pose_from_msg
from tiago_nav.sim.world import load_world

TIMEOUT = 30.0


class SimTestCase(unittest.TestCase):
    """Joins the simulated world: ``world`` (from ``~world``), ``tf`` and :meth:`base_pose`."""
    node_name = 'sim_test'

    @classmethod
    def setUpClass(cls):
        rospy.init_node(cls.node_name)
        cls.world = load_world(rospy.get_param('~world'))
        cls.tf = tf2_ros.Buffer()
        cls.listener = tf2_ros.TransformListener(cls.tf)
        cls._truth = None
        cls._truth_sub = rospy.Subscriber('/sim/ground_truth', Odometry, cls._on_truth, queue_size=1)
        rospy.wait_for_message('/clock', rospy.AnyMsg, timeout=TIMEOUT)

    @classmethod
    def _on_truth(cls, msg):
        cls._truth = msg

    @classmethod
    def base_pose(cls):
        """Ground-truth pose ``(x, y, yaw)`` of base_footprint in map now: the first
        /sim/ground_truth stamped at or after the current ROS time (tf map -> base_footprint is
        the localisation's estimate). Not simply the latest one received: with the simulator at
        full speed this node's subscriber can be a few steps behind, and a pose from 0.3 s
        before a goal's end (the robot still turning) is not where the goal left it."""
        now = rospy.Time.now()
        deadline = time.monotonic() + TIMEOUT       # wall time: ROS time may stand still
        while (cls._truth is None or cls._truth.header.stamp < now) and not rospy.is_shutdown():
            if time.monotonic() > deadline:
                raise AssertionError('no /sim/ground_truth stamped at or after %.3f s within %g s'
                                     % (now.to_sec(), TIMEOUT))
            time.sleep(0.005)
        return pose_from_msg(cls._truth.pose.pose)


def pose_at(stamps, poses, t, max_gap=math.inf):
    """The pose ``(x, y, yaw)`` at ``t`` [s], interpolated between the two of ``poses`` (at
    the sorted ``stamps`` [s]) around it; None outside them or when they are more than
    ``max_gap`` [s] apart (messages lost in between: the robot may have turned meanwhile)."""
    i = bisect.bisect_left(stamps, t)
    if i < len(stamps) and abs(stamps[i] - t) < 1e-6:
        return poses[i]
    if i == 0 or i >= len(stamps) or stamps[i] - stamps[i - 1] > max_gap:
        return None
    a, b = poses[i - 1], poses[i]
    f = (t - stamps[i - 1]) / (stamps[i] - stamps[i - 1])
    return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]),
            a[2] + f * wrap_angle(b[2] - a[2]))


class LocalisationErrors:
    """Every /amcl_pose estimate against the true pose at its stamp (/sim/ground_truth,
    :func:`pose_at` within ``max_gap`` [s]: a loaded machine drops some ground-truth messages,
    and interpolating a turn over their gap would invent errors), from construction on."""

    max_gap = 0.1

    def __init__(self):
        self.lock = threading.Lock()
        self.truth_t, self.truth_p = [], []
        self.estimates = []
        self._subs = [
            rospy.Subscriber('/sim/ground_truth', Odometry, self._on_truth, queue_size=1000),
            rospy.Subscriber('/amcl_pose', PoseWithCovarianceStamped, self._on_estimate,
                             queue_size=1000)]

    def _on_truth(self, msg):
        with self.lock:
            self.truth_t.append(msg.header.stamp.to_sec())
            self.truth_p.append(pose_from_msg(msg.pose.pose))

    def _on_estimate(self, msg):
        with self.lock:
            self.estimates.append((msg.header.stamp.to_sec(), pose_from_msg(msg.pose.pose)))

    def worst(self):
        """``(position [m], yaw [rad], n)``: the largest errors of the estimates so far that
        the ground truth covers, and how many those are."""
        with self.lock:
            ts, ps, estimates = list(self.truth_t), list(self.truth_p), list(self.estimates)
        pos = yaw = 0.0
        n = 0
        for t, est in estimates:
            truth = pose_at(ts, ps, t, self.max_gap)
            if truth is None:
                continue
            n += 1
            pos = max(pos, math.hypot(est[0] - truth[0], est[1] - truth[1]))
            yaw = max(yaw, abs(wrap_angle(est[2] - truth[2])))
        return pos, yaw, n


def distinct_states(feedbacks):
    """The feedback states in the order they came, each repeat run collapsed to one."""
    out = []
    for f in feedbacks:
        if not out or out[-1] != f.state:
            out.append(f.state)
    return out
