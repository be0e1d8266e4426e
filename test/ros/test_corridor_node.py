#!/usr/bin/python3
"""Rostest of nodes/corridor_controller in the shipped world, checked against the world file:
the action SUCCEEDS at the corridor's exit from robot_start, /sim/collisions stays 0, feedback
comes at >= 5 Hz; a second goal, with the robot already out of the corridor, ABORTS; a goal
cancelled while driving is PREEMPTED and the robot stops."""
import math

import actionlib
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Twist
from std_msgs.msg import UInt32

from tiago_nav.msg import CorridorAction, CorridorGoal
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.ros.actions import wait_server

from simtest import SimTestCase

TIMEOUT = 30.0


def corridor_walls(world):
    """The two long walls bounding the world's corridor (ground truth): the walls whose centre
    lies within a wall length of the corridor's axis, nearest each side of it."""
    c = world.corridor
    ax, ay = c.entry
    ex, ey = c.exit
    th = math.atan2(ey - ay, ex - ax)
    out = {}
    for w in world.walls:
        u = (w.x - ax) * math.cos(th) + (w.y - ay) * math.sin(th)
        v = -(w.x - ax) * math.sin(th) + (w.y - ay) * math.cos(th)
        if abs(math.sin(w.yaw - th)) < 0.1 and 0 < u < math.hypot(ex - ax, ey - ay) and abs(v) < c.width:
            side = 'left' if v > 0 else 'right'
            out[side] = (u + w.length / 2.0) if side not in out else max(out[side], u + w.length / 2)
    return th, out


class CorridorNodeTest(SimTestCase):
    node_name = 'test_corridor_node'

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.client = actionlib.SimpleActionClient('corridor_controller', CorridorAction)
        assert wait_server(cls.client, TIMEOUT), 'no corridor_controller server'

    def test_1_drives_the_corridor_to_its_exit(self):
        feedback = []
        start = self.base_pose()
        self.client.send_goal(CorridorGoal(), feedback_cb=lambda f: feedback.append(
            (rospy.Time.now().to_sec(), f)))
        self.assertTrue(self.client.wait_for_result(rospy.Duration(40.0)), 'no result in 40 s')
        state, result = self.client.get_state(), self.client.get_result()
        self.assertEqual(state, GoalStatus.SUCCEEDED, result.reason)
        rospy.sleep(1.0)
        x, y, yaw = self.base_pose()
        # ground truth: the corridor along world.corridor; its walls end at `ends` along it
        th, ends = corridor_walls(self.world)
        self.assertEqual(set(ends), {'left', 'right'})
        ax, ay = self.world.corridor.entry
        along = (x - ax) * math.cos(th) + (y - ay) * math.sin(th)
        across = -(x - ax) * math.sin(th) + (y - ay) * math.cos(th)
        first_end = min(ends.values())
        # out of the corridor: the base's back edge past the first wall end, within 0.5 m of it
        self.assertGreater(along - ROBOT_RADIUS, first_end - 0.05)
        self.assertLess(along, first_end + 0.8)
        self.assertLess(abs(across), 0.1)                                    # near the centre line
        self.assertLess(abs(math.atan2(math.sin(yaw - th), math.cos(yaw - th))), math.radians(10))
        self.assertAlmostEqual(result.distance, math.hypot(x - start[0], y - start[1]), delta=0.2)
        self.assertEqual(result.exit_pose.header.frame_id, 'map')
        self.assertAlmostEqual(result.exit_pose.pose.position.x, x, delta=0.05)
        collisions = rospy.wait_for_message('/sim/collisions', UInt32, timeout=TIMEOUT)
        self.assertEqual(collisions.data, 0)
        # feedback at >= 5 Hz of sim time, with the walls on both sides about the corridor width
        stamps = [t for t, _ in feedback]
        self.assertGreater(len(stamps), 5 * (stamps[-1] - stamps[0]) * 0.9)
        widths = [f.left_distance + f.right_distance for _, f in feedback
                  if f.left_distance > 0 and 1.5 < f.distance < 4.0]
        self.assertTrue(widths)
        for wdt in widths:
            self.assertAlmostEqual(wdt, self.world.corridor.width, delta=0.05)
        # and it was still afterwards
        self.assertLess(math.hypot(*(v - w for v, w in zip(self.base_pose()[:2], (x, y)))), 0.01)

    def test_2_no_corridor_ahead_aborts(self):
        # the robot now stands in the big room, past the corridor: nothing narrow ahead
        before = self.base_pose()
        self.client.send_goal(CorridorGoal(max_speed=0.5))
        self.assertTrue(self.client.wait_for_result(rospy.Duration(20.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.ABORTED)
        self.assertIn('no corridor', self.client.get_result().reason)
        after = self.base_pose()
        self.assertLess(math.hypot(after[0] - before[0], after[1] - before[1]), 0.05)

    def test_3_cancel_preempts_and_stops(self):
        # back into the corridor (open-loop, slowly: the robot is centred and aligned with it)
        cmd = rospy.Publisher('/mobile_base_controller/cmd_vel', Twist, queue_size=1)
        rospy.sleep(0.5)
        twist = Twist()
        twist.linear.x = -0.3
        end = rospy.Time.now() + rospy.Duration(5.0)
        rate = rospy.Rate(20)
        while rospy.Time.now() < end:
            cmd.publish(twist)
            rate.sleep()
        cmd.publish(Twist())
        rospy.sleep(1.0)
        feedback = []
        self.client.send_goal(CorridorGoal(max_speed=0.5), feedback_cb=feedback.append)
        end = rospy.Time.now() + rospy.Duration(10.0)
        while not any(f.distance > 0.2 for f in feedback) and rospy.Time.now() < end:
            rospy.sleep(0.05)
        self.assertTrue(any(f.distance > 0.2 for f in feedback), 'did not drive')
        self.client.cancel_goal()
        self.assertTrue(self.client.wait_for_result(rospy.Duration(5.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.PREEMPTED)
        rospy.sleep(1.5)                      # braking from <= 0.5 m/s at 1 m/s^2 takes 0.5 s
        a = self.base_pose()
        rospy.sleep(1.0)
        b = self.base_pose()
        self.assertLess(math.hypot(a[0] - b[0], a[1] - b[1]), 0.005)   # stopped
        collisions = rospy.wait_for_message('/sim/collisions', UInt32, timeout=TIMEOUT)
        self.assertEqual(collisions.data, 0)


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_corridor_node', CorridorNodeTest)
