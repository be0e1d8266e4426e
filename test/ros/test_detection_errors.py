#!/usr/bin/python3
"""Rostest of the obstacle_detection node's failure paths, the test standing in for the robot:
no /map yet, no /scan, no transform, then scans with invalid ranges. Each failure must give an
empty list and a message naming the cause; the node must keep serving afterwards. The scans are
the pybullet cast of test/worlds/detection_row.yaml with seeded noise; ground truth is the world
file and Scene.visible_obstacles."""
import math
import threading
import unittest

import numpy as np
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
            cls.visible = scene.visible_obstacles(POSE)
        cls.rng = np.random.default_rng(5)
        cls.corrupt = False
        cls.pub_map = rospy.Publisher('/map', OccupancyGrid, queue_size=1, latch=True)
        cls.pub_scan = rospy.Publisher('/scan', LaserScan, queue_size=5)
        cls.tf_static = tf2_ros.StaticTransformBroadcaster()
        rospy.wait_for_service('obstacle_detection', timeout=TIMEOUT)
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
                if cls.corrupt:
                    r[::7] = np.nan
                    r[3::11] = np.inf
                    r[5::13] = -1.0
                    r[6::17] = 1e6
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
        self.assertEqual(len(resp.obstacles), len(self.visible), resp.message)
        for i in self.visible:
            c = self.world.movable_obstacles[i]
            e = min(math.hypot(o.center.x - c.x, o.center.y - c.y) for o in resp.obstacles)
            self.assertLess(e, tol, resp.message)

    def test_failure_paths_then_recovery(self):
        # 1. no map yet
        resp = self.call(DetectObstaclesRequest())
        self.assertEqual(len(resp.obstacles), 0)
        self.assertIn('/map', resp.message)
        # 2. a map, but no scan
        self.pub_map.publish(gridmap_to_msg(rasterise_world(self.world), 'map', rospy.Time.now()))
        deadline = rospy.Time.now() + rospy.Duration(TIMEOUT)
        while 'no /map' in resp.message and rospy.Time.now() < deadline:
            rospy.sleep(0.1)
            resp = self.call(DetectObstaclesRequest())
        self.assertEqual(len(resp.obstacles), 0)
        self.assertIn('no /scan', resp.message)
        # 3. scans, but no transform map <- base_laser_link
        self.scanning.set()
        resp = self.call(DetectObstaclesRequest())
        self.assertEqual(len(resp.obstacles), 0)
        self.assertIn('no transform', resp.message)
        # 4. the tf chain (static): now it works
        stamp = rospy.Time.now()
        odom = (0.1, 0.05, 0.02)                 # map -> odom, not the identity
        base_in_odom = compose(inverse(odom), POSE)
        self.tf_static.sendTransform([
            transform_stamped(odom, 'map', 'odom', stamp),
            transform_stamped(base_in_odom, 'odom', 'base_footprint', stamp),
            transform_stamped((self.laser.offset, 0.0, 0.0), 'base_footprint', 'base_laser_link', stamp)])
        deadline = rospy.Time.now() + rospy.Duration(TIMEOUT)
        while 'no transform' in resp.message and rospy.Time.now() < deadline:
            rospy.sleep(0.1)
            resp = self.call(DetectObstaclesRequest())
        self.found_ok(resp)
        # centres in base_footprint agree with the true pose
        for o in resp.obstacles:
            x, y, _ = compose(POSE, (o.center_robot.x, o.center_robot.y, 0.0))
            self.assertAlmostEqual(x, o.center.x, delta=0.01)
            self.assertAlmostEqual(y, o.center.y, delta=0.01)
        # 5. invalid ranges (NaN, inf, negative, beyond range_max) are skipped, not fatal
        self.__class__.corrupt = True
        rospy.sleep(0.2)
        self.found_ok(self.call(DetectObstaclesRequest()))
        # 6. bad requests change nothing and say why
        for req, word in ((DetectObstaclesRequest(method='ransac'), 'unknown method'),
                          (DetectObstaclesRequest(scan_minus_map_threshold=float('nan')),
                           'scan_minus_map_threshold')):
            resp = self.call(req)
            self.assertEqual(len(resp.obstacles), 0)
            self.assertIn(word, resp.message)
        self.__class__.corrupt = False
        rospy.sleep(0.2)
        self.found_ok(self.call(DetectObstaclesRequest()))


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_detection_errors', DetectionErrorsTest)
