#!/usr/bin/python3
"""Rostest of nodes/simulator in test/worlds/sim_box.yaml (checked against the world file).

The test drives the base as a controller does in lockstep (a LockstepParticipant answering
each 0.05 s cycle with its command): the simulator applies each command at its cycle and
holds simulated time for the next answer, so the distances driven do not depend on how fast
this process runs on a loaded machine."""
import math
import threading
import time

import numpy as np
import rospy
import rostest
from geometry_msgs.msg import Twist
from nav_msgs.msg import OccupancyGrid, Odometry
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String, UInt32

from tiago_nav.geometry import transform_points
from tiago_nav.scan import scan_to_points
from tiago_nav.ros.conversions import gridmap_from_msg, pose_from_msg, pose_from_transform
from tiago_nav.ros.lockstep import LockstepParticipant
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import Scene

from simtest import SimTestCase

TIMEOUT = 20.0
PERIOD = 0.05        # [s] the test's control cycle (3 physics steps at 60 Hz)
SETTLE = 1.0         # [s simulated] zero commands after a drive, for the base to come to rest


class SimulatorNodeTest(SimTestCase):
    node_name = 'test_sim_node'

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.part = LockstepParticipant(PERIOD, enabled=True)
        assert cls.part.joined.wait(TIMEOUT), 'the test never joined the simulator\'s lockstep'

    def drive(self, v, w, seconds):
        """``(v, w)`` for ``seconds`` of simulated time from the next cycle, then zero for
        :data:`SETTLE`: every command answered in its cycle, so applied at its stamp."""
        p = self.part
        p.claim()
        end = settled = None
        try:
            while True:
                self.assertTrue(p.tick(), 'no lockstep cycle (simulator stalled?)')
                if end is None:
                    end = p.stamp + rospy.Duration(seconds)
                    settled = end + rospy.Duration(SETTLE)
                if p.stamp >= settled:
                    p.answer(self._twist(0, 0))
                    return
                p.answer(self._twist(v, w) if p.stamp < end else self._twist(0, 0))
        finally:
            p.release()

    @staticmethod
    def _twist(v, w):
        t = Twist()
        t.linear.x, t.angular.z = v, w
        return t

    def test_1_map_is_latched_and_matches_the_world(self):
        msg = rospy.wait_for_message('/map', OccupancyGrid, timeout=TIMEOUT)
        self.assertEqual(msg.header.frame_id, 'map')
        grid = gridmap_from_msg(msg)
        xmin, ymin, xmax, ymax = self.world.bounds
        self.assertAlmostEqual(grid.resolution, self.world.resolution, places=6)
        self.assertAlmostEqual(grid.origin[0], xmin, places=6)
        self.assertEqual(grid.width, int(round((xmax - xmin) / self.world.resolution)))
        expected = rasterise_world(self.world)
        np.testing.assert_array_equal(grid.data, expected.data)
        # a cell on each wall is occupied; the movable cylinder's centre and the robot's are free
        for w in self.world.walls:
            (r, c), = grid.world_to_cell([[w.x, w.y]])
            self.assertEqual(grid.data[r, c], 100)
        for c in self.world.movable_obstacles:
            (r, cc), = grid.world_to_cell([[c.x, c.y]])
            self.assertEqual(grid.data[r, cc], 0)

    def test_2_tf_chain_and_scan(self):
        pose = self.base_pose()
        sx, sy, syaw = self.world.start_pose
        self.assertAlmostEqual(pose[0], sx, delta=0.02)
        self.assertAlmostEqual(pose[1], sy, delta=0.02)
        laser = self.tf.lookup_transform('base_footprint', 'base_laser_link', rospy.Time(),
                                         rospy.Duration(TIMEOUT))
        self.assertAlmostEqual(laser.transform.translation.x, 0.2, places=6)
        self.tf.lookup_transform('odom', 'base_footprint', rospy.Time(), rospy.Duration(TIMEOUT))
        body = self.tf.lookup_transform('base_footprint', 'base_link', rospy.Time(),
                                        rospy.Duration(TIMEOUT))
        self.assertEqual(pose_from_transform(body.transform), (0.0, 0.0, 0.0))
        laser = self.tf.lookup_transform('base_link', 'base_laser_link', rospy.Time(),
                                         rospy.Duration(TIMEOUT))
        self.assertAlmostEqual(laser.transform.translation.x, 0.2, places=6)

        scan = rospy.wait_for_message('/scan', LaserScan, timeout=TIMEOUT)
        self.assertEqual(scan.header.frame_id, 'base_laser_link')
        self.assertEqual(len(scan.ranges), 666)
        self.assertAlmostEqual(math.degrees(scan.angle_min), -110, delta=0.1)
        self.assertAlmostEqual(math.degrees(scan.angle_max), 110, delta=0.1)
        self.assertAlmostEqual(scan.range_min, 0.05)
        self.assertAlmostEqual(scan.range_max, 25.0)
        # every beam agrees with a noise-free cast from the ground-truth pose, within noise
        t = self.tf.lookup_transform('map', 'base_laser_link', scan.header.stamp, rospy.Duration(5))
        laser_pose = pose_from_transform(t.transform)
        with Scene(self.world) as scene:
            base = (laser_pose[0] - 0.2 * math.cos(laser_pose[2]),
                    laser_pose[1] - 0.2 * math.sin(laser_pose[2]), laser_pose[2])
            truth, _ = scene.cast(base)
        r = np.asarray(scan.ranges)
        both = np.isfinite(r) & np.isfinite(truth)
        self.assertGreater(both.sum(), 600)
        err = r[both] - truth[both]
        self.assertLess(np.abs(err).max(), 0.06)            # 6 sigma of 0.01 m noise
        self.assertAlmostEqual(float(np.std(err)), 0.01, delta=0.004)
        # and every scan point lies inside the box (no beam through a wall)
        pts, _ = scan_to_points(r, scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)
        world_pts = transform_points(laser_pose, pts)
        self.assertTrue(np.all(world_pts[:, 0] < 2.5 + 0.05))

    def test_3_scan_rate_is_15hz_of_sim_time(self):
        stamps = []
        sub = rospy.Subscriber('/scan', LaserScan, lambda m: stamps.append(m.header.stamp.to_sec()))
        rospy.sleep(2.0)
        sub.unregister()
        # every scan on the 1/15 s grid of simulated time, one period apart where none was
        # dropped on the way (a loaded machine may drop some)
        self.assertGreater(len(stamps), 5)
        steps = np.diff(stamps) * 15.0
        self.assertTrue(np.allclose(steps, np.round(steps), atol=0.01), steps)
        self.assertAlmostEqual(float(steps.min()), 1.0, delta=0.01)

    def test_4_commands_move_the_robot(self):
        before = self.base_pose()
        odom0 = rospy.wait_for_message('/mobile_base_controller/odom', Odometry, timeout=TIMEOUT)
        self.drive(0.0, 1.0, 1.5)          # turn left in place ~1.3 rad
        mid = self.base_pose()
        self.assertAlmostEqual(mid[0], before[0], delta=0.01)
        turned = math.atan2(math.sin(mid[2] - before[2]), math.cos(mid[2] - before[2]))
        self.assertGreater(turned, 0.9)
        self.assertLess(turned, 1.8)
        self.drive(0.0, -1.0, 1.5)         # and back
        self.drive(0.3, 0.0, 2.0)          # ~0.5 m forward along +x
        after = self.base_pose()
        self.assertGreater(after[0] - before[0], 0.35)
        self.assertLess(after[0] - before[0], 0.75)
        odom1 = rospy.wait_for_message('/mobile_base_controller/odom', Odometry, timeout=TIMEOUT)
        moved_odom = np.hypot(*(np.subtract(pose_from_msg(odom1.pose.pose)[:2],
                                            pose_from_msg(odom0.pose.pose)[:2])))
        self.assertAlmostEqual(moved_odom, math.hypot(after[0] - before[0], after[1] - before[1]),
                               delta=0.02)
        self.assertEqual(odom1.header.frame_id, 'odom')
        self.assertEqual(odom1.child_frame_id, 'base_footprint')
        collisions = rospy.wait_for_message('/sim/collisions', UInt32, timeout=TIMEOUT)
        self.assertEqual(collisions.data, 0)

    def test_5_driving_into_a_wall_counts_a_collision(self):
        self.drive(0.5, 0.0, 5.0)          # the east wall is ~1 m ahead
        pose = self.base_pose()
        self.assertLess(pose[0], 2.5 - 0.27 + 0.01)         # stopped at the wall, not through it
        collisions = rospy.wait_for_message('/sim/collisions', UInt32, timeout=TIMEOUT)
        self.assertEqual(collisions.data, 1)

    def test_6_ground_truth_is_the_map_pose(self):
        truth = rospy.wait_for_message('/sim/ground_truth', Odometry, timeout=TIMEOUT)
        self.assertEqual(truth.header.frame_id, 'map')
        self.assertEqual(truth.child_frame_id, 'base_footprint')
        t = self.tf.lookup_transform('map', 'base_footprint', truth.header.stamp,
                                     rospy.Duration(5))
        np.testing.assert_allclose(pose_from_msg(truth.pose.pose), pose_from_transform(t.transform),
                                   atol=1e-6)

    def test_7_injected_laser_faults(self):
        scans, lock = [], threading.Lock()

        def on_scan(m):
            with lock:
                scans.append((m.header.stamp.to_sec(), np.asarray(m.ranges)))

        def wait_for(what, cond):
            end = time.monotonic() + TIMEOUT
            while time.monotonic() < end and not rospy.is_shutdown():
                with lock:
                    if cond(scans):
                        return
                time.sleep(0.01)
            self.fail('timed out waiting for ' + what)

        sub = rospy.Subscriber('/scan', LaserScan, on_scan)
        faults = rospy.Publisher('/sim/laser_fault', String, queue_size=5)
        wait_for('the fault subscriber', lambda _: faults.get_num_connections() > 0)
        wait_for('a healthy scan', lambda ss: any(not np.isnan(r).any() for _, r in ss))
        try:
            faults.publish(String('nan 1'))
            wait_for('a NaN scan and then a healthy one again',
                     lambda ss: any(np.isnan(r).all() for _, r in ss)
                     and not np.isnan(ss[-1][1]).any())
            with lock:
                nan = [t for t, r in scans if np.isnan(r).all()]
                first_nan = nan[0]
                healthy_after = [t for t, r in scans if t > first_nan and not np.isnan(r).any()]
                healthy_before = [t for t, r in scans if t < first_nan and not np.isnan(r).any()]
            # 1 s of NaN scans: none healthy within it, none NaN after it. A publisher under load
            # may drop scans, the first NaN ones too, so the test counts none and measures the
            # fault by the healthy scans around it: the last before it and the first after it
            # are at least 1 s apart (drops only widen that), the NaN ones at most 1 s
            self.assertLessEqual(nan[-1] - first_nan, 1.0 + 1e-6)
            self.assertGreaterEqual(healthy_after[0] - healthy_before[-1], 1.0 - 1e-6)

            faults.publish(String('dead'))
            # no scan for 1 s of simulated time (one already on its way may still come)
            wait_for('1 s of sim time', lambda ss: rospy.get_time() > ss[-1][0] + 1.0)
            faults.publish(String('none'))
            wait_for('scans again', lambda ss: ss[-1][0] > rospy.get_time() - 0.5)
            with lock:
                stamps = np.array([t for t, _ in scans if t > first_nan])
            self.assertGreater(np.diff(stamps).max(), 1.0)          # the laser was silent
        finally:
            faults.publish(String('none'))
            sub.unregister()

    def test_8_cmd_vel_of_a_node_outside_lockstep_moves_the_base(self):
        """Last (the test leaves lockstep): a node that does not take part, e.g. a teleop,
        drives by cmd_vel; turning on the spot (the base is against the east wall)."""
        self.part.close()
        pub = rospy.Publisher('/mobile_base_controller/cmd_vel', Twist, queue_size=1)
        yaw0 = self.base_pose()[2]
        end = time.monotonic() + TIMEOUT           # a hang guard: it turns within sim seconds
        turned = 0.0
        while turned < 0.3:
            self.assertLess(time.monotonic(), end, 'cmd_vel did not turn the base (%.2f rad)'
                            % turned)
            pub.publish(self._twist(0.0, 0.8))
            time.sleep(0.05)
            yaw = self.base_pose()[2]
            turned = abs(math.atan2(math.sin(yaw - yaw0), math.cos(yaw - yaw0)))
        pub.publish(self._twist(0.0, 0.0))


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_sim_node', SimulatorNodeTest)
