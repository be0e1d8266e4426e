#!/usr/bin/python3
"""Rostest of the obstacle_detection node's start-up and failure paths, the test standing in for
the robot: no service until the map arrives (and a fatal exit when it never does), then no
/scan, no transform, corrupted but usable ranges, scans with too few valid beams (all NaN, all
zero), bad requests and an unusable map. Every failure must answer success=false, no obstacles
and a message naming the cause; the node must keep serving afterwards. The scans are the
pybullet cast of test/worlds/detection_row.yaml with seeded noise; ground truth is the world
file and tiago_nav_tools.evaluate.inview.view_from."""
import math
import subprocess
import threading
import time
import unittest

import numpy as np
import rosgraph
import roslib.packages
import rospy
import rostest
import tf2_ros
from sensor_msgs.msg import LaserScan
from nav_msgs.msg import OccupancyGrid

from tiago_nav.geometry import compose, inverse
from tiago_nav.ros.conversions import gridmap_to_msg, transform_stamped
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import LaserConfig, Scene, noisy
from tiago_nav.sim.world import load_world
from tiago_nav.srv import DetectObstacles, DetectObstaclesRequest
from tiago_nav_tools.evaluate.inview import view_from

TIMEOUT = 20.0
POSE = (0.3, -0.2, math.radians(10.0))     # base_footprint in map


class DetectionErrorsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_detection_errors')
        cls.world = load_world(rospy.get_param('~world'))
        cls.laser = LaserConfig()
        with Scene(cls.world) as scene:
            cls.clean, _ = scene.cast(POSE)
            cls.visible = view_from(scene, POSE).in_view
        cls.rng = np.random.default_rng(5)
        cls.corrupt = None
        cls.pub_map = rospy.Publisher('/map', OccupancyGrid, queue_size=1, latch=True)
        cls.pub_scan = rospy.Publisher('/scan', LaserScan, queue_size=5)
        cls.tf_static = tf2_ros.StaticTransformBroadcaster()
        cls.call = rospy.ServiceProxy('obstacle_detection', DetectObstacles)
        cls.scanning = threading.Event()
        cls.stop = threading.Event()
        cls.thread = threading.Thread(target=cls.scan_loop, daemon=True)
        cls.thread.start()

    @classmethod
    def tearDownClass(cls):
        cls.stop.set()
        cls.thread.join(2.0)

    @classmethod
    def scan_loop(cls):
        cfg = cls.laser
        while not cls.stop.is_set() and not rospy.is_shutdown():
            if cls.scanning.is_set():
                r = noisy(cls.clean, 0.01, cls.rng, cfg.range_min, cfg.range_max)
                if cls.corrupt == 'some':       # 27 % invalid: still judged
                    r[::7] = np.nan
                    r[3::11] = np.inf
                    r[5::13] = -1.0
                    r[6::17] = 1e6
                elif cls.corrupt == 'nan':      # a dead laser
                    r[:] = np.nan
                elif cls.corrupt == 'zero':     # a driver that publishes zeros
                    r[:] = 0.0
                s = LaserScan()
                s.header.stamp = rospy.Time.now()
                s.header.frame_id = 'base_laser_link'
                s.angle_min, s.angle_max = cfg.angle_min, cfg.angle_max
                s.angle_increment = cfg.angle_increment
                s.range_min, s.range_max = cfg.range_min, cfg.range_max
                s.ranges = r.tolist()
                cls.pub_scan.publish(s)
            cls.stop.wait(0.05)

    def found_ok(self, resp, tol=0.03):
        self.assertTrue(resp.success, resp.message)
        self.assertEqual(len(resp.obstacles), len(self.visible), resp.message)
        for i in self.visible:
            c = self.world.movable_obstacles[i]
            e = min(math.hypot(o.center.x - c.x, o.center.y - c.y) for o in resp.obstacles)
            self.assertLess(e, tol, resp.message)

    def failed(self, resp, *words):
        """``resp`` is a failure whose message holds every one of ``words``."""
        self.assertFalse(resp.success, resp.message)
        self.assertEqual(len(resp.obstacles), 0, resp.message)
        for w in words:
            self.assertIn(w, resp.message)

    def call_until(self, req, done):
        """Call until ``done(resp)`` (a transform or map that was just published has to reach
        the node), for up to TIMEOUT wall seconds; returns the last answer."""
        deadline = time.monotonic() + TIMEOUT
        resp = self.call(req)
        while not done(resp) and time.monotonic() < deadline:
            resp = self.call(req)
        return resp

    def set_corrupt(self, mode):
        """Scans from now on are corrupted as ``mode`` says; returns once one has been sent."""
        self.__class__.corrupt = mode
        sub = rospy.wait_for_message('/scan', LaserScan, timeout=TIMEOUT)
        self.assertIsNotNone(sub)

    def wait_subscribed(self, topic, node):
        """Wait until ``node`` has subscribed to ``topic`` (it is up and waiting)."""
        master = rosgraph.Master(rospy.get_name())
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            _, subs, _ = master.getSystemState()
            if any(t == topic and node in nodes for t, nodes in subs):
                return
            time.sleep(0.05)
        self.fail('%s never subscribed to %s' % (node, topic))

    def test_1_no_map_is_a_fatal_exit_with_the_reason(self):
        exe = roslib.packages.find_node('tiago_nav', 'obstacle_detection')[0]
        out = subprocess.run([exe, '__name:=detection_without_map', '_map_topic:=/no_map',
                              '_map_timeout:=1.0'], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, timeout=TIMEOUT + 30)
        self.assertEqual(out.returncode, 1, out.stdout)
        self.assertIn('no usable map on /no_map within ~map_timeout = 1.0 s', out.stdout)

    def test_2_failure_paths_then_recovery(self):
        # 1. the node is up, waiting for /map: no service yet
        self.wait_subscribed('/map', '/obstacle_detection')
        with self.assertRaises(rospy.ROSException):
            rospy.wait_for_service('obstacle_detection', timeout=1.0)
        # 2. a map: the service comes; no scan yet
        self.pub_map.publish(gridmap_to_msg(rasterise_world(self.world), 'map', rospy.Time.now()))
        rospy.wait_for_service('obstacle_detection', timeout=TIMEOUT)
        self.failed(self.call(DetectObstaclesRequest()), 'no /scan received within 0.5 s')
        # 3. scans, but no transform map <- base_laser_link
        self.scanning.set()
        resp = self.call_until(DetectObstaclesRequest(), lambda r: 'no /scan' not in r.message)
        self.failed(resp, 'no transform map <- base_laser_link at the scan time within 0.3 s')
        # 4. the tf chain (static): now it works
        stamp = rospy.Time.now()
        odom = (0.1, 0.05, 0.02)                 # map -> odom, not the identity
        base_in_odom = compose(inverse(odom), POSE)
        self.tf_static.sendTransform([
            transform_stamped(odom, 'map', 'odom', stamp),
            transform_stamped(base_in_odom, 'odom', 'base_footprint', stamp),
            transform_stamped((self.laser.offset, 0.0, 0.0), 'base_footprint', 'base_laser_link', stamp)])
        resp = self.call_until(DetectObstaclesRequest(), lambda r: 'no transform' not in r.message)
        self.found_ok(resp)
        # centres in base_footprint agree with the true pose
        for o in resp.obstacles:
            x, y, _ = compose(POSE, (o.center_robot.x, o.center_robot.y, 0.0))
            self.assertAlmostEqual(x, o.center.x, delta=0.01)
            self.assertAlmostEqual(y, o.center.y, delta=0.01)
        # 5. some invalid ranges (NaN, inf, negative, beyond range_max) are skipped, not fatal
        self.set_corrupt('some')
        self.found_ok(self.call(DetectObstaclesRequest()))
        # 6. too few valid beams: a failure, never "found none"
        for mode in ('nan', 'zero'):
            self.set_corrupt(mode)
            self.failed(self.call(DetectObstaclesRequest()), 'too few valid beams to judge',
                        '0 % of the 666 beams')
        self.set_corrupt(None)
        self.found_ok(self.call(DetectObstaclesRequest()))
        # 7. bad requests change nothing and say why
        for req, words in ((DetectObstaclesRequest(method='ransac'), ('bad request', 'method')),
                           (DetectObstaclesRequest(scan_minus_map_threshold=float('nan')),
                            ('bad request', 'scan_minus_map_threshold')),
                           (DetectObstaclesRequest(cluster_threshold=-1.0),
                            ('bad request', 'cluster_threshold'))):
            self.failed(self.call(req), *words)
        self.found_ok(self.call(DetectObstaclesRequest()))
        # 8. an unusable map (rotated origin): calls fail until a usable one comes
        bad = gridmap_to_msg(rasterise_world(self.world), 'map', rospy.Time.now())
        bad.info.origin.orientation.z, bad.info.origin.orientation.w = math.sin(0.2), math.cos(0.2)
        self.pub_map.publish(bad)
        resp = self.call_until(DetectObstaclesRequest(), lambda r: not r.success)
        self.failed(resp, 'unusable /map', 'rotated origin')
        self.pub_map.publish(gridmap_to_msg(rasterise_world(self.world), 'map', rospy.Time.now()))
        self.found_ok(self.call_until(DetectObstaclesRequest(), lambda r: r.success))


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_detection_errors', DetectionErrorsTest)
