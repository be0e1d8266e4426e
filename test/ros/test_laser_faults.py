#!/usr/bin/python3
"""Rostest: laser faults injected through the simulator's ``/sim/laser_fault`` during whole
missions over the real chain (demo.launch), judged on ground truth (/sim/ground_truth,
/sim/collisions).

In order (one launch, the course world from its start):
1. during the corridor law, 2 s of NaN ranges: the base stops (an unusable scan is "blocked"),
   then the law resumes and the mission succeeds;
2.-5. from pose B, missions to nearby goals with, while the robot moves, 2 s of NaN ranges and
   2 s of zeros (the base stops within the fault: an all-invalid scan blocks driving), a 2 s
   frozen scan and a 2 s dead laser (the base, by ground truth, brakes from within 1 s of the
   fault at the base's deceleration, comes to rest and stays put until real scans return;
   move_base commands nothing but a stop meanwhile); each mission then succeeds (short gaps
   resume);
6. a laser that stays dead: the base stops and the mission aborts with
   ``navigation failed: move_base aborted: no laser data for 3.0 s``.
Every case: no collision. The bound on stopping: within the fault, i.e. the base's speed
(ground truth) falls below 0.05 m/s less than FAULT seconds (simulated) after the command.
move_base's commands are read from its lockstep answers (each stamped with its cycle), or from
cmd_vel outside lockstep.

Private params: ``world`` (path).
"""
import math
import sys
import threading
import time
import unittest

import actionlib
import rospy
import rostest
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Twist
from move_base_msgs.msg import MoveBaseAction
from nav_msgs.msg import Odometry
from std_msgs.msg import String, UInt32

from tiago_nav.msg import (CorridorAction, LockstepAck, TiagoTaskAction,
                           TiagoTaskFeedback as FB, TiagoTaskGoal)
from tiago_nav.ros.actions import TaskClient, wait_server
from tiago_nav.ros.lockstep import ACK_TOPIC, USE_LOCKSTEP
from tiago_nav.sim.diffdrive import BaseLimits
from tiago_nav.sim.world import load_world

from test_mission import MissionTest

WAIT = 90.0          # [s wall] bound on server waits and on one mission
FAULT = 2.0          # [s simulated] length of a fault burst
STOPPED = 0.05       # [m/s] stopped below this (ground truth, linear speed)
SILENT_STOP = 1.0    # [s simulated] move_base's stop command within this of a silent laser
                     # (sensor_timeout 0.5 s + control periods + delivery)
DECEL = BaseLimits().max_linear_acceleration   # [m/s^2] the simulated base's braking
SAMPLE = 0.1         # [s simulated] slack of one ground-truth sample and one control cycle
PUT = 0.02           # [m] at rest, the base moves less than this (ground truth)
MOVING = 0.2         # [m/s] the fault is injected once the robot drives at least this fast


class LaserFaultTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_laser_faults')
        cls.world = load_world(rospy.get_param('~world'))
        cls.tf = tf2_ros.Buffer()
        cls.listener = tf2_ros.TransformListener(cls.tf)
        cls.lock = threading.Lock()
        cls.speeds = []              # (stamp [s sim], linear speed [m/s]) from ground truth
        cls.places = []              # (stamp [s sim], x, y) from ground truth
        cls.collisions = None
        cls.cmds = []                # (time [s sim], linear.x) of move_base's commands
        rospy.Subscriber('/sim/ground_truth', Odometry, cls._on_truth)
        if rospy.get_param(USE_LOCKSTEP, False):
            # in lockstep each command comes in move_base's answer, stamped with its cycle: a
            # cmd_vel copy stamped with this process's ROS time on arrival could be stamped up
            # to a second of simulated time early on a loaded machine (a command after the
            # fault's end then counted as one during it)
            rospy.Subscriber(ACK_TOPIC, LockstepAck, cls._on_ack, queue_size=None)
        else:
            rospy.Subscriber('/mobile_base_controller/cmd_vel', Twist, cls._on_cmd)
        rospy.Subscriber('/sim/collisions', UInt32, cls._on_collisions)
        cls.fault = rospy.Publisher('/sim/laser_fault', String, queue_size=10)
        cls.client = TaskClient('tiago_controller')
        for name, kind in (('tiago_controller', TiagoTaskAction), ('move_base', MoveBaseAction),
                           ('corridor_controller', CorridorAction)):
            assert wait_server(actionlib.SimpleActionClient(name, kind), WAIT), 'no %s' % name
        rospy.wait_for_service('obstacle_detection', WAIT)
        end = time.monotonic() + WAIT
        while cls.fault.get_num_connections() == 0:          # the simulator subscribed
            assert time.monotonic() < end, 'the simulator never subscribed to /sim/laser_fault'
            time.sleep(0.05)

    @classmethod
    def _on_truth(cls, m):
        t = m.twist.twist
        with cls.lock:
            cls.speeds.append((m.header.stamp.to_sec(), math.hypot(t.linear.x, t.linear.y)))
            cls.places.append((m.header.stamp.to_sec(), m.pose.pose.position.x,
                               m.pose.pose.position.y))

    @classmethod
    def _on_cmd(cls, m):
        if m._connection_header.get('callerid') == '/move_base':
            with cls.lock:
                cls.cmds.append((rospy.get_time(), m.linear.x))

    @classmethod
    def _on_ack(cls, m):
        if m.node == '/move_base' and m.has_command:
            with cls.lock:
                cls.cmds.append((m.stamp.to_sec(), m.cmd.linear.x))

    @classmethod
    def _on_collisions(cls, m):
        cls.collisions = m.data

    def pose(self):
        return MissionTest.pose(self)

    def free_goal_near(self, pose, dist):
        return MissionTest.free_goal_near(self, pose, dist)

    def speed(self):
        with self.lock:
            return self.speeds[-1] if self.speeds else (None, 0.0)

    def run_with_fault(self, goal, corridor, when, command):
        """Send the mission ``goal`` (x, y, yaw_deg); once ``when(feedback)`` holds and the
        robot drives faster than :data:`MOVING`, publish the fault ``command``. Returns
        (GoalStatus, result message, fault time [s sim], feedback list)."""
        fbs = []
        self.client.send_goal(TiagoTaskGoal(x=goal[0], y=goal[1], yaw_deg=goal[2],
                                            use_corridor_law=corridor), feedback_cb=fbs.append)
        end = time.monotonic() + WAIT
        while not (any(when(f) for f in list(fbs)) and self.speed()[1] > MOVING):
            self.assertLess(time.monotonic(), end, 'never %s' % command)
            self.assertFalse(self.client.wait_for_result(0.0), 'the mission ended before the '
                             'fault: %s' % self.client.get_goal_status_text())
            time.sleep(0.02)
        t_fault = self.speed()[0]
        self.fault.publish(String(command))
        self.assertTrue(self.client.wait_for_result(WAIT), 'no result in time')
        result = self.client.get_result()
        return (self.client.get_state(), result.message if result else '', t_fault, fbs)

    def assert_stopped_within(self, t_fault, bound):
        """The base's linear speed fell below :data:`STOPPED` within ``bound`` [s sim] of the
        fault; return when [s after the fault]."""
        with self.lock:
            window = [(t, v) for t, v in self.speeds if t_fault <= t <= t_fault + bound]
            stops = [t for t, v in window if v < STOPPED]
        self.assertTrue(window, 'no ground truth within %g s of the fault' % bound)
        self.assertTrue(stops, 'the base did not stop within %g s of the fault (lowest speed '
                        '%.2f m/s)' % (bound, min(v for _, v in window)))
        return stops[0] - t_fault

    def check_burst(self, kind, goal=None, corridor=False, when=None):
        if goal is None:
            start = self.pose()
            goal = self.free_goal_near(start, 3.0) + (math.degrees(start[2]),)
        when = when or (lambda f: f.state == FB.MOVING)
        state, msg, t_fault, fbs = self.run_with_fault(goal, corridor, when,
                                                       '%s %g' % (kind, FAULT))
        self.assertEqual(state, GoalStatus.SUCCEEDED, msg)
        stop = self.assert_stopped_within(t_fault, FAULT)
        rospy.loginfo('%s %g s: stopped %.2f s after the fault; mission: %s', kind, FAULT, stop,
                      msg)
        self.assertEqual(self.collisions, 0)
        return fbs

    def test_1_nan_burst_in_the_corridor_stops_the_law_which_resumes(self):
        fbs = self.check_burst('nan', (11.0, 0.0, -45.0), True,
                               lambda f: f.state == FB.CORRIDOR
                               and f.status.startswith('in the corridor'))
        self.assertIn(FB.NAVIGATING, [f.state for f in fbs])

    def test_2_nan_burst_while_navigating_stops_and_resumes(self):
        self.check_burst('nan')

    def test_3_zero_burst_while_navigating_stops_and_resumes(self):
        self.check_burst('zero')

    def test_4_frozen_scan_while_navigating_stops_and_resumes(self):
        """A frozen scan (the same ranges again with new stamps, a stuck driver) is no fresh
        data to move_base (scan.FrozenScanCheck): it commands a stop once the newest real scan
        is older than sensor_timeout and nothing else while the scans repeat; then it resumes."""
        self.check_silent('freeze')

    def test_5_dead_laser_for_a_moment_stops_and_resumes(self):
        """move_base commands a stop once the newest scan is older than sensor_timeout (0.5 s)
        and commands nothing else while the laser is silent; the robot brakes (at 1 m/s^2 it
        may not reach 0 before the 2 s gap ends); then it resumes and the mission succeeds."""
        self.check_silent('dead')

    def check_silent(self, kind):
        start = self.pose()
        goal = self.free_goal_near(start, 3.0) + (math.degrees(start[2]),)
        state, msg, t_fault, _ = self.run_with_fault(goal, False, lambda f: f.state == FB.MOVING,
                                                     '%s %g' % (kind, FAULT))
        self.assertEqual(state, GoalStatus.SUCCEEDED, msg)
        self.assert_braked_and_stayed_put(t_fault, kind)
        with self.lock:
            stops = [t for t, v in self.cmds if t_fault <= t <= t_fault + SILENT_STOP and v == 0]
            self.assertTrue(stops, 'move_base did not command a stop within %g s of the laser '
                            'fault %s' % (SILENT_STOP, kind))
            during = [v for t, v in self.cmds if stops[0] <= t <= t_fault + FAULT - 0.2]
        self.assertEqual(max(abs(v) for v in during), 0.0, 'drove during the fault %s' % kind)
        self.assertEqual(self.collisions, 0)

    def assert_braked_and_stayed_put(self, t_fault, kind):
        """Ground truth through a silent-laser fault: from :data:`SILENT_STOP` after the fault
        the base's speed only falls, at least as fast as the base brakes, until it is at rest;
        at rest it stays put until the fault ends."""
        end = t_fault + FAULT
        with self.lock:
            speeds = [(t, v) for t, v in self.speeds if t_fault <= t <= end]
            places = [(t, x, y) for t, x, y in self.places if t_fault <= t <= end]
        self.assertTrue(speeds, 'no ground truth during the fault %s' % kind)
        v0 = speeds[0][1]
        t_brake = t_fault + SILENT_STOP
        # the fastest it may go once braking began: what it reached by then (it may still have
        # been speeding up until the stop came)
        vb = max(v for t, v in speeds if t <= t_brake + SAMPLE)
        for t, v in speeds:          # braking: never faster than the brake from t_brake allows
            allowed = max(0.0, vb - DECEL * (t - t_brake - SAMPLE)) if t > t_brake + SAMPLE else 1e9
            self.assertLessEqual(v, allowed + STOPPED, 'the base drove at %.2f m/s %.2f s into '
                                 'the fault %s (at most %.2f m/s braking from %.2f m/s)'
                                 % (v, t - t_fault, kind, allowed, vb))
        rest = [t for t, v in speeds if v < STOPPED]
        if t_brake + vb / DECEL + 2 * SAMPLE < end:       # it had the time to come to rest
            self.assertTrue(rest, 'the base never came to rest during the fault %s' % kind)
        if rest:
            put = [(x, y) for t, x, y in places if rest[0] <= t <= end - 0.2]
            moved = max((math.hypot(x - put[0][0], y - put[0][1]) for x, y in put), default=0.0)
            self.assertLess(moved, PUT, 'at rest, the base moved %.3f m during the fault %s'
                            % (moved, kind))
        rospy.loginfo('%s %g s: %.2f m/s at the fault, at rest %s', kind, FAULT, v0,
                      '%.2f s after it' % (rest[0] - t_fault) if rest else 'not before its end')

    def test_6_dead_laser_stops_the_base_and_aborts(self):
        start = self.pose()
        goal = self.free_goal_near(start, 3.0) + (math.degrees(start[2]),)
        try:
            state, msg, t_fault, _ = self.run_with_fault(goal, False,
                                                         lambda f: f.state == FB.MOVING, 'dead')
        finally:
            self.fault.publish(String('none'))
        self.assertEqual(state, GoalStatus.ABORTED, msg)
        self.assertTrue(msg.startswith('navigation failed: move_base aborted: no laser data for'),
                        msg)
        self.assert_stopped_within(t_fault, FAULT)
        self.assertEqual(self.collisions, 0)


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_laser_faults', LaserFaultTest)
