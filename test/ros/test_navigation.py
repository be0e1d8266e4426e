#!/usr/bin/python3
"""Rostest of nodes/navigation (move_base) in the shipped world, with a plain
SimpleActionClient of MoveBaseAction, checked against the world file's ground truth
(/sim/ground_truth the true pose, tf map -> base_footprint the localisation's estimate,
/sim/collisions the contact count):
goals past the movable cylinders are reached within tolerance, a goal inside a wall and a goal in
a free pocket no path reaches are ABORTED with a reason, a cancelled goal is PREEMPTED and the
base stops, /move_base/make_plan answers, a goal with a NaN field or a zero quaternion is ABORTED at once
with the reason and the robot does not move, and /sim/collisions stays 0 throughout."""
import math

import actionlib
import numpy as np
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import OccupancyGrid, Odometry
from nav_msgs.srv import GetPlan
from scipy import ndimage
from std_msgs.msg import UInt32
from std_srvs.srv import Empty
from geometry_msgs.msg import PoseStamped

from tiago_nav.geometry import wrap_angle
from tiago_nav.ros.actions import wait_server
from tiago_nav.ros.conversions import pose_stamped
from tiago_nav.sim.raster import rasterise_world

from simtest import LocalisationErrors, SimTestCase

TIMEOUT = 30.0
ROBOT_RADIUS = 0.27


def goal_msg(x, y, yaw_deg, frame='map'):
    return MoveBaseGoal(target_pose=pose_stamped((x, y, math.radians(yaw_deg)), frame, rospy.Time.now()))


def clearance(world, x, y):
    """Distance [m] from (x, y) to the nearest movable cylinder's surface (ground truth)."""
    return min(math.hypot(x - c.x, y - c.y) - c.radius for c in world.movable_obstacles)


