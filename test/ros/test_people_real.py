#!/usr/bin/python3
"""Rostest of the obstacle_detection node (``shapes`` on) on real laser data
(test/people_real.test): people walking past a laser standing still, 25 s of leg_tracker's demo
recording (test/data/legs_demo_slice.bag, see test/data/README.md; 250 scans of /scan at
10 Hz, 512 beams, frame ``laser``).

No map exists for that room: as bench/bench_legs_real.py does, the static background is built
from the slice's own scans (tiago_nav.detection.background) and given latched on /map, the
laser standing at the map's origin (static tf map -> odom -> base_footprint -> laser, all
identity). The test publishes /clock and /scan itself, scan after scan in recording order, and
after every ``~every``-th scan calls the service with ``scan_stamp`` set to that scan's stamp:
no wall-clock playback, so a loaded machine delays the test but does not change what the node
sees. Each answer's message names the scan it used and the oldest of the scans at rest it
combined; the verdict is judged on exactly those scans.

Truth (mirrors bench_legs_real.demo(), the physical criterion of "a person walking past"): a
reported object most of whose points (the named scan's points within its radius + 5 cm of its
centre) lie at least 0.3 m in front of their beam's background (or on a beam with none) is
foreground; one whose place was seen free (at least half its beams past it + 0.3 m or with no
return, in two scans in a row) both within the 10 scans (1 s) before the oldest scan the call
combined and within the 10 scans after the named scan is a person walking past (nothing else
moves in that room). Asserted: every call succeeds on 5 scans at rest; at least
``MIN_PASSING`` people walking past are judged; every one is reported ``moving``, none
``static``. Measured on this slice: 50 calls, 128 people walking past, 128 moving, 0 static.
The bench calls on every 10th scan; this test on every 5th (``~every``), which calls on the
scan 41.8 s into the recording (the slice's 169th) where a planted leg read as ``unknown``
was once reported static beside its walker's moving ``legs``.
"""
import os
import re
import threading
import time
import unittest

import numpy as np
import rosbag
import rospy
import rostest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from nav_msgs.msg import OccupancyGrid
from tf2_msgs.msg import TFMessage

from tiago_nav.detection.background import background_map, background_ranges
from tiago_nav.detection.motion import beams_of
from tiago_nav.ros.conversions import gridmap_to_msg, transform_stamped
from tiago_nav.scan import HIT, classify, scan_to_points
from tiago_nav.srv import DetectObstacles

HERE = os.path.dirname(os.path.abspath(__file__))
SLICE = os.path.join(os.path.dirname(HERE), 'data', 'legs_demo_slice.bag')
TIMEOUT = 60.0          # [s wall] for each wait (the node's start, a connection, one call)
FOREGROUND = 0.3        # [m] as bench_legs_real.FOREGROUND
WINDOW = 10             # [scans] as bench_legs_real.WINDOW: 1 s at 10 Hz
MIN_PASSING = 100       # people walking past judged at least (128 on this slice)
# the answer's message: '... on the scan at T s (the median of N scans at rest, from T0 s); ...'
USED = re.compile(r'on the scan at ([0-9.]+) s(?: \(the median of (\d+) scans at rest, '
                  r'from ([0-9.]+) s\))?')


def call_within(proxy, timeout, **request):
    """``proxy(**request)`` from a worker thread, failing the test when it does not answer within
    ``timeout`` wall seconds (a rospy service call has no timeout of its own)."""
    out = {}

    def run():
        try:
            out['answer'] = proxy(**request)
        except Exception as e:      # noqa: BLE001 (reported below)
            out['error'] = e
    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(timeout)
    if t.is_alive():
        raise AssertionError('obstacle_detection did not answer within %g s' % timeout)
    if 'error' in out:
        raise AssertionError('obstacle_detection call raised %r' % out['error'])
    return out['answer']


def wait_until(condition, timeout, what):
    deadline = time.monotonic() + timeout
    while not condition():
        if rospy.is_shutdown() or time.monotonic() > deadline:
            raise AssertionError('%s within %g s' % (what, timeout))
        time.sleep(0.01)


class PeopleRealTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_people_real')
        with rosbag.Bag(rospy.get_param('~slice', SLICE)) as bag:
            cls.msgs = [m for _, m, _ in bag.read_messages(topics=['/scan'])]
        cls.every = int(rospy.get_param('~every', 5))
        cls.rest = int(rospy.get_param('/obstacle_detection/rest_scans'))
        m = cls.msgs[0]
        cls.stamps = np.array([s.header.stamp.to_sec() for s in cls.msgs])
        raw = [np.asarray(s.ranges, dtype=float) for s in cls.msgs]
        # the static background and its map, as bench_legs_real.background_grid
        cls.background = background_ranges(raw, m.range_min, m.range_max)
        cls.grid = background_map(cls.background, m.angle_min, m.angle_increment,
                                  reach=m.range_max + 0.5)
        # per scan: hits' ranges (no hit: inf) and the hits as points (laser = map frame)
        cls.ranges = [np.where(classify(r, m.range_min, m.range_max) == HIT, r, np.inf)
                      for r in raw]
        cls.points = [scan_to_points(r, m.angle_min, m.angle_increment, m.range_min,
                                     m.range_max)[0] for r in raw]

    def publish_world(self):
        """Latched tf (the laser standing at the map's origin) and the background map; /clock
        and /scan publishers connected to the node."""
        stamp = self.msgs[0].header.stamp
        self.tf_pub = rospy.Publisher('/tf_static', TFMessage, queue_size=1, latch=True)
        self.tf_pub.publish(TFMessage([
            transform_stamped((0.0, 0.0, 0.0), 'map', 'odom', stamp),
            transform_stamped((0.0, 0.0, 0.0), 'odom', 'base_footprint', stamp),
            transform_stamped((0.0, 0.0, 0.0), 'base_footprint', self.msgs[0].header.frame_id,
                              stamp)]))
        self.map_pub = rospy.Publisher('/map', OccupancyGrid, queue_size=1, latch=True)
        self.map_pub.publish(gridmap_to_msg(self.grid, 'map', stamp))
        self.clock = rospy.Publisher('/clock', Clock, queue_size=len(self.msgs) + 1)
        self.scan_pub = rospy.Publisher('/scan', LaserScan, queue_size=len(self.msgs) + 1)
        rospy.wait_for_service('obstacle_detection', timeout=TIMEOUT)   # the map is in
        wait_until(lambda: self.scan_pub.get_num_connections() > 0, TIMEOUT,
                   'obstacle_detection did not connect to /scan')
        return rospy.ServiceProxy('obstacle_detection', DetectObstacles)

    def index(self, seconds):
        """The slice's scan stamped ``seconds`` (as the message prints it, to the ms)."""
        k = int(np.argmin(np.abs(self.stamps - seconds)))
        self.assertLess(abs(self.stamps[k] - seconds), 6e-4, 'no scan at %.3f s' % seconds)
        return k

    def free(self, js, b, rng):
        """Bench_legs_real.demo().free: the place (beams ``b`` at ranges ``rng``) seen free,
        at least half its beams past it + FOREGROUND or with no return, in two of the scans
        ``js`` in a row (outside the slice: not seen)."""
        seen = [0 <= j < len(self.msgs)
                and np.mean(~(self.ranges[j][b] <= rng + FOREGROUND)) >= 0.5 for j in js]
        return any(a and c for a, c in zip(seen[:-1], seen[1:]))

    def judge(self, answer, i, counts):
        """Count the answer's people walking past (the module's doc) and their motion."""
        m = USED.search(answer.message)
        self.assertIsNotNone(m, 'the answer does not name its scans: %r' % answer.message)
        self.assertEqual(self.index(float(m.group(1))), i, answer.message)
        self.assertIsNotNone(m.group(2), 'scan %d: not combined with the scans at rest before '
                             'it (motion not judged): %r' % (i, answer.message))
        oldest = self.index(float(m.group(3)))
        # the held scans just before it: every one was published before the call
        self.assertEqual((int(m.group(2)), i - oldest + 1), (self.rest, self.rest),
                         answer.message)
        first, pts_i = self.msgs[0], self.points[i]
        for o in answer.obstacles:
            counts['objects'] += 1
            near = np.hypot(pts_i[:, 0] - o.center.x, pts_i[:, 1] - o.center.y) \
                <= o.radius + 0.05
            pts = pts_i[near]
            if not len(pts):
                continue
            b = beams_of(pts, (0.0, 0.0, 0.0), first.angle_min, first.angle_increment,
                         len(self.background))
            rng = np.hypot(*pts.T)
            front = ~(rng > self.background[b] - FOREGROUND)   # NaN background: nothing stays
            if np.mean(front) < 0.5:
                continue
            counts['foreground'] += 1
            if self.free(range(oldest - WINDOW, oldest), b, rng) \
                    and self.free(range(i + 1, i + 1 + WINDOW), b, rng):
                counts['passing'] += 1
                key = o.motion if o.motion in ('moving', 'static') else 'unknown'
                counts['passing_' + key] += 1
                if o.motion != 'moving':
                    counts['wrong'].append('scan %d (%.3f s): %s %s at (%.2f, %.2f), %d points, '
                                           '%s' % (i, self.stamps[i], o.motion, o.shape,
                                                   o.center.x, o.center.y, o.num_points, o.note))

    def test_people_walking_past_are_moving(self):
        detect = self.publish_world()
        counts = {'calls': 0, 'objects': 0, 'foreground': 0, 'passing': 0, 'passing_moving': 0,
                  'passing_static': 0, 'passing_unknown': 0, 'wrong': []}
        first_call = True
        for i, msg in enumerate(self.msgs):
            self.clock.publish(Clock(clock=msg.header.stamp))
            self.scan_pub.publish(msg)
            if i < self.rest - 1 or (i - (self.rest - 1)) % self.every:
                continue
            answer = call_within(detect, TIMEOUT, scan_stamp=msg.header.stamp)
            # the first call: the node's tf listener may not hold the latched tf yet (it waits
            # ~tf_timeout for it); ask again until it does, within TIMEOUT
            deadline = time.monotonic() + TIMEOUT
            while first_call and not answer.success and answer.message.startswith(
                    'no transform') and time.monotonic() < deadline:
                rospy.loginfo('people_real: the node has no tf yet (%s): asking again',
                              answer.message)
                answer = call_within(detect, TIMEOUT, scan_stamp=msg.header.stamp)
            first_call = False
            self.assertTrue(answer.success, 'scan %d: %s' % (i, answer.message))
            counts['calls'] += 1
            self.judge(answer, i, counts)
        wrong = counts.pop('wrong')
        rospy.loginfo('people_real: %s', counts)
        for w in wrong:
            rospy.logwarn('people_real: a person walking past reported %s', w)
        self.assertEqual(counts['calls'], len(range(self.rest - 1, len(self.msgs), self.every)))
        self.assertGreaterEqual(counts['passing'], MIN_PASSING, counts)
        self.assertEqual(counts['passing_static'], 0, '\n'.join(wrong))
        self.assertEqual(counts['passing_moving'], counts['passing'], '\n'.join(wrong))


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'people_real', PeopleRealTest)
