"""What the localisation takes in from a real robot: scans of any beam count and angular
range, a map whose origin is rotated, scans that come before the map or faster than a search
(the node's intake: tiago_nav.nodes.localisation)."""
import math
import os
import threading
import time

import numpy as np
import pytest
from nav_msgs.msg import OccupancyGrid
from std_msgs.msg import Header

from conftest import ROOT
from tiago_nav.geometry import compose, inverse, wrap_angle, yaw_to_quaternion
from tiago_nav.localisation.localiser import Localiser
from tiago_nav.nodes.localisation import ScanQueue, from_grid, to_grid, turn_covariance
from tiago_nav.ros.conversions import gridmap_from_msg, gridmap_in_grid_frame
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import LaserConfig
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import load_world
from tiago_nav_tools.testing.localisation import raster_config

# needs ROS's messages and rospy (the node's module)
pytestmark = pytest.mark.ros

WORLD = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')
TRUTH = (0.2, 0.05, math.radians(20.0))


@pytest.fixture(scope='module')
def world():
    return load_world(WORLD)


def scan_of(world, pose, laser):
    sim = Simulator(world, SimConfig(seed=1, laser=laser), start_pose=pose)
    try:
        return sim.scan()
    finally:
        sim.close()


def track_one(grid, laser, ranges, start):
    """The pose the localiser registers from ``start`` (a search: a fresh start) with one scan."""
    loc = Localiser(grid, start, odom=(0.0, 0.0, 0.0), config=raster_config())
    pts = loc.scan_points(ranges, laser.angle_min, laser.angle_increment, laser.range_min,
                          laser.range_max, (laser.offset, 0.0, 0.0))
    up = loc.update((0.0, 0.0, 0.0), pts, (laser.offset, 0.0))
    assert up.corrected, up.reason
    return up


@pytest.mark.parametrize('beams,fov_deg', [(180, 180.0), (360, 180.0), (512, 180.0),
                                           (666, 220.0), (768, 270.0), (1081, 270.0),
                                           (360, 360.0 - 1.0)])
def test_any_beam_count_and_angular_range_registers(world, beams, fov_deg):
    """The beam counts and fans of the real lasers at hand (SICK LMS 180 / 360 beams over 180°,
    512 over 180°, TIAGo's 666 over 220°, 768 over 270°, a 1081-beam 270° one and an almost
    full turn): from 0.2 m / 5° off, the registration lands within 3 cm / 1° of the truth,
    where the start was 20 cm off."""
    half = math.radians(fov_deg) / 2.0
    laser = LaserConfig(num_beams=beams, angle_min=-half, angle_max=half)
    ranges = scan_of(world, TRUTH, laser)
    assert len(ranges) == beams
    start = (TRUTH[0] + 0.15, TRUTH[1] - 0.13, TRUTH[2] + math.radians(5.0))
    up = track_one(rasterise_world(world), laser, ranges, start)
    assert math.hypot(up.pose[0] - TRUTH[0], up.pose[1] - TRUTH[1]) < 0.03, up.pose
    assert abs(wrap_angle(up.pose[2] - TRUTH[2])) < math.radians(1.0), up.pose


def grid_msg(grid, origin):
    """An OccupancyGrid of ``grid``'s cells with MapMetaData's origin at ``origin`` (x, y, yaw)."""
    m = OccupancyGrid(header=Header(frame_id='map'))
    m.info.resolution = grid.resolution
    m.info.height, m.info.width = grid.data.shape
    m.info.origin.position.x, m.info.origin.position.y = origin[:2]
    q = yaw_to_quaternion(origin[2])
    (m.info.origin.orientation.x, m.info.origin.orientation.y, m.info.origin.orientation.z,
     m.info.origin.orientation.w) = q
    m.data = grid.data.ravel().tolist()
    return m


