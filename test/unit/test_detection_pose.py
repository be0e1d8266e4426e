"""The detection's pose correction: the scan's static part registered to the map removes a pose
error it can see; too little map to register leaves the given pose, and says so."""
import math

import numpy as np
import pytest

from test_detection import L, world
from tiago_nav.detection import DetectionParams, ObstacleDetector
from tiago_nav.detection.service import DetectionService
from tiago_nav.scan import Scan
from tiago_nav.geometry import compose, inverse
from tiago_nav.nodes.obstacle_detection import Params
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import Scene, noisy

# needs ROS: the node's Params: tiago_nav.nodes.obstacle_detection imports rospy
pytestmark = pytest.mark.ros

# a closed room whose wall faces sit where the raster puts them on average (a quarter cell
# inside the occupied band), so the registration's own bias is small (about 7 mm here)
WALLS = [{'x': 3.5, 'y': 2.9875, 'length': 9.0, 'width': 0.15},
         {'x': 3.5, 'y': -2.9875, 'length': 9.0, 'width': 0.15},
         {'x': 7.4875, 'y': 0.0, 'length': 6.0, 'width': 0.15, 'yaw_deg': 90},
         {'x': -0.4875, 'y': 0.0, 'length': 6.0, 'width': 0.15, 'yaw_deg': 90}]
OBSTACLES = [(3.0, 0.8, 0.2), (4.5, -1.0, 0.15)]
POSE = (1.0, 0.3, 0.2)
ERROR = (0.03, -0.02, math.radians(0.8))      # base_footprint's error, in its own frame


@pytest.fixture(scope='module')
def scene():
    w = world(OBSTACLES, walls=WALLS)
    with Scene(w) as s:
        clean, _ = s.cast(POSE)
        laser = s.laser_pose(POSE)
    r = noisy(clean, 0.01, np.random.default_rng(3), L.range_min, L.range_max)
    return w, rasterise_world(w), r, laser


def locate(grid, r, laser_pose, method='circle_fit', **kw):
    det = ObstacleDetector(grid, DetectionParams(**kw))
    return det.locate(r, L.angle_min, L.angle_increment, L.range_min, L.range_max, laser_pose,
                      method)


def centre_errors(w, found):
    return [min(math.hypot(d.center[0] - c.x, d.center[1] - c.y) for d in found)
            for c in w.movable_obstacles]


def test_a_known_pose_error_is_removed(scene):
    w, grid, r, laser = scene
    lib = compose(inverse(POSE), laser)
    wrong = compose(compose(POSE, ERROR), lib)
    from_truth = locate(grid, r, laser).correction
    fixed = locate(grid, r, wrong)
    c = fixed.correction
    assert c.applied and c.reason == '' and c.static_points > 300
    # the same pose as from the true start, to within a few mm: the error is gone ...
    d = compose(inverse(from_truth.laser_pose), c.laser_pose)
    assert math.hypot(d[0], d[1]) < 0.003 and abs(d[2]) < math.radians(0.05)
    # ... and that pose is the true one to within the map raster's bias (about 7 mm here)
    t = compose(inverse(laser), c.laser_pose)
    assert math.hypot(t[0], t[1]) < 0.01 and abs(t[2]) < math.radians(0.1)
    # the centres follow: within 1.5 cm with the correction, not without it
    assert max(centre_errors(w, fixed.detections)) < 0.015
    uncorrected = locate(grid, r, wrong, correct_pose=False)
    assert not uncorrected.correction.applied
    assert uncorrected.correction.reason == 'correct_pose is off'
    assert max(centre_errors(w, uncorrected.detections)) > 0.03


def test_too_little_map_falls_back_and_says_so(scene):
    w, grid, r, laser = scene
    res = locate(grid, r, laser, min_static_points=5000)
    c = res.correction
    assert not c.applied and c.laser_pose == tuple(laser) and c.delta == (0.0, 0.0, 0.0)
    assert c.reason.startswith('only %d scan points on the map (min_static_points 5000)'
                               % c.static_points)
    assert c.describe().startswith('pose not corrected: only')
    assert max(centre_errors(w, res.detections)) < 0.03      # placed with the given pose


def test_an_open_floor_has_no_static_part():
    w = world(OBSTACLES, walls=[])
    with Scene(w) as s:
        clean, _ = s.cast(POSE)
        laser = s.laser_pose(POSE)
    r = noisy(clean, 0.01, np.random.default_rng(3), L.range_min, L.range_max)
    res = locate(rasterise_world(w), r, laser)
    assert not res.correction.applied and res.correction.static_points == 0
    assert len(res.detections) == 2


def test_discontinuity_reads_no_map_and_is_not_corrected(scene):
    w, grid, r, laser = scene
    c = locate(grid, r, laser, method='discontinuity').correction
    assert not c.applied and 'reads no map' in c.reason


