#!/usr/bin/python3
"""Rostest: kill a downstream node (SIGKILL: a crash, no goodbye) mid-mission over the real
chain (demo.launch) while the real client executable (``rosrun tiago_nav client``) runs the
task; the proxy must abort naming the stage and the reason, on its own lost-server timer
(``server_lost_timeout``, named in the message) and not on its longer ``server_timeout`` (the
bound, read from its parameters), the client must exit 1 with that line, the base must stop
(ground truth) within :data:`STOP_SIM` of simulated time and nothing may collide. The only
other wall bound is :data:`WAIT`, a guard against hangs.

A node can be killed only once per launch, so the cases are ordered (test names) within two
classes, chosen by the test's argument:
- ``chain`` (course world, from its start): corridor_controller killed in the corridor; then
  (corridor law off) obstacle_detection killed once the robot has arrived, before DETECTING;
  then move_base killed while the robot moves; then the proxy itself (waiting for move_base):
  the client exits 1 on its own lost-server timer.
- ``sim`` (course world, starting near pose B, ``sim_required:=false``): obstacle_detection
  killed during its call (frozen first, so that the call hangs in it); then the
  simulator killed while the robot moves.

Private params: ``world`` (path).
"""
import math
import os
import signal
import subprocess
import sys
import threading
import time
import unittest

import actionlib
import rospy
import rostest
import tf2_ros
from move_base_msgs.msg import MoveBaseAction
from actionlib_msgs.msg import GoalStatus
from nav_msgs.msg import Odometry
from std_msgs.msg import UInt32

from tiago_nav.nodes.client import SERVER_LOST
from tiago_nav.msg import (CorridorAction, TiagoTaskAction, TiagoTaskActionFeedback,
                           TiagoTaskActionResult, TiagoTaskFeedback as FB)
from tiago_nav.ros.actions import wait_server
from tiago_nav.sim.world import load_world
from tiago_nav_tools.testing import harness

from test_mission import MissionTest

WAIT = 60.0          # [s wall] bound on waits for servers, states and the client's exit
STOPPED = 0.05       # [m/s] the base counts as stopped below this (ground truth)
STOP_SIM = 3.0       # [s simulated] after the result, the base is at rest within this: the
#                      simulator's cmd_timeout (0.5 s) and braking from full speed, with room


def node_pid(name):
    """The pid of the running node ``name`` (asked over its XML-RPC API)."""
    return harness.node_pid(name, '/test_fault_kill')


class Watch:
    """The task as the action's topics show it (whoever sent the goal): feedback, the result
    and the wall time it arrived; the ground-truth speed; the collision count."""

    def __init__(self):
        self.lock = threading.Condition()
        self.feedback, self.result, self.t_result = [], None, None
        self.sim_result = None            # [s ROS] when the result came
        self.sim_stopped = None           # [s ROS] stamp of the first truth at rest after it
        self.speed, self.collisions = None, None
        rospy.Subscriber('/tiago_controller/feedback', TiagoTaskActionFeedback, self._on_fb)
        rospy.Subscriber('/tiago_controller/result', TiagoTaskActionResult, self._on_result)
        rospy.Subscriber('/sim/ground_truth', Odometry, self._on_truth)
        rospy.Subscriber('/sim/collisions', UInt32, self._on_collisions)

    def _on_fb(self, m):
        with self.lock:
            self.feedback.append((time.monotonic(), m.feedback))
            self.lock.notify_all()

    def _on_result(self, m):
        with self.lock:
            self.result, self.t_result = m, time.monotonic()
            self.sim_result = rospy.get_time()
            self.lock.notify_all()

    def _on_truth(self, m):
        t = m.twist.twist
        self.speed = (math.hypot(t.linear.x, t.linear.y), abs(t.angular.z))
        with self.lock:
            if self.sim_result is not None and self.sim_stopped is None \
                    and self.speed[0] < STOPPED and self.speed[1] < 0.1 \
                    and m.header.stamp.to_sec() >= self.sim_result:
                self.sim_stopped = m.header.stamp.to_sec()
                self.lock.notify_all()

    def _on_collisions(self, m):
        self.collisions = m.data

    def reset(self):
        with self.lock:
            self.feedback, self.result, self.t_result = [], None, None
            self.sim_result = self.sim_stopped = None

    def wait(self, cond, timeout, what):
        """Wait (wall ``timeout``) until ``cond()`` holds (checked under the lock)."""
        end = time.monotonic() + timeout
        with self.lock:
            while not cond():
                left = end - time.monotonic()
                assert left > 0, 'timed out waiting for %s' % what
                self.lock.wait(min(left, 0.2))


