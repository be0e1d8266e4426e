#!/usr/bin/python3
"""Rostest of dynamic_reconfigure on move_base and corridor_controller, with the standard client
(what `rosrun dynamic_reconfigure dynparam set` and rqt_reconfigure use).

During a long move_base goal (the course's pose B, through the corridor), once the robot's true
speed (/sim/ground_truth, differences of its positions) is above 0.3 m/s, max_vel_x is set to
0.3. A change comes in force at the next control cycle's boundary (0.1 s at move_base's 10 Hz)
and the controller then brakes at acc_lim_x (1 m/s^2, the base's own limit too), so from the
request on the speed must stay under ``max(0.3, v0 - acc_lim_x * (t - t0 - LAG)) + EPS``: v0 the
speed when the request was made, t0 the test's ROS time then, LAG one cycle for the cycle in
progress plus up to 0.2 s by which this test's /clock may trail the simulator's (real-time
factor 1, lockstep), EPS the noise of a speed from two 0.1 s-apart true positions. It must
reach 0.3 m/s within (v0 - 0.3) / acc_lim_x + LAG and stay there while the goal runs on; the
goal then succeeds with the speed restored. A change the node refuses (inflation_radius below
the robot's radius) leaves the values in force, on the server and on the parameter server.
"""
import math
import threading

import actionlib
import dynamic_reconfigure.client
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import Odometry

from tiago_nav.ros.actions import wait_server
from tiago_nav.ros.conversions import pose_stamped

from simtest import SimTestCase

TIMEOUT = 30.0
LIMIT = 0.3         # [m/s] the max_vel_x set during the goal
ACC = 1.0           # [m/s^2] acc_lim_x (config/navigation.yaml), the base's limit too
LAG = 0.3           # [s] one control cycle + this test's clock lag (module docstring)
EPS = 0.03          # [m/s] noise of a speed from true positions 0.1 s apart
WINDOW = 0.1        # [s] of simulated time between the two positions of one speed


class Speeds:
    """The robot's true speed [m/s] over each WINDOW of simulated time, from /sim/ground_truth."""

    def __init__(self):
        self.lock = threading.Lock()
        self.samples = []           # (t, x, y)
        self.sub = rospy.Subscriber('/sim/ground_truth', Odometry, self.on_truth, queue_size=100)

    def on_truth(self, msg):
        p = msg.pose.pose.position
        with self.lock:
            self.samples.append((msg.header.stamp.to_sec(), p.x, p.y))

    def since(self, t0):
        """``[(t, v)]``: the speed over (t - WINDOW, t] for every sample t > t0 + WINDOW."""
        with self.lock:
            s = list(self.samples)
        out, j = [], 0
        for i, (t, x, y) in enumerate(s):
            while j < i and s[j + 1][0] <= t - WINDOW:
                j += 1
            tj, xj, yj = s[j]
            if t > t0 and t - tj >= WINDOW - 1e-6:
                out.append((t, math.hypot(x - xj, y - yj) / (t - tj)))
        return out


class ReconfigureTest(SimTestCase):
    node_name = 'test_reconfigure'

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.speeds = Speeds()
        cls.nav = actionlib.SimpleActionClient('move_base', MoveBaseAction)
        assert wait_server(cls.nav, TIMEOUT), 'no move_base server'
        cls.move_base = dynamic_reconfigure.client.Client('move_base', timeout=TIMEOUT)
        cls.corridor = dynamic_reconfigure.client.Client('corridor_controller', timeout=TIMEOUT)

    def wait_sim(self, seconds):
        end = rospy.Time.now() + rospy.Duration(seconds)
        while rospy.Time.now() < end and not rospy.is_shutdown():
            rospy.sleep(0.05)

    def test_1_refused_change_keeps_the_values(self):
        before = self.move_base.get_configuration(TIMEOUT)
        got = self.move_base.update_configuration({'inflation_radius': 0.2, 'xy_goal_tolerance': 0.2})
        self.assertEqual(got['inflation_radius'], before['inflation_radius'])
        self.assertEqual(got['xy_goal_tolerance'], before['xy_goal_tolerance'])
        self.assertEqual(rospy.get_param('/move_base/inflation_radius'), before['inflation_radius'])

    def test_2_corridor_controller_reconfigures(self):
        got = self.corridor.update_configuration({'speed_limit': 0.6})
        self.assertEqual(got['speed_limit'], 0.6)
        self.assertEqual(rospy.get_param('/corridor_controller/speed_limit'), 0.6)
        got = self.corridor.update_configuration({'speed_limit': 1.0})
        self.assertEqual(got['speed_limit'], 1.0)

    def test_3_max_vel_x_limits_the_speed_from_the_next_cycle(self):
        goal = MoveBaseGoal(target_pose=pose_stamped((11.0, 0.0, math.radians(-45)), 'map',
                                                     rospy.Time.now()))
        start = rospy.Time.now().to_sec()
        self.nav.send_goal(goal)
        # until the robot drives well above the limit to come
        fast = []
        end = rospy.Time.now().to_sec() + 30.0
        while rospy.Time.now().to_sec() < end:
            fast = [v for t, v in self.speeds.since(rospy.Time.now().to_sec() - 0.5)]
            if fast and min(fast) > 0.6:
                break
            rospy.sleep(0.02)
        self.assertTrue(fast and min(fast) > 0.6, 'the robot never drove above 0.6 m/s: %s' % fast)
        before = [v for t, v in self.speeds.since(start)]
        v0 = max(v for t, v in self.speeds.since(rospy.Time.now().to_sec() - 0.3))
        got = self.move_base.update_configuration({'max_vel_x': LIMIT})
        t0 = rospy.Time.now().to_sec()
        self.assertEqual(got['max_vel_x'], LIMIT)
        self.assertEqual(rospy.get_param('/move_base/max_vel_x'), LIMIT)
        self.assertGreater(max(before), LIMIT + 0.3, 'not faster than the limit before')
        self.wait_sim(6.0)
        self.assertEqual(self.nav.get_state(), GoalStatus.ACTIVE, 'the goal ended early: %s'
                         % self.nav.get_goal_status_text())
        after = self.speeds.since(t0)
        self.assertGreater(len(after), 40, 'too few ground-truth samples')
        for t, v in after:
            bound = max(LIMIT, v0 - ACC * (t - t0 - LAG)) + EPS
            self.assertLessEqual(v, bound, '%.2f m/s at %.2f s after max_vel_x 0.3 (v0 %.2f): '
                                 'bound %.2f' % (v, t - t0, v0, bound))
        settled = t0 + (v0 - LIMIT) / ACC + LAG
        late = [v for t, v in after if t > settled]
        self.assertTrue(late and max(late) <= LIMIT + EPS, max(late or [0]))
        self.assertGreater(max(late), 0.2, 'the robot stopped instead of driving at 0.3 m/s')
        first = next(t for t, v in after if v <= LIMIT + EPS)
        rospy.loginfo('reconfigure_test: v0 %.3f m/s; <= %.2f m/s from %.2f s after the request '
                      '(the ramp allows %.2f s); then max %.3f m/s over %d samples', v0,
                      LIMIT + EPS, first - t0, settled - t0, max(late), len(late))
        # the speed back: the goal goes on and succeeds
        self.move_base.update_configuration({'max_vel_x': 1.0})
        self.assertTrue(self.nav.wait_for_result(rospy.Duration(90.0)), 'no result')
        self.assertEqual(self.nav.get_state(), GoalStatus.SUCCEEDED,
                         self.nav.get_goal_status_text())


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'reconfigure_test', ReconfigureTest)