def test_a_rotated_map_origin_gives_the_same_pose_as_the_unrotated_map(world):
    """The same cells published with their origin turned by 35° about a point elsewhere: the
    map frame is then that much turned, the robot's true pose in it too; the node's estimate
    (taken in and given out through the grid's frame) is that true pose, and the unrotated
    map's estimate carried into the turned map frame, to the micrometre."""
    grid = rasterise_world(world)
    laser = LaserConfig()
    ranges = scan_of(world, TRUTH, laser)
    plain_grid = gridmap_from_msg(grid_msg(grid, (grid.origin[0], grid.origin[1], 0.0)))
    assert plain_grid.origin == grid.origin
    start = (TRUTH[0] + 0.1, TRUTH[1] + 0.1, TRUTH[2] - math.radians(4.0))
    plain = track_one(plain_grid, laser, ranges, start).pose

    origin = (-7.0, 12.0, math.radians(35.0))
    msg = grid_msg(grid, origin)
    with pytest.raises(ValueError, match='rotated origin'):
        gridmap_from_msg(msg)                   # the other nodes' conversion refuses it
    turned, frame = gridmap_in_grid_frame(msg)
    assert frame == pytest.approx(origin) and turned.origin == (0.0, 0.0)
    # the world's cells at their place in the turned map frame: world point p is at T ∘ p
    shift = (-grid.origin[0], -grid.origin[1], 0.0)
    world_to_map = compose(frame, shift)
    truth_map = compose(world_to_map, TRUTH)
    start_map = compose(world_to_map, start)
    up = track_one(turned, laser, ranges, to_grid(frame, start_map))
    got = from_grid(frame, up.pose)
    assert math.hypot(got[0] - truth_map[0], got[1] - truth_map[1]) < 0.03
    assert abs(wrap_angle(got[2] - truth_map[2])) < math.radians(1.0)
    want = compose(world_to_map, plain)
    assert got[:2] == pytest.approx(want[:2], abs=1e-6)
    assert wrap_angle(got[2] - want[2]) == pytest.approx(0.0, abs=1e-9)
    # and the covariance turns with it: the same spread, along the turned axes
    cov = np.diag([0.04, 0.0001, 0.01])
    turned_cov = turn_covariance(cov, frame[2])
    u = np.array([math.cos(frame[2]), math.sin(frame[2])])
    assert u @ turned_cov[:2, :2] @ u == pytest.approx(0.04)
    assert np.linalg.eigvalsh(turned_cov) == pytest.approx(np.linalg.eigvalsh(cov))
    # an unrotated map is its own frame: nothing turned, the pose as given
    assert to_grid((0.0, 0.0, 0.0), start) == start
    assert from_grid(frame, to_grid(frame, start)) == pytest.approx(start)


class Msg:
    """A scan message's stand-in (what the queue and its skip callback read)."""
    def __init__(self, k):
        self.k = k


def test_the_scan_queue_keeps_order_and_loses_none_while_a_scan_takes_long():
    done, skipped = [], []
    slow = threading.Event()

    def process(msg):
        if msg.k == 0:
            slow.wait(5.0)          # a search after a (re)set: longer than many scan periods
        done.append(msg.k)

    q = ScanQueue(process, 30, skipped.append)
    try:
        for k in range(20):
            q.put(Msg(k))
        slow.set()
        end = time.monotonic() + 10.0
        while len(done) < 20 and time.monotonic() < end:
            time.sleep(0.01)
        assert done == list(range(20)) and not skipped
    finally:
        q.close()


def test_a_full_scan_queue_skips_the_oldest_and_says_so():
    done, skipped = [], []
    hold = threading.Event()
    q = ScanQueue(lambda m: (hold.wait(5.0), done.append(m.k)), 3, skipped.append)
    try:
        q.put(Msg(0))
        end = time.monotonic() + 5.0
        while q.queue and time.monotonic() < end:     # scan 0 in hand, the queue empty
            time.sleep(0.01)
        for k in range(1, 7):
            q.put(Msg(k))
        assert [m.k for m in skipped] == [1, 2, 3]      # the oldest waiting, each counted
        hold.set()
        while len(done) < 4 and time.monotonic() < end:
            time.sleep(0.01)
        assert done == [0, 4, 5, 6]
    finally:
        q.close()
    assert not q.thread.is_alive() or q.thread.join(2.0) is None and not q.thread.is_alive()
