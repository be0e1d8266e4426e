#!/usr/bin/python3
"""Rostest of nodes/tiago_controller and nodes/client against fake servers hosted here: a fake
move_base that moves the robot's tf (map -> base_footprint) toward the goal, a fake corridor
controller and a fake detection service, each switchable to abort, hang or fail. No simulator:
this checks the proxy's state machine, failure paths and cancel over real ROS plumbing."""
import math
import os
import signal
import subprocess
import threading
import unittest

import actionlib
import rospy
import rostest
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseResult
from visualization_msgs.msg import MarkerArray

from tiago_nav.msg import (CorridorAction, CorridorFeedback, CorridorResult, Obstacle,
                           TiagoTaskActionGoal, TiagoTaskFeedback as FB,
                           TiagoTaskGoal)
from tiago_nav.ros.actions import TaskClient
from tiago_nav.ros.conversions import pose_from_msg, transform_stamped
from tiago_nav.srv import DetectObstacles, DetectObstaclesResponse

from simtest import distinct_states

T = 30.0            # generous bound on every wait [s]
FOUND = [(3.1, 0.4, 0.2), (4.0, -1.2, 0.15)]     # the fake detection's obstacles (x, y, r)


class Fakes:
    """The fake servers. ``mode`` of each: see the class attributes."""
    nav_mode = 'succeed'      # succeed | abort | hang
    detect_mode = 'ok'        # ok | error | slow

    def __init__(self):
        self.pose = [0.0, 0.0, 0.0]
        self.lock = threading.Lock()
        self.nav_goals = []
        self.nav_preempted = 0
        self.corridor_goals = 0
        self.detect_calls = 0
        self.tfb = tf2_ros.TransformBroadcaster()
        self.nav = actionlib.SimpleActionServer('fake_move_base', MoveBaseAction, self.on_nav, False)
        self.corridor = actionlib.SimpleActionServer('fake_corridor', CorridorAction,
                                                     self.on_corridor, False)
        self.nav.start()
        self.corridor.start()
        rospy.Service('fake_detection', DetectObstacles, self.on_detect)
        threading.Thread(target=self.tf_loop, daemon=True).start()

    def tf_loop(self):
        r = rospy.Rate(30)
        while not rospy.is_shutdown():
            with self.lock:
                p = tuple(self.pose)
            try:
                self.tfb.sendTransform(transform_stamped(p, 'map', 'base_footprint', rospy.Time.now()))
                r.sleep()
            except rospy.ROSInterruptException:
                break

    def on_corridor(self, goal):
        self.corridor_goals += 1
        for i in range(10):
            if self.corridor.is_preempt_requested():
                self.corridor.set_preempted()
                return
            with self.lock:
                self.pose[0] += 0.05
            self.corridor.publish_feedback(CorridorFeedback(left_distance=0.5, right_distance=0.5,
                                                            distance=0.05 * (i + 1)))
            rospy.sleep(0.05)
        self.corridor.set_succeeded(CorridorResult(distance=0.5, reason='corridor end'))

    def on_nav(self, goal):
        self.nav_goals.append(goal)
        gx, gy, gyaw = pose_from_msg(goal.target_pose.pose)
        if self.nav_mode == 'abort':
            rospy.sleep(0.2)
            self.nav.set_aborted(MoveBaseResult(), 'the goal is inside an obstacle (fake)')
            return
        r = rospy.Rate(20)
        while not rospy.is_shutdown():
            if self.nav.is_preempt_requested():
                self.nav_preempted += 1
                self.nav.set_preempted(MoveBaseResult(), 'cancelled')
                return
            with self.lock:
                dx, dy = gx - self.pose[0], gy - self.pose[1]
                d = math.hypot(dx, dy)
                step = min(d, 0.1)                      # 2 m/s at 20 Hz
                if d > 1e-6:
                    self.pose[0] += step * dx / d
                    self.pose[1] += step * dy / d
                if d < 1e-6 and self.nav_mode == 'succeed':
                    self.pose[2] = gyaw
                    self.nav.set_succeeded(MoveBaseResult(), 'goal reached')
                    return
            r.sleep()

    def on_detect(self, req):
        self.detect_calls += 1
        if self.detect_mode == 'error':
            raise rospy.ServiceException('no scan received (fake)')
        if self.detect_mode == 'slow':
            rospy.sleep(6.0)
        obs = [Obstacle(center=Point(x, y, 0), center_robot=Point(x - self.pose[0], y - self.pose[1], 0),
                        radius=r, num_points=20) for x, y, r in FOUND]
        return DetectObstaclesResponse(success=True, obstacles=obs, message='')


class MissionFakesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_mission_fakes')
        cls.fakes = Fakes()
        cls.cmds = []
        rospy.Subscriber('/mobile_base_controller/cmd_vel', Twist,
                         lambda m: cls.cmds.append((rospy.get_time(), m.linear.x, m.angular.z)))
        cls.goals_seen = []
        rospy.Subscriber('/tiago_controller/goal', TiagoTaskActionGoal, cls.goals_seen.append)
        cls.markers = []
        rospy.Subscriber('/tiago_controller/obstacle_markers', MarkerArray, cls.markers.append)
        cls.client = TaskClient('tiago_controller')
        assert cls.client.wait_for_server(rospy.Duration(T)), 'no tiago_controller'

    def setUp(self):
        Fakes.nav_mode, Fakes.detect_mode = 'succeed', 'ok'
        with self.fakes.lock:
            self.fakes.pose[:] = [0.0, 0.0, 0.0]
        rospy.sleep(0.3)

    def send(self, x, y, yaw, corridor, client=None, cancel_when=None):
        client = client or self.client
        fbs = []
        client.send_goal(TiagoTaskGoal(x=x, y=y, yaw_deg=yaw, use_corridor_law=corridor),
                         feedback_cb=fbs.append)
        if cancel_when is not None:
            end = rospy.get_time() + T
            while not any(cancel_when(f) for f in list(fbs)) and rospy.get_time() < end:
                rospy.sleep(0.05)
            client.cancel_goal()
        self.assertTrue(client.wait_for_result(rospy.Duration(T)), 'no result')
        return client.get_state(), client.get_result(), client.get_goal_status_text(), fbs

    def assert_stop_commanded_after(self, t):
        self.assertTrue(any(c[0] >= t and c[1] == 0 and c[2] == 0 for c in self.cmds),
                        'no zero cmd_vel after the goal ended')

    def test_1_success_states_in_order_and_obstacles_relayed(self):
        t0 = rospy.get_time()
        state, result, text, fbs = self.send(2.0, 1.0, 90.0, True)
        self.assertEqual(state, GoalStatus.SUCCEEDED, text)
        st = distinct_states(fbs)
        self.assertEqual(st[:3], [FB.GOAL_RECEIVED, FB.CORRIDOR, FB.NAVIGATING])
        self.assertIn(FB.MOVING, st)
        self.assertEqual(st[-3:], [FB.ARRIVED, FB.DETECTING, FB.DETECTION_DONE])
        self.assertTrue(any('m to go' in f.status for f in fbs if f.state == FB.MOVING))
        self.assertEqual([(o.center.x, o.center.y) for o in result.obstacles],
                         [(x, y) for x, y, _ in FOUND])
        fx, fy, fyaw = pose_from_msg(result.final_pose.pose)
        self.assertAlmostEqual(fx, 2.0, delta=0.02)
        self.assertAlmostEqual(fy, 1.0, delta=0.02)
        self.assertAlmostEqual(math.degrees(fyaw), 90.0, delta=1.0)
        self.assertEqual(result.final_pose.header.frame_id, 'map')
        self.assertIn('found 2 obstacles', result.message)
        self.assert_stop_commanded_after(t0)
        rospy.sleep(0.5)
        self.assertTrue(self.markers)
        self.assertEqual(len([m for m in self.markers[-1].markers if m.ns == 'obstacles']), 2)

    def test_2_navigation_aborted_names_navigation(self):
        Fakes.nav_mode = 'abort'
        state, result, text, _ = self.send(1.0, 0.0, 0.0, False)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertIn('navigation', text)
        self.assertIn('inside an obstacle (fake)', result.message)

    def test_3_navigation_timeout(self):
        Fakes.nav_mode = 'hang'
        n = self.fakes.nav_preempted
        state, result, text, _ = self.send(100.0, 0.0, 0.0, False)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertIn('navigation failed: timed out', result.message)
        rospy.sleep(0.5)
        self.assertEqual(self.fakes.nav_preempted, n + 1)    # the move_base goal was cancelled

    def test_4_detection_error_aborts_naming_detection(self):
        Fakes.detect_mode = 'error'
        state, result, text, _ = self.send(0.5, 0.0, 0.0, False)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertTrue(result.message.startswith('detection failed'), result.message)
        self.assertIn('no scan received (fake)', result.message)

    def test_5_detection_that_never_answers_times_out(self):
        Fakes.detect_mode = 'slow'
        state, result, text, _ = self.send(0.5, 0.0, 0.0, False)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertIn('detection failed', result.message)
        self.assertIn('did not answer', result.message)

    def test_6_absent_servers_abort_with_a_message(self):
        absent = TaskClient('tiago_controller_absent')
        self.assertTrue(absent.wait_for_server(rospy.Duration(T)))
        state, result, text, _ = self.send(1.0, 0.0, 0.0, True, client=absent)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertIn('corridor failed: no corridor_controller server', result.message)
        state, result, text, _ = self.send(1.0, 0.0, 0.0, False, client=absent)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertIn('navigation failed: no move_base server', result.message)

    def test_7_cancel_preempts_and_stops_the_robot(self):
        Fakes.nav_mode = 'hang'
        n = self.fakes.nav_preempted
        t0 = rospy.get_time()
        state, result, text, fbs = self.send(100.0, 0.0, 0.0, False,
                                             cancel_when=lambda f: f.state == FB.MOVING)
        self.assertEqual(state, GoalStatus.PREEMPTED)
        self.assertIn('cancelled during navigation', result.message)
        rospy.sleep(0.3)
        self.assertEqual(self.fakes.nav_preempted, n + 1)
        self.assert_stop_commanded_after(t0)
        with self.fakes.lock:
            x = self.fakes.pose[0]
        rospy.sleep(0.5)
        with self.fakes.lock:
            self.assertEqual(self.fakes.pose[0], x)          # nothing moves it any more

    def run_client(self, *args):
        return subprocess.run(['rosrun', 'tiago_nav', 'client'] + list(args),
                              stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=120)

    def test_8_client_bad_arguments_exit_2_and_send_nothing(self):
        n = len(self.goals_seen)
        for args in (['nan', '0', '0'], ['1', '0', '500'], ['1', '0'], ['one', '2', '3']):
            p = self.run_client(*args)
            self.assertEqual(p.returncode, 2, p.stdout)
            self.assertIn('error', p.stdout)
        rospy.sleep(1.0)
        self.assertEqual(len(self.goals_seen), n)

    def test_9_client_exit_codes_and_table(self):
        p = self.run_client('1.5', '-0.5', '-45', '--no-corridor')
        self.assertEqual(p.returncode, 0, p.stdout)
        self.assertIn('DETECTION_DONE', p.stdout)
        self.assertIn('SUCCEEDED', p.stdout)
        rows = [line.split() for line in p.stdout.splitlines() if line[:2].strip().isdigit()]
        self.assertEqual([(float(r[1]), float(r[2])) for r in rows], [(x, y) for x, y, _ in FOUND])
        Fakes.nav_mode = 'abort'
        p = self.run_client('1.5', '-0.5', '-45', '--no-corridor')
        self.assertEqual(p.returncode, 1, p.stdout)
        self.assertIn('ABORTED: navigation failed', p.stdout)

    def test_9b_client_ctrl_c_cancels_and_exits_1(self):
        Fakes.nav_mode = 'hang'
        n = self.fakes.nav_preempted
        fbs = []
        sub = rospy.Subscriber('/tiago_controller/feedback', rospy.AnyMsg, fbs.append)
        p = subprocess.Popen(['rosrun', 'tiago_nav', 'client', '50', '0', '0', '--no-corridor'],
                             stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, start_new_session=True)
        try:
            end = rospy.get_time() + T
            while len(fbs) < 3 and rospy.get_time() < end:     # the task is under way
                rospy.sleep(0.05)
            self.assertGreaterEqual(len(fbs), 3)
            os.killpg(p.pid, signal.SIGINT)
            out, _ = p.communicate(timeout=60)
        finally:
            sub.unregister()
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
        self.assertEqual(p.returncode, 1, out)
        self.assertIn('PREEMPTED: cancelled during navigation', out)
        self.assertEqual(self.fakes.nav_preempted, n + 1)


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_mission_fakes', MissionFakesTest)
