#!/usr/bin/python3
"""Rostest of nodes/tiago_controller and nodes/client against fake servers hosted here: a fake
move_base that moves the robot's tf (map -> base_footprint) toward the goal, a fake corridor
controller, a fake /scan (a corridor ahead, open space, or silence) and a fake detection service
that fails as the real one does (answers ``success: false`` with a reason) or crashes (its
handler raises), each switchable to abort, hang or fail. No simulator: this checks the proxy's
state machine, failure paths, cancel and shutdown over real ROS plumbing."""
import math
import os
import signal
import subprocess
import threading
import time
import unittest

import actionlib
import numpy as np
import rospy
import rostest
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseResult
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import MarkerArray

from tiago_nav.detection.pipeline import Detection
from tiago_nav.detection.service import found_obstacles
from tiago_nav.geometry import compose, inverse
from tiago_nav.msg import (CorridorAction, CorridorFeedback, CorridorResult, Obstacle,
                           TiagoTaskActionGoal, TiagoTaskFeedback as FB,
                           TiagoTaskGoal)
from tiago_nav.ros.actions import TaskClient
from tiago_nav.nodes.obstacle_detection import obstacle_msg
from tiago_nav.ros.conversions import pose_from_msg, transform_stamped
from tiago_nav.srv import DetectObstacles, DetectObstaclesResponse

from simtest import distinct_states

T = 30.0            # generous bound on every wait [s wall]: a hang guard, not a timing
FOUND = [(4.0, -1.2, 0.15), (3.1, 0.4, 0.2)]     # the fake detection's obstacles (x, y, r),
#                                                  farther from the test's poses B first
NO_SCAN = 'no /scan received within 2.0 s'       # the node's answer without a scan (its wording)


def wait_for(condition, what, timeout=T):
    """Wait (wall clock: there is no simulator here) until ``condition()``; fail naming
    ``what`` after ``timeout``."""
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise AssertionError('timed out after %g s waiting for %s' % (timeout, what))
        time.sleep(0.01)


def nearest_first(pose):
    """FOUND's centres in the order the node answers: nearest the robot at ``pose`` first."""
    return sorted(((x, y) for x, y, _ in FOUND), key=lambda c: math.hypot(c[0] - pose[0],
                                                                         c[1] - pose[1]))