class NavigationTest(SimTestCase):
    node_name = 'test_navigation'

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.localisation = LocalisationErrors()
        cls.collisions = None
        rospy.Subscriber('/sim/collisions', UInt32, cls._on_collisions)
        cls.odom = None
        rospy.Subscriber('/mobile_base_controller/odom', Odometry, cls._on_odom)
        cls.client = actionlib.SimpleActionClient('move_base', MoveBaseAction)
        assert wait_server(cls.client, TIMEOUT), 'no move_base server'

    @classmethod
    def _on_collisions(cls, msg):
        cls.collisions = msg.data

    @classmethod
    def _on_odom(cls, msg):
        cls.odom = msg

    def assert_no_collision(self):
        end = rospy.Time.now() + rospy.Duration(2.0)
        while self.collisions is None and rospy.Time.now() < end:
            rospy.sleep(0.1)
        self.assertEqual(self.collisions, 0, 'the robot touched something (/sim/collisions)')

    def send_and_wait(self, goal, timeout):
        # the stamps move_base gave its feedback (when it sent them, in ROS time): not when they
        # arrived, which on a loaded machine can be long after simulated time ran on
        feedback = []
        self.client.send_goal(goal, feedback_cb=lambda f: feedback.append(
            f.base_position.header.stamp.to_sec()))
        self.assertTrue(self.client.wait_for_result(rospy.Duration(timeout)), 'no result in %.0f s' % timeout)
        return self.client.get_state(), self.client.get_goal_status_text(), feedback

    def reach(self, x, y, yaw_deg, timeout=90.0):
        state, text, feedback = self.send_and_wait(goal_msg(x, y, yaw_deg), timeout)
        self.assertEqual(state, GoalStatus.SUCCEEDED, 'goal (%g, %g): state %d, %r' % (x, y, state, text))
        px, py, pyaw = self.base_pose()
        self.assertLess(math.hypot(px - x, py - y), 0.15 + 0.03, 'ended at (%.2f, %.2f)' % (px, py))
        self.assertLess(abs(wrap_angle(pyaw - math.radians(yaw_deg))), 0.1 + 0.03)
        if len(feedback) > 10:
            rate = (len(feedback) - 1) / (feedback[-1] - feedback[0])
            self.assertGreaterEqual(rate, 4.5, 'feedback at %.1f Hz' % rate)
        self.assert_no_collision()

    def test_1_reaches_pose_b_and_goals_past_the_cylinders(self):
        # pose B of the course, then two goals whose straight line crosses a movable cylinder
        self.reach(11.0, 0.0, -45.0)
        for x, y, yaw in ((12.0, -2.0, 0.0), (10.2, -3.2, 180.0)):
            self.assertGreater(clearance(self.world, x, y), ROBOT_RADIUS + 0.2)
            self.reach(x, y, yaw)

    def test_2_goal_inside_a_wall_aborts_quickly(self):
        # rejected on arrival, before any planning (not after the planner's patience); simulated
        # time runs free here (wait_for_work false), so its duration would measure the host
        w = self.world.walls[len(self.world.walls) // 2]
        state, text, _ = self.send_and_wait(goal_msg(w.x, w.y, 0.0), 10.0)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertTrue(text.startswith('goal rejected: '), text)
        self.assertIn('inside an obstacle', text)

    def test_3_goal_outside_the_map_aborts(self):
        xmin, ymin, xmax, ymax = self.world.bounds
        state, text, _ = self.send_and_wait(goal_msg(xmax + 5.0, ymax + 5.0, 0.0), 10.0)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertIn('outside the map', text)

    def test_4_unreachable_goal_aborts(self):
        # a free pocket (ground truth: the world's own raster) not connected to the robot's
        grid = rasterise_world(self.world)
        dist = grid.distance_field()
        labels, n = ndimage.label(dist > ROBOT_RADIUS + 0.1)
        rc = grid.world_to_cell([self.base_pose()[:2]])[0]
        mine = labels[rc[0], rc[1]]
        other = (labels > 0) & (labels != mine)
        if not other.any():
            self.skipTest('this world has no unreachable free pocket')
        best = np.unravel_index(np.argmax(np.where(other, dist, 0)), dist.shape)
        x, y = grid.cell_to_world([best])[0]
        state, text, _ = self.send_and_wait(goal_msg(x, y, 0.0), 30.0)
        self.assertEqual(state, GoalStatus.ABORTED, 'goal (%.2f, %.2f): %r' % (x, y, text))
        self.assertIn('no path', text)
        self.assert_no_collision()

    def test_5_make_plan_service(self):
        rospy.wait_for_service('/move_base/make_plan', timeout=TIMEOUT)
        srv = rospy.ServiceProxy('/move_base/make_plan', GetPlan)
        start = self.base_pose()
        resp = srv(start=pose_stamped(start, 'map'), goal=pose_stamped((11.0, 0.0, 0.0), 'map'),
                   tolerance=0.0)
        self.assertGreater(len(resp.plan.poses), 10)
        last = resp.plan.poses[-1].pose.position
        self.assertLess(math.hypot(last.x - 11.0, last.y), 0.1)
        # every plan point keeps the robot clear of the static walls (ground truth raster)
        grid = rasterise_world(self.world)
        dist = grid.distance_field()
        pts = np.array([[p.pose.position.x, p.pose.position.y] for p in resp.plan.poses])
        rc = grid.world_to_cell(pts)
        self.assertGreaterEqual(dist[rc[:, 0], rc[:, 1]][3:].min(), ROBOT_RADIUS)

    def test_6_cancel_preempts_and_stops(self):
        self.client.send_goal(goal_msg(3.0, 0.0, 180.0))
        end = rospy.Time.now() + rospy.Duration(20.0)
        while rospy.Time.now() < end and (self.odom is None or self.odom.twist.twist.linear.x < 0.3):
            rospy.sleep(0.05)
        self.assertGreaterEqual(self.odom.twist.twist.linear.x, 0.3,
                                'the robot never got moving (goal state %d, %r)'
                                % (self.client.get_state(), self.client.get_goal_status_text()))
        self.client.cancel_goal()
        self.assertTrue(self.client.wait_for_result(rospy.Duration(10.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.PREEMPTED)
        rospy.sleep(1.5)
        tw = self.odom.twist.twist
        self.assertLess(abs(tw.linear.x), 0.02, 'still moving after the cancel')
        self.assertLess(abs(tw.angular.z), 0.02)
        self.assert_no_collision()

    def test_7_newer_goal_preempts(self):
        self.client.send_goal(goal_msg(11.0, 0.0, 0.0))
        rospy.sleep(1.0)
        first = actionlib.SimpleActionClient('move_base', MoveBaseAction)
        self.assertTrue(wait_server(first, TIMEOUT), 'no move_base server for a second client')
        # the second client's goal replaces the first client's
        first.send_goal(goal_msg(*self.base_pose()[:2], 0.0))
        self.assertTrue(self.client.wait_for_result(rospy.Duration(10.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.PREEMPTED)
        self.assertTrue(first.wait_for_result(rospy.Duration(30.0)))
        self.assertEqual(first.get_state(), GoalStatus.SUCCEEDED, first.get_goal_status_text())
        self.assert_no_collision()

    def test_8_simple_goal_topic_and_clear_costmaps(self):
        rospy.wait_for_service('/move_base/clear_costmaps', timeout=TIMEOUT)
        rospy.ServiceProxy('/move_base/clear_costmaps', Empty)()
        pub = rospy.Publisher('/move_base_simple/goal', PoseStamped, queue_size=1, latch=True)
        x, y, yaw = 8.0, -0.5, 90.0
        pub.publish(pose_stamped((x, y, math.radians(yaw)), 'map', rospy.Time.now()))
        end = rospy.Time.now() + rospy.Duration(60.0)
        reached = False
        while rospy.Time.now() < end and not reached:
            rospy.sleep(0.2)
            px, py, pyaw = self.base_pose()
            reached = (math.hypot(px - x, py - y) < 0.18 and abs(wrap_angle(pyaw - math.radians(yaw))) < 0.13
                       and self.odom is not None and abs(self.odom.twist.twist.angular.z) < 0.02)
        self.assertTrue(reached, 'the /move_base_simple/goal pose was not reached')
        self.assert_no_collision()

    def assert_rejected_and_still(self, goal, why):
        t0 = rospy.Time.now()
        state, text, _ = self.send_and_wait(goal, 10.0)
        self.assertEqual(state, GoalStatus.ABORTED, text)
        self.assertIn(why, text)
        self.assertLess((rospy.Time.now() - t0).to_sec(), 2.0)
        end = rospy.Time.now() + rospy.Duration(1.0)
        while rospy.Time.now() < end:
            tw = self.odom.twist.twist
            self.assertLess(abs(tw.linear.x), 0.02, 'moving after a rejected goal')
            self.assertLess(abs(tw.angular.z), 0.02, 'turning after a rejected goal')
            rospy.sleep(0.1)

    def test_9_nan_goal_and_zero_quaternion_rejected(self):
        self.wait_still()
        goal = goal_msg(float('nan'), 0.0, 0.0)
        self.assert_rejected_and_still(goal, 'non-finite field (position.x=nan)')
        goal = goal_msg(*self.base_pose()[:2], 0.0)
        o = goal.target_pose.pose.orientation
        o.x = o.y = o.z = o.w = 0.0
        self.assert_rejected_and_still(goal, 'cannot be normalised')
        goal = goal_msg(*self.base_pose()[:2], 0.0)
        goal.target_pose.pose.orientation.z = float('nan')
        self.assert_rejected_and_still(goal, 'orientation.z=nan')

    def wait_still(self, timeout=20.0):
        end = rospy.Time.now() + rospy.Duration(timeout)
        while rospy.Time.now() < end:
            tw = self.odom.twist.twist if self.odom is not None else None
            if tw is not None and abs(tw.linear.x) < 0.01 and abs(tw.angular.z) < 0.01:
                return
            rospy.sleep(0.1)
        self.fail('the robot did not come to rest')


    def test_9b_the_costmap_shows_the_unmapped_cylinders_and_nothing_that_is_not_there(self):
        # at pose B four cylinders are in the laser's view; the published costmap (costmap_2d's
        # values) covers each with lethal cells, and every lethal cell lies within the robot's
        # radius of a wall or a cylinder of the world file
        self.reach(11.0, 0.0, -45.0)
        got = []
        sub = rospy.Subscriber('/move_base/global_costmap/costmap', OccupancyGrid, got.append)
        static = rospy.wait_for_message('/map', OccupancyGrid, timeout=TIMEOUT)
        end = rospy.Time.now() + rospy.Duration(TIMEOUT)
        while len(got) < 2 and rospy.Time.now() < end:     # one with a scan after subscribing
            rospy.sleep(0.1)
        sub.unregister()
        self.assertGreaterEqual(len(got), 2, 'no costmap on /move_base/global_costmap/costmap')
        msg = got[-1]
        info = msg.info
        self.assertEqual((info.width, info.height, info.resolution),
                         (static.info.width, static.info.height, static.info.resolution))
        cost = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
        occupied = np.asarray(static.data, dtype=np.int8).reshape(info.height, info.width) == 100
        self.assertTrue(np.all(cost[occupied] == 100), 'a wall of the map is not lethal')
        res, ox, oy = info.resolution, info.origin.position.x, info.origin.position.y
        rows, cols = np.nonzero(cost == 100)
        xy = np.column_stack((ox + (cols + 0.5) * res, oy + (rows + 0.5) * res))
        # distance of each lethal cell to the nearest thing of the world
        to_wall = ndimage.distance_transform_edt(~occupied) * res
        gap = to_wall[rows, cols]
        for c in self.world.movable_obstacles:
            gap = np.minimum(gap, np.hypot(xy[:, 0] - c.x, xy[:, 1] - c.y) - c.radius)
        # a lethal cell lies within the robot's radius of a marked cell, whose centre is within
        # half a cell's diagonal (0.035 m) of the hit, itself within the range noise (3 std,
        # 0.03 m) of the surface; a wall's raster cell centre is another 0.035 m off its face.
        # The hit is placed with the localisation's pose: its error so far moves it by up to
        # the position error plus the yaw error times obstacle_range. A ghost is farther.
        pos, yaw, n = self.localisation.worst()
        self.assertGreater(n, 50, 'too few /amcl_pose estimates matched with the ground truth')
        reach = rospy.get_param('/move_base/obstacle_range')
        bound = ROBOT_RADIUS + 0.1 + pos + yaw * reach
        worst = int(np.argmax(gap))
        self.assertLessEqual(float(gap[worst]), bound,
                             'a lethal cell at (%.2f, %.2f) m is %.3f m from anything in the '
                             'world, over %.3f m (the localisation was off by up to %.3f m '
                             'and %.2f deg)' % (xy[worst, 0], xy[worst, 1], gap[worst], bound,
                                                pos, math.degrees(yaw)))
        covered = [c for c in self.world.movable_obstacles
                   if cost[int((c.y - oy) / res), int((c.x - ox) / res)] == 100]
        self.assertGreaterEqual(len(covered), 4, 'unmapped cylinders in the costmap: %d' % len(covered))


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_navigation', NavigationTest)
