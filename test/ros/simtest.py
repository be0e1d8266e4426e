"""Shared pieces of the rostests: the set-up of those that run against the simulator (a test
node, the world file every assertion is checked against, the robot's true pose from
/sim/ground_truth) and :func:`distinct_states` for the mission tests."""
import time
import unittest

import rospy
import tf2_ros
from nav_msgs.msg import Odometry

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


def distinct_states(feedbacks):
    """The feedback states in the order they came, each repeat run collapsed to one."""
    out = []
    for f in feedbacks:
        if not out or out[-1] != f.state:
            out.append(f.state)
    return out