class Fakes:
    """The fake servers. ``mode`` of each: see the class attributes."""
    nav_mode = 'succeed'      # succeed | abort | hang
    detect_mode = 'ok'        # ok | fail (answers success: false) | crash (raises) | slow
    scan_mode = 'corridor'    # corridor (walls 1.1 m apart along +x) | open (no returns) | none

    def __init__(self):
        self.pose = [0.0, 0.0, 0.0]
        self.lock = threading.Lock()
        self.nav_goals = []
        self.nav_preempted = 0
        self.corridor_goals = 0
        self.detect_calls = 0
        self.nav_running = False           # an on_nav call is under way (it moves the robot)
        self.silent_scans = 0              # scan periods passed without a scan
        self.tfb = tf2_ros.TransformBroadcaster()
        self.nav = actionlib.SimpleActionServer('fake_move_base', MoveBaseAction, self.on_nav, False)
        self.corridor = actionlib.SimpleActionServer('fake_corridor', CorridorAction,
                                                     self.on_corridor, False)
        self.nav.start()
        self.corridor.start()
        rospy.Service('fake_detection', DetectObstacles, self.on_detect)
        threading.Thread(target=self.tf_loop, daemon=True).start()
        self.scan_pub = rospy.Publisher('/scan', LaserScan, queue_size=1)
        threading.Thread(target=self.scan_loop, daemon=True).start()

    def scan_loop(self):
        """A TIAGo-like scan in base_footprint: two walls at y = +-0.55 m from x = -0.3 to 0.8 m
        (a corridor leading along +x), or nothing within range."""
        n, amin, amax = 666, -1.92, 1.92
        a = np.linspace(amin, amax, n)
        s = np.sin(a)
        with np.errstate(divide='ignore', invalid='ignore'):
            r = np.where(np.abs(s) > 1e-6, 0.55 / np.abs(s), np.inf)
        r = np.where((r * np.cos(a) >= -0.3) & (r * np.cos(a) <= 0.8), r, np.inf)
        rate = rospy.Rate(15)
        while not rospy.is_shutdown():
            if self.scan_mode == 'none':
                self.silent_scans += 1
            else:
                msg = LaserScan(angle_min=amin, angle_max=amax, angle_increment=(amax - amin) / (n - 1),
                                range_min=0.05, range_max=25.0,
                                ranges=list(r) if self.scan_mode == 'corridor' else [np.inf] * n)
                msg.header.frame_id = 'base_footprint'
                msg.header.stamp = rospy.Time.now()
                try:
                    self.scan_pub.publish(msg)
                except rospy.ROSException:
                    break
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break

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
        self.nav_running = True
        try:
            self._on_nav(goal)
        finally:
            self.nav_running = False

    def _on_nav(self, goal):
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
        if self.detect_mode == 'fail':         # how the real node reports a failure
            return DetectObstaclesResponse(success=False, obstacles=[], message=NO_SCAN)
        if self.detect_mode == 'crash':        # a handler that raised: the call itself errs
            raise rospy.ServiceException('handler crashed (fake)')
        if self.detect_mode == 'slow':         # well past the proxy's detection_timeout
            rospy.sleep(3 * rospy.get_param('/tiago_controller/detection_timeout'))
        with self.lock:
            robot = tuple(self.pose)
        # the node's own conversion: centres in the robot frame (rotated by its yaw), nearest
        # the robot first; the laser frame is the robot's here
        found = found_obstacles([Detection((x, y), r, 20, None, np.diag([4e-5, 4e-5, 1e-4]))
                                 for x, y, r in FOUND], robot,
                                (0.0, 0.0, 0.0))
        return DetectObstaclesResponse(success=True, obstacles=[obstacle_msg(f) for f in found],
                                       message='')


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
        cls.tf = tf2_ros.Buffer()
        cls.listener = tf2_ros.TransformListener(cls.tf)
        cls.client = TaskClient('tiago_controller')
        assert cls.client.wait_for_server(rospy.Duration(T)), 'no tiago_controller'

    def setUp(self):
        Fakes.nav_mode, Fakes.detect_mode, Fakes.scan_mode = 'succeed', 'ok', 'corridor'
        wait_for(lambda: not self.fakes.nav_running, 'the last move_base goal to end')
        with self.fakes.lock:
            self.fakes.pose[:] = [0.0, 0.0, 0.0]
        wait_for(self.tf_at_start, 'tf map -> base_footprint at the start pose')

    def tf_at_start(self):
        """The robot's tf, as the proxy reads it, is the reset pose."""
        try:
            t = self.tf.lookup_transform('map', 'base_footprint', rospy.Time(0)).transform
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException):
            return False
        return abs(t.translation.x) + abs(t.translation.y) + abs(t.rotation.z) < 1e-9

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

    def assert_robot_left_alone(self):
        """Nothing moves the fake robot any more: its move_base goal ended (the only mover)."""
        wait_for(lambda: not self.fakes.nav_running and not self.fakes.nav.is_active(),
                 'the move_base goal to end')

    def assert_stop_commanded_after(self, t):
        self.assertTrue(any(c[0] >= t and c[1] == 0 and c[2] == 0 for c in self.cmds),
                        'no zero cmd_vel after the goal ended')

    def test_1_success_states_in_order_and_obstacles_relayed(self):
        t0 = rospy.get_time()
        markers_before = len(self.markers)
        state, result, text, fbs = self.send(2.0, 1.0, 90.0, True)
        self.assertEqual(state, GoalStatus.SUCCEEDED, text)
        st = distinct_states(fbs)
        self.assertEqual(st[:3], [FB.GOAL_RECEIVED, FB.CORRIDOR, FB.NAVIGATING])
        self.assertEqual(self.fakes.corridor_goals, 1)          # a corridor was ahead: the law ran
        self.assertIn(FB.MOVING, st)
        self.assertEqual(st[-3:], [FB.ARRIVED, FB.DETECTING, FB.DETECTION_DONE])
        self.assertTrue(any('m to go' in f.status for f in fbs if f.state == FB.MOVING))
        fx, fy, fyaw = pose_from_msg(result.final_pose.pose)
        # relayed as the node answers: nearest the robot first, robot-frame centres through its
        # pose (rotated by its yaw of 90 deg)
        self.assertEqual([(o.center.x, o.center.y) for o in result.obstacles], nearest_first((2.0, 1.0)))
        for o in result.obstacles:
            rx, ry, _ = compose(inverse((2.0, 1.0, math.radians(90.0))), (o.center.x, o.center.y, 0.0))
            self.assertAlmostEqual(o.center_robot.x, rx, delta=1e-6)
            self.assertAlmostEqual(o.center_robot.y, ry, delta=1e-6)
        self.assertAlmostEqual(fx, 2.0, delta=0.02)
        self.assertAlmostEqual(fy, 1.0, delta=0.02)
        self.assertAlmostEqual(math.degrees(fyaw), 90.0, delta=1.0)
        self.assertEqual(result.final_pose.header.frame_id, 'map')
        self.assertIn('found 2 obstacles', result.message)
        self.assert_stop_commanded_after(t0)
        # the proxy publishes an empty array when the goal starts and the obstacles' before the
        # result; topics are not ordered with each other, so either may still be on its way
        wait_for(lambda: len(self.markers) > markers_before and len(
            [m for m in self.markers[-1].markers if m.ns == 'obstacles']) == 2,
            'the markers of the 2 obstacles found')

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
        wait_for(lambda: self.fakes.nav_preempted > n, 'the move_base goal to be cancelled')
        self.assertEqual(self.fakes.nav_preempted, n + 1)

    def test_1b_no_corridor_ahead_navigates_directly(self):
        Fakes.scan_mode = 'open'
        n = self.fakes.corridor_goals
        state, result, text, fbs = self.send(2.0, 1.0, 90.0, True)
        self.assertEqual(state, GoalStatus.SUCCEEDED, text)
        self.assertEqual(self.fakes.corridor_goals, n)          # the law was not asked
        self.assertIn('no corridor ahead, navigating directly',
                      [f.status for f in fbs if f.state == FB.CORRIDOR])
        self.assertEqual(distinct_states(fbs)[:3], [FB.GOAL_RECEIVED, FB.CORRIDOR, FB.NAVIGATING])

    def test_1c_no_scan_to_judge_the_corridor_aborts(self):
        silent = self.fakes.silent_scans
        Fakes.scan_mode = 'none'
        wait_for(lambda: self.fakes.silent_scans >= silent + 2, 'the fake laser to fall silent')
        state, result, text, _ = self.send(2.0, 1.0, 90.0, True)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertTrue(result.message.startswith('corridor failed: no laser scan on /scan'),
                        result.message)

    def test_4_detection_answering_failure_aborts_naming_detection(self):
        Fakes.detect_mode = 'fail'
        state, result, text, _ = self.send(0.5, 0.0, 0.0, False)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertEqual(result.message, 'detection failed: ' + NO_SCAN)
        self.assertEqual(list(result.obstacles), [])

    def test_4b_detection_crashing_aborts_naming_detection(self):
        Fakes.detect_mode = 'crash'
        state, result, text, _ = self.send(0.5, 0.0, 0.0, False)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertTrue(result.message.startswith('detection failed'), result.message)
        self.assertIn('handler crashed (fake)', result.message)

    def test_5_slow_detection_is_waited_for(self):
        """A detection node that lives but answers only after 3 detection_timeouts is slow, not
        dead: the mission waits for its answer and succeeds with it."""
        Fakes.detect_mode = 'slow'
        t0 = time.monotonic()
        state, result, text, _ = self.send(0.5, 0.0, 0.0, False)
        self.assertEqual(state, GoalStatus.SUCCEEDED, result.message)
        self.assertEqual(len(result.obstacles), len(FOUND))
        self.assertGreaterEqual(time.monotonic() - t0,
                                3 * rospy.get_param('/tiago_controller/detection_timeout'))

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
        wait_for(lambda: self.fakes.nav_preempted > n, 'the move_base goal to be cancelled')
        self.assertEqual(self.fakes.nav_preempted, n + 1)
        self.assert_stop_commanded_after(t0)
        self.assert_robot_left_alone()

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
        self.assertEqual([(float(r[1]), float(r[2])) for r in rows], nearest_first((1.5, -0.5)))
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

    def test_z_killing_the_proxy_cancels_move_base_and_stops_the_base(self):
        """Last: it kills /tiago_controller_killed (a third proxy on the same fakes)."""
        Fakes.nav_mode = 'hang'
        n = self.fakes.nav_preempted
        client = TaskClient('tiago_controller_killed')
        self.assertTrue(client.wait_for_server(rospy.Duration(T)))
        fbs = []
        client.send_goal(TiagoTaskGoal(x=100.0, y=0.0, yaw_deg=0.0, use_corridor_law=False),
                         feedback_cb=fbs.append)
        end = rospy.get_time() + T
        while not any(f.state == FB.MOVING for f in list(fbs)) and rospy.get_time() < end:
            rospy.sleep(0.05)
        self.assertTrue(any(f.state == FB.MOVING for f in fbs), 'never moving')
        t_kill = rospy.get_time()
        subprocess.run(['rosnode', 'kill', '/tiago_controller_killed'], stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, timeout=30)
        wait_for(lambda: self.fakes.nav_preempted > n, 'the killed proxy\'s move_base goal to '
                 'be cancelled')
        self.assertEqual(self.fakes.nav_preempted, n + 1)
        self.assert_stop_commanded_after(t_kill)
        self.assert_robot_left_alone()


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_mission_fakes', MissionFakesTest)
