#!/usr/bin/python3
"""Rostest: start the mission's nodes one by one in different orders, and check that a whole
mission succeeds each time (docs/design-decisions.md, "Trust": nothing depends on start-up
order; every node waits for what it needs).

The nodes and their parameters are demo.launch's own (loaded with roslaunch's API, so this
follows the launch file as it changes); the test sets the parameters, then starts the nodes in
the chosen order, each one once the one before has registered with the master (so it really
starts before anything it needs after it is there), and sends the mission as soon as the
tiago_controller action server is seen (the goal is part of the race too). Then everything is
stopped and the next order starts from scratch.

Private params: ``world`` (path), ``real_time_factor``.
"""
import os
import time
import unittest

import rosgraph
import roslaunch
import rospkg
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from std_msgs.msg import UInt32

from tiago_nav.msg import TiagoTaskGoal
from tiago_nav.ros.actions import TaskClient

WAIT = 60.0          # [s wall] bound on a node's registration, the server, one mission
ORDERS = [
    # every node before everything it waits for: the proxy first, the simulator (the source) last
    ('tiago_controller', 'obstacle_detection', 'corridor_controller', 'move_base', 'simulator'),
    # mixed: the simulator in the middle, the proxy last
    ('obstacle_detection', 'move_base', 'simulator', 'corridor_controller', 'tiago_controller'),
]

def log(text):
    print('start_order: %s' % text, flush=True)


class StartOrderTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_start_order')
        world = rospy.get_param('~world')
        rtf = rospy.get_param('~real_time_factor', 5.0)
        demo = os.path.join(rospkg.RosPack().get_path('tiago_nav'), 'launch', 'demo.launch')
        cls.config = roslaunch.config.load_config_default(
            [(demo, ['world:=%s' % world, 'real_time_factor:=%g' % rtf, 'client:=false',
                     'rviz:=false'])], None)
        cls.nodes = {n.name: n for n in cls.config.nodes}
        for n in cls.nodes.values():
            n.required = False        # stopping the simulator between orders ends nothing else
        cls.master = rosgraph.Master('/test_start_order')
        for name, p in cls.config.params.items():
            cls.master.setParam(name, p.value)
        cls.launch = roslaunch.scriptapi.ROSLaunch()
        cls.launch.start()
        cls.collisions = None
        rospy.Subscriber('/sim/collisions', UInt32, cls._on_collisions)

    @classmethod
    def tearDownClass(cls):
        cls.launch.stop()

    @classmethod
    def _on_collisions(cls, m):
        cls.collisions = m.data

    def registered(self, name):
        try:
            self.master.lookupNode('/' + name)
            return True
        except rosgraph.MasterError:
            return False

    def run_order(self, order):
        """Start the nodes in ``order`` (any node of demo.launch it does not name: after them,
        in the launch file's order) and run the course mission."""
        order = [n for n in order if n in self.nodes] + [n for n in self.nodes if n not in order]
        procs = []
        t0 = time.monotonic()
        try:
            for name in order:
                procs.append(self.launch.launch(self.nodes[name]))
                end = time.monotonic() + WAIT
                while not self.registered(name):
                    self.assertTrue(procs[-1].is_alive(), '%s exited at start-up' % name)
                    self.assertLess(time.monotonic(), end, '%s never registered' % name)
                    time.sleep(0.05)
            log('%s: all started after %.1f s' % (order, time.monotonic() - t0))
            client = TaskClient('tiago_controller')
            self.assertTrue(client.wait_for_server(WAIT), 'no tiago_controller server')
            client.send_goal(TiagoTaskGoal(x=11.0, y=0.0, yaw_deg=-45.0, use_corridor_law=True))
            self.assertTrue(client.wait_for_result(WAIT), 'no result in time')
            log('mission done after %.1f s: %s' % (time.monotonic() - t0, client.get_goal_status_text()))
            result = client.get_result()
            self.assertEqual(client.get_state(), GoalStatus.SUCCEEDED,
                             'order %s: %s' % (order, client.get_goal_status_text()))
            self.assertGreater(len(result.obstacles), 0, result.message)
            self.assertEqual(self.collisions, 0)
            dead = [n for n, p in zip(order, procs) if not p.is_alive()]
            self.assertEqual(dead, [], 'nodes exited during the mission')
        finally:
            for p in procs:
                p.stop()
            end = time.monotonic() + WAIT
            while any(self.registered(n) for n in order) and time.monotonic() < end:
                time.sleep(0.05)
            self.collisions = type(self).collisions = None
            log('stopped after %.1f s' % (time.monotonic() - t0))

    def test_1_proxy_first_simulator_last(self):
        self.run_order(ORDERS[0])

    def test_2_mixed_simulator_in_the_middle_proxy_last(self):
        self.run_order(ORDERS[1])

if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_start_order', StartOrderTest)