class KillTest(unittest.TestCase):
    """Shared set-up and the one case: run a task with the client, kill a node when the
    feedback says so, check the abort."""

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_fault_kill')
        cls.world = load_world(rospy.get_param('~world'))
        cls.watch = Watch()
        cls.tf = tf2_ros.Buffer()
        cls.listener = tf2_ros.TransformListener(cls.tf)
        for name, kind in (('tiago_controller', TiagoTaskAction), ('move_base', MoveBaseAction),
                           ('corridor_controller', CorridorAction)):
            assert wait_server(actionlib.SimpleActionClient(name, kind), WAIT), 'no %s' % name
        rospy.wait_for_service('obstacle_detection', WAIT)
        cls.lost = rospy.get_param('/tiago_controller/server_lost_timeout')
        cls.bound = rospy.get_param('/tiago_controller/server_timeout')
        assert cls.lost < cls.bound

    def pose(self):
        return MissionTest.pose(self)

    def free_goal_near(self, pose, dist):
        return MissionTest.free_goal_near(self, pose, dist)

    def start_client(self, x, y, yaw, corridor):
        self.watch.reset()
        return subprocess.Popen(
            ['rosrun', 'tiago_nav', 'client', '%.3f' % x, '%.3f' % y, '%.1f' % yaw,
             '--corridor=%s' % ('true' if corridor else 'false')],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def kill_when(self, client, trigger, node, bound_from=None, pid=None):
        """Wait for a feedback that ``trigger(fb)`` accepts, then SIGKILL ``node``; then check
        the abort (sooner than the proxy's ``server_timeout`` after the kill, or after the
        first feedback ``bound_from`` accepts if that comes later: its lost-server timer, not
        the wait for a server that never came) and the client's exit; return the result's
        message."""
        try:
            self.wait_feedback(trigger, 'the feedback to kill %s at' % node)
            os.kill(pid or node_pid(node), signal.SIGKILL)
            t_ref = time.monotonic()
            self.watch.wait(lambda: self.watch.result is not None, WAIT, 'the task result')
            if bound_from is not None:
                t_ref = max(t_ref, next(t for t, f in self.watch.feedback if bound_from(f)))
            out, _ = client.communicate(timeout=WAIT)
        finally:
            if client.poll() is None:
                client.kill()
        r = self.watch.result
        self.assertEqual(r.status.status, GoalStatus.ABORTED, r.result.message)
        self.assertLess(self.watch.t_result - t_ref, self.bound,
                        'the abort came %.1f s after killing %s: %s'
                        % (self.watch.t_result - t_ref, node, r.result.message))
        self.assertEqual(client.returncode, 1, out)
        self.assertIn('ABORTED: ' + r.result.message, out)
        return r.result.message

    def wait_feedback(self, trigger, what):
        self.watch.wait(lambda: any(trigger(f) for _, f in self.watch.feedback), WAIT, what)

    def states(self):
        return [f.state for _, f in self.watch.feedback]

    def assert_stopped(self):
        """The base comes to rest (ground truth) within :data:`STOP_SIM` of simulated time
        after the abort, with no collision."""
        self.watch.wait(lambda: self.watch.sim_stopped is not None, WAIT,
                        'the base to come to rest (still %s)' % (self.watch.speed,))
        self.assertLessEqual(self.watch.sim_stopped - self.watch.sim_result, STOP_SIM,
                             'at rest %.2f s of simulated time after the abort'
                             % (self.watch.sim_stopped - self.watch.sim_result))
        self.assertEqual(self.watch.collisions, 0)


class ChainTest(KillTest):
    def test_1_corridor_controller_killed_in_the_corridor(self):
        c = self.start_client(11.0, 0.0, -45.0, True)
        msg = self.kill_when(c, lambda f: f.state == FB.CORRIDOR
                             and f.status.startswith('in the corridor'), '/corridor_controller')
        self.assertTrue(msg.startswith('corridor failed: the corridor_controller server went '
                                       'away'), msg)
        self.assertIn('gone for %g s' % self.lost, msg)
        self.assert_stopped()

    def test_2_detection_killed_before_detecting(self):
        """Killed during navigation: the proxy finds it gone when it needs it, after DETECTING,
        and aborts naming the fact (its registration stayed, its process is gone)."""
        c = self.start_client(11.0, 0.0, -45.0, False)
        msg = self.kill_when(c, lambda f: f.state == FB.MOVING, '/obstacle_detection',
                             bound_from=lambda f: f.state == FB.DETECTING)
        self.assertTrue(msg.startswith('detection failed: the /obstacle_detection service went '
                                       'away'), msg)
        self.assertIn("registered, but its node's process is gone", msg)
        self.assertIn(FB.DETECTING, self.states())
        self.assert_stopped()

    def test_3_move_base_killed_while_moving(self):
        gx, gy = self.free_goal_near(self.pose(), 2.5)
        c = self.start_client(gx, gy, 0.0, False)
        msg = self.kill_when(c, lambda f: f.state == FB.MOVING, '/move_base')
        self.assertTrue(msg.startswith('navigation failed: the move_base server went away'), msg)
        self.assertIn('gone for %g s' % self.lost, msg)
        self.assert_stopped()

    def test_4_proxy_killed_the_client_exits_1(self):
        """move_base is gone (test 3), so the proxy waits for it in NAVIGATING: killed there,
        the client must not wait forever: it gives up on its own lost-server timer
        (SERVER_LOST, named in its line), sooner than its wait for a server that never came."""
        c = self.start_client(11.0, 0.0, -45.0, False)
        try:
            self.wait_feedback(lambda f: f.state == FB.NAVIGATING, 'NAVIGATING')
            os.kill(node_pid('/tiago_controller'), signal.SIGKILL)
            out, _ = c.communicate(timeout=WAIT)
        finally:
            if c.poll() is None:
                c.kill()
        self.assertEqual(c.returncode, 1, out)
        self.assertIn('ABORTED: tiago_controller failed: the /tiago_controller action server '
                      'went away (gone for %g s)' % SERVER_LOST, out)


class SimTest(KillTest):
    def test_1_detection_killed_during_its_call(self):
        """The node is frozen (SIGSTOP) while the robot moves, so the proxy's call hangs in
        it; killed at DETECTING, the call fails at once."""
        gx, gy = self.free_goal_near(self.pose(), 1.5)
        pid = node_pid('/obstacle_detection')
        c = self.start_client(gx, gy, 0.0, False)
        self.wait_feedback(lambda f: f.state == FB.MOVING, 'MOVING')
        os.kill(pid, signal.SIGSTOP)
        msg = self.kill_when(c, lambda f: f.state == FB.DETECTING, '/obstacle_detection',
                             pid=pid)
        # the kill races the proxy's call: in flight, the call fails; not yet made, the
        # proxy finds the service registered but dead. Either way detection is named.
        self.assertTrue(msg.startswith('detection failed: the obstacle_detection service failed')
                        or msg.startswith('detection failed: the /obstacle_detection service '
                                          'went away'), msg)
        self.assert_stopped()

    def test_2_simulator_killed_while_moving(self):
        gx, gy = self.free_goal_near(self.pose(), 2.5)
        c = self.start_client(gx, gy, 0.0, False)
        msg = self.kill_when(c, lambda f: f.state == FB.MOVING, '/simulator')
        self.assertTrue(msg.startswith('navigation failed'), msg)
        self.assertIn('ROS time stopped advancing', msg)
        # the verdict names what it rests on: the simulator's process gone, its connection
        # closed or its /clock unregistered (never ROS time standing still alone)
        self.assertTrue(any(fact in msg for fact in (
            'the process of /simulator, which published /clock, is gone',
            'the connection to /simulator, which publishes /clock, is closed',
            'nothing publishes /clock any more')), msg)


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_fault_kill', SimTest if 'sim' in sys.argv[1:] else ChainTest)
