#!/usr/bin/python3
"""Rostest of nodes/corridor_controller with a cylinder inside the corridor (world file ground
truth): the goal ABORTS with "blocked ahead", the robot stops in front of it without contact."""
import math

import actionlib
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from std_msgs.msg import UInt32

from tiago_nav.msg import CorridorAction, CorridorGoal
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.ros.actions import wait_server

from simtest import SimTestCase

TIMEOUT = 30.0


class CorridorBlockedTest(SimTestCase):
    node_name = 'test_corridor_blocked'

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.client = actionlib.SimpleActionClient('corridor_controller', CorridorAction)
        assert wait_server(cls.client, TIMEOUT), 'no corridor_controller server'

    def test_blocked_ahead_aborts_before_the_obstacle(self):
        self.client.send_goal(CorridorGoal())
        self.assertTrue(self.client.wait_for_result(rospy.Duration(40.0)), 'no result in 40 s')
        self.assertEqual(self.client.get_state(), GoalStatus.ABORTED)
        result = self.client.get_result()
        self.assertIn('blocked ahead', result.reason)
        rospy.sleep(1.0)
        x, y, _ = self.base_pose()
        obstacle = self.world.movable_obstacles[0]
        gap = math.hypot(obstacle.x - x, obstacle.y - y) - obstacle.radius - ROBOT_RADIUS
        self.assertGreater(gap, 0.0)
        self.assertLess(gap, 0.25)                  # it drove up to the obstacle, then stopped
        self.assertGreater(result.distance, 2.0)
        collisions = rospy.wait_for_message('/sim/collisions', UInt32, timeout=TIMEOUT)
        self.assertEqual(collisions.data, 0)


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_corridor_blocked', CorridorBlockedTest)