class Sensors:
    def __init__(self, r, laser_in_map, laser_in_robot, covariance=None):
        self.r, self.poses = r, {'map': laser_in_map, 'base_footprint': laser_in_robot}
        self.covariance = covariance

    def pose_covariance(self, stamp):
        return self.covariance

    def fresh_scan(self, timeout):
        return Scan(tuple(self.r), L.angle_min, L.angle_increment, L.range_min, L.range_max,
                    1.0, 'base_laser_link')

    def scans_before(self, scan, count):
        return []

    def transform(self, target, source, stamp, timeout):
        return self.poses[target]


@pytest.mark.parametrize('min_static', [80, 5000])
def test_the_service_reports_the_correction(scene, min_static):
    w, grid, r, laser = scene
    lib = compose(inverse(POSE), laser)
    svc = DetectionService(Params(detection=DetectionParams(min_static_points=min_static)))
    svc.set_map(grid)
    a = svc.handle('', 0.0, 0.0, Sensors(r, compose(compose(POSE, ERROR), lib), lib))
    assert a.success and a.message.startswith('2 obstacle(s) found with circle_fit on the scan at 1.000 s; ')
    if min_static == 80:
        # the robot's pose in map: corrected minus given, close to minus the error put in
        given = compose(POSE, ERROR)
        assert a.pose_corrected and 'pose corrected by' in a.message
        assert abs(given[0] + a.pose_correction[0] - POSE[0]) < 0.01
        assert abs(given[1] + a.pose_correction[1] - POSE[1]) < 0.01
        assert abs(a.pose_correction[2] + ERROR[2]) < math.radians(0.1)
        # centres in the robot frame come from the scan alone: unchanged by the correction
        for o in a.obstacles:
            c = compose(inverse(POSE), (o.center[0], o.center[1], 0.0))
            assert math.hypot(c[0] - o.center_robot[0], c[1] - o.center_robot[1]) < 0.02
    else:
        assert not a.pose_corrected and a.pose_correction == (0.0, 0.0, 0.0)
        assert 'pose not corrected: only' in a.message


def test_the_laser_pose_error_is_in_the_map_covariance_only(scene):
    """Placed with the given pose (no correction), the localisation's covariance reaches each
    centre in map: its position as it is, its heading across the beam by the range; the robot
    frame's covariance stays the fit's. With the correction, its own covariance and the raster
    replace it."""
    w, grid, r, laser = scene
    lib = compose(inverse(POSE), laser)
    sigma_xy, sigma_yaw = 0.02, math.radians(0.5)
    cov = np.diag([sigma_xy ** 2, sigma_xy ** 2, sigma_yaw ** 2])
    given = compose(POSE, ERROR)
    svc = DetectionService(Params(detection=DetectionParams(min_static_points=5000)))
    svc.set_map(grid)
    exact = svc.handle('', 0.0, 0.0, Sensors(r, compose(given, lib), lib))
    unsure = svc.handle('', 0.0, 0.0, Sensors(r, compose(given, lib), lib, cov))
    assert not unsure.pose_corrected and len(exact.obstacles) == len(unsure.obstacles) == 2
    for a, b in zip(exact.obstacles, unsure.obstacles):
        assert a.center == b.center and a.center_robot_covariance == b.center_robot_covariance
        rng = math.hypot(b.center[0] - given[0], b.center[1] - given[1])
        fit, position, heading, raster = b.center_variance_terms
        # along the least certain direction: at most the position's and the heading's whole
        # variance, at least the larger of them
        assert max(sigma_xy ** 2, (rng * sigma_yaw) ** 2) * 0.9 <= position + heading
        assert position + heading <= (sigma_xy + rng * sigma_yaw) ** 2 * 1.01
        assert raster == pytest.approx(grid.resolution ** 2 / 24, rel=1e-6)
        assert b.center_std ** 2 == pytest.approx(sum(b.center_variance_terms), rel=1e-6)
        # without a covariance the pose is exact: the fit alone, the robot frame's rotated
        assert a.center_variance_terms[1:] == (0.0, 0.0, 0.0)
        assert a.center_std ** 2 == pytest.approx(a.center_variance_terms[0], rel=1e-6)
    svc = DetectionService(Params(detection=DetectionParams()))
    svc.set_map(grid)
    fixed = svc.handle('', 0.0, 0.0, Sensors(r, compose(given, lib), lib, cov))
    assert fixed.pose_corrected
    for o in fixed.obstacles:
        fit, position, heading, raster = o.center_variance_terms
        # the registration pins the pose far better than the given 2 cm / 0.5 deg; the raster
        # leaves about a cell's share along each axis (a cell widened by twice the mean's
        # noise of 10 points on a wall at 1 cm: refine_on_raster), and its walls' tilts a
        # share of the heading
        assert 0 < position + heading < (0.25 * sigma_xy) ** 2
        rng = math.hypot(o.center_robot[0], o.center_robot[1])
        most = (grid.resolution + 4 * 0.01 / math.sqrt(10)) ** 2 / 24 * 2 + (
            rng * math.radians(1.0)) ** 2
        assert (grid.resolution / 8) ** 2 < raster <= most
