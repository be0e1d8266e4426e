"""Shared pieces of the rostests: the set-up of those that run against the simulator (a test
node, the world file every assertion is checked against, the robot's pose from tf) and
:func:`distinct_states` for the mission tests."""
import unittest

import rospy
import tf2_ros

from tiago_nav.ros.conversions import pose_from_transform
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
        rospy.wait_for_message('/clock', rospy.AnyMsg, timeout=TIMEOUT)

    @classmethod
    def base_pose(cls):
        """Ground-truth pose ``(x, y, yaw)`` of base_footprint in map, the latest tf has."""
        t = cls.tf.lookup_transform('map', 'base_footprint', rospy.Time(), rospy.Duration(TIMEOUT))
        return pose_from_transform(t.transform)


def distinct_states(feedbacks):
    """The feedback states in the order they came, each repeat run collapsed to one."""
    out = []
    for f in feedbacks:
        if not out or out[-1] != f.state:
            out.append(f.state)
    return out
