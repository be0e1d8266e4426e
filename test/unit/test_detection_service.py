"""The obstacle_detection service's decisions without ROS (tiago_nav.detection.service): bad
requests, missing map/scan/tf and pipeline errors give success=false and a message naming the
cause; a good request on a synthetic scan (pybullet cast of test/worlds/detection_row.yaml with
seeded noise) returns every obstacle in view, in the map and robot frames, nearest first."""
import math
import os
from dataclasses import asdict, replace

import numpy as np
import pytest

from conftest import ROOT
from tiago_nav.clock import source_verdict
from tiago_nav.detection.service import STRIDE_SCANS, DetectionService, Failure, check_request
from tiago_nav.scan import Scan
from tiago_nav.geometry import compose, inverse
from tiago_nav.gridmap import GridMap
from tiago_nav.nodes.obstacle_detection import Params
from tiago_nav.params import ParamError
from tiago_nav.robot import LASER_OFFSET
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import LaserConfig, Scene, noisy
from tiago_nav.sim.world import load_world
from tiago_nav_tools.evaluate.inview import view_from

# needs ROS: the node's Params: tiago_nav.nodes.obstacle_detection imports rospy
pytestmark = pytest.mark.ros

L = LaserConfig()
POSE = (0.3, -0.2, math.radians(10.0))        # base_footprint in map
WORLD = load_world(os.path.join(ROOT, 'test', 'worlds', 'detection_row.yaml'))


class FakeSensors:
    """A scan (or none) at 12.5 s and the transforms of a robot standing at ``pose``; records
    the calls. ``earlier``: the held scans before it, newest first, as ``(ranges, odom pose of
    the laser)`` pairs 1/15 s apart (as the node holds them); the laser's odom pose at 12.5 s is
    ``odom``."""

    def __init__(self, ranges, pose=POSE, missing=(), earlier=(), odom=(1.0, 2.0, 0.5)):
        self.ranges, self.pose, self.missing = ranges, pose, set(missing)
        self.odom = {12.5: odom}
        self.earlier = []
        for k, (r, at) in enumerate(earlier):
            stamp = 12.5 - (k + 1) / 15.0
            self.earlier.append(Scan(tuple(r), L.angle_min, L.angle_increment, L.range_min,
                                     L.range_max, stamp, 'base_laser_link'))
            self.odom[stamp] = at
        self.calls = []

    def fresh_scan(self, timeout):
        self.calls.append(('scan', timeout))
        if self.ranges is None:
            return None
        return Scan(self.ranges, L.angle_min, L.angle_increment, L.range_min, L.range_max,
                    12.5, 'base_laser_link')

    def scan_at(self, stamp, timeout, published=False):
        """Like the node's: the first scan at or after ``stamp``; the one scan here is at 12.5 s.
        A later one never comes: the node waits for a ``published`` one while its publisher
        lives, so it fails only once that is dead, naming the fact (here: unregistered)."""
        self.calls.append(('scan_at', stamp, timeout, published))
        if self.ranges is None or stamp > 12.5:
            if published:
                raise Failure('no /scan stamped at or after %.3f s: %s' % (stamp, source_verdict(
                    '/scan', [], set())))
            return None
        return Scan(self.ranges, L.angle_min, L.angle_increment, L.range_min, L.range_max,
                    12.5, 'base_laser_link')

    def scans_before(self, scan, count):
        self.calls.append(('scans_before', scan.stamp, count))
        return self.earlier[:count]

    def pose_covariance(self, stamp):
        return None             # (a ground-truth localisation: none published)

    def transform(self, target, source, stamp, timeout):
        self.calls.append(('tf', target, source, stamp, timeout))
        if target in self.missing:
            raise LookupError('"%s" passed to lookupTransform argument target_frame does not '
                              'exist' % target)
        if target == 'odom':
            return self.odom[stamp]
        laser_in_robot = (LASER_OFFSET, 0.0, 0.0)
        return compose(self.pose, laser_in_robot) if target == 'map' else laser_in_robot


@pytest.fixture(scope='module')
def clean():
    with Scene(WORLD) as scene:
        r, _ = scene.cast(POSE)
        return r, view_from(scene, POSE).in_view


@pytest.fixture(scope='module')
def grid():
    return rasterise_world(WORLD)


def service(grid, **kw):
    s = DetectionService(Params(**kw))
    if grid is not None:
        s.set_map(grid)
    return s


def noisy_scan(clean, seed=3):
    return noisy(clean[0], 0.01, np.random.default_rng(seed), L.range_min, L.range_max)


def test_a_request_with_a_scan_stamp_uses_the_scan_at_that_stamp_and_names_it(clean, grid):
    sensors = FakeSensors(noisy_scan(clean))
    a = service(grid).handle('', 0.0, 0.0, sensors, scan_stamp=12.5)
    assert a.success, a.message
    assert sensors.calls[0] == ('scan_at', 12.5, Params().scan_timeout, True)
    assert a.stamp == 12.5 and 'on the scan at 12.500 s' in a.message
    later = service(grid).handle('', 0.0, 0.0, FakeSensors(noisy_scan(clean)), scan_stamp=13.0)
    assert not later.success
    assert later.message == ('no /scan stamped at or after 13.000 s: nothing publishes /scan any '
                             'more (the simulator is not running)')


def _errors(answer, visible):
    out = []
    for i in visible:
        c = WORLD.movable_obstacles[i]
        out.append(min(math.hypot(o.center[0] - c.x, o.center[1] - c.y) for o in answer.obstacles))
    return np.array(out)


def test_scans_at_rest_are_combined_and_place_the_centres_better(clean, grid):
    """Five scans from one pose: the median of their ranges halves the range noise, so over 10
    calls the centres are nearer the truth than from the one scan each call names."""
    one, five = [], []
    for seed in range(10):
        scans = [noisy_scan(clean, seed=100 * seed + k) for k in range(5)]
        rest = [(r, (1.0, 2.0, 0.5)) for r in scans[1:]]
        a = service(grid).handle('', 0.0, 0.0, FakeSensors(scans[0], earlier=rest),
                                 scan_stamp=12.5)
        b = service(grid, rest_scans=1).handle('', 0.0, 0.0, FakeSensors(scans[0], earlier=rest),
                                               scan_stamp=12.5)
        assert a.success and b.success
        assert 'the median of 5 scans at rest, from 12.233 s' in a.message
        assert 'median' not in b.message
        five.append(_errors(a, clean[1]))
        one.append(_errors(b, clean[1]))
    rms = [float(np.sqrt(np.mean(np.concatenate(e) ** 2))) for e in (one, five)]
    assert rms[1] < 0.75 * rms[0], rms


@pytest.mark.parametrize('moved', [(1.002, 2.0, 0.5), (1.0, 2.0, 0.5 + math.radians(0.1))])
def test_a_scan_taken_elsewhere_ends_the_scans_at_rest(clean, grid, moved):
    r = noisy_scan(clean)
    still = (1.0, 2.0, 0.5)
    sensors = FakeSensors(r, earlier=[(r, still), (r, moved), (r, still)])
    a = service(grid).handle('', 0.0, 0.0, sensors, scan_stamp=12.5)
    assert a.success and 'the median of 2 scans at rest' in a.message
    assert ('scans_before', 12.5, STRIDE_SCANS) in sensors.calls


def test_without_odometry_the_named_scan_is_used_alone(clean, grid):
    r = noisy_scan(clean)
    sensors = FakeSensors(r, missing=('odom',), earlier=[(r, (1.0, 2.0, 0.5))])
    a = service(grid).handle('', 0.0, 0.0, sensors, scan_stamp=12.5)
    assert a.success and 'median' not in a.message


def test_good_request_returns_every_obstacle_in_both_frames_nearest_first(clean, grid):
    sensors = FakeSensors(noisy_scan(clean))
    a = service(grid).handle('', 0.0, 0.0, sensors)
    assert a.success, a.message
    assert a.stamp == 12.5
    assert 'obstacle(s) found with circle_fit' in a.message
    visible = clean[1]
    assert len(a.obstacles) == len(visible) >= 4
    for i in visible:
        c = WORLD.movable_obstacles[i]
        o = min(a.obstacles, key=lambda o: math.hypot(o.center[0] - c.x, o.center[1] - c.y))
        assert math.hypot(o.center[0] - c.x, o.center[1] - c.y) < 0.03
        assert abs(o.radius - c.radius) < 0.04
        assert o.num_points >= 5
        # robot frame: the true centre seen from the true pose
        rx, ry, _ = compose(inverse(POSE), (c.x, c.y, 0.0))
        assert math.hypot(o.center_robot[0] - rx, o.center_robot[1] - ry) < 0.03
    d = [math.hypot(*o.center_robot) for o in a.obstacles]
    assert d == sorted(d)
    # the waits use the node's timeouts
    assert ('scan', 2.0) in sensors.calls
    assert [c[1] for c in sensors.calls if c[0] == 'tf'] == ['map', 'base_footprint']
    assert all(c[4] == 1.0 for c in sensors.calls if c[0] == 'tf')


def test_methods_and_thresholds_of_the_request_are_used(clean, grid):
    r = noisy_scan(clean)
    svc = service(grid)
    a = svc.handle('centroid', 0.0, 0.0, FakeSensors(r))
    assert a.success and 'with centroid' in a.message
    b = svc.handle('', 0.0, 0.0, FakeSensors(r))
    # the centroid lies between the true centre and the laser: nearer the robot
    assert sum(math.hypot(*o.center_robot) for o in a.obstacles) \
        < sum(math.hypot(*o.center_robot) for o in b.obstacles)
    # a huge map threshold removes every point: looked, found none
    c = svc.handle('', 5.0, 0.0, FakeSensors(r))
    assert c.success and c.obstacles == () and c.message.startswith('0 obstacle(s)')


def test_default_method_is_a_parameter(clean, grid):
    a = service(grid, method='discontinuity').handle('', 0.0, 0.0, FakeSensors(noisy_scan(clean)))
    assert a.success and 'with discontinuity' in a.message


@pytest.mark.parametrize('method, smt, ct, field', [
    ('ransac', 0.0, 0.0, 'method'),
    ('CIRCLE_FIT', 0.0, 0.0, 'method'),
    ('', float('nan'), 0.0, 'scan_minus_map_threshold'),
    ('', -0.1, 0.0, 'scan_minus_map_threshold'),
    ('', float('inf'), 0.0, 'scan_minus_map_threshold'),
    ('', 0.0, -1.0, 'cluster_threshold'),
    ('', 0.0, float('nan'), 'cluster_threshold'),
    ('centroid', 0.0, float('-inf'), 'cluster_threshold'),
])
def test_every_bad_request_fails_naming_the_field_and_touches_nothing(clean, grid, method, smt,
                                                                      ct, field):
    sensors = FakeSensors(noisy_scan(clean))
    a = service(grid).handle(method, smt, ct, sensors)
    assert not a.success
    assert a.obstacles == ()
    assert 'bad request' in a.message and field in a.message
    assert sensors.calls == []          # no scan waited for, no tf looked up
    with pytest.raises(Exception, match=field):
        check_request(method, smt, ct, 'circle_fit')


def test_check_request_defaults_the_method():
    assert check_request('', 0.0, 0.0, 'centroid') == 'centroid'
    assert check_request('discontinuity', 0.3, 0.5, 'centroid') == 'discontinuity'


def test_before_any_map_the_reason_names_the_topic():
    """The node advertises the service only once a usable map came (no call can be answered
    "no map"); until then this reason is what its fatal exit after ~map_timeout gives
    (test_detection_errors: 'no usable map on ... (no /map received yet)')."""
    assert service(None, map_topic='/static_map').map_error == 'no /static_map received yet'


def test_an_unusable_map_replaces_the_old_one_until_a_good_one_comes(clean, grid):
    svc = service(grid)
    svc.map_unusable('maps with a rotated origin are not supported')
    a = svc.handle('', 0.0, 0.0, FakeSensors(noisy_scan(clean)))
    assert not a.success and 'unusable /map: maps with a rotated origin' in a.message
    svc.set_map(grid)
    assert svc.handle('', 0.0, 0.0, FakeSensors(noisy_scan(clean))).success


def test_no_scan_fails_naming_the_topic_and_the_wait(grid):
    a = service(grid, scan_topic='/base_scan', scan_timeout=0.7).handle(
        '', 0.0, 0.0, FakeSensors(None))
    assert not a.success and a.obstacles == ()
    assert a.message == 'no /base_scan received within 0.7 s'


@pytest.mark.parametrize('frame', ['map', 'base_footprint'])
def test_no_transform_fails_naming_the_frames(clean, grid, frame):
    a = service(grid).handle('', 0.0, 0.0, FakeSensors(noisy_scan(clean), missing={frame}))
    assert not a.success and a.obstacles == ()
    assert a.message.startswith('no transform %s <- base_laser_link at the scan time' % frame)
    assert 'does not exist' in a.message


def test_frames_are_parameters(clean, grid):
    sensors = FakeSensors(noisy_scan(clean), missing={'base_link'})
    a = service(grid, map_frame='world', robot_frame='base_link').handle('', 0.0, 0.0, sensors)
    assert [c[1] for c in sensors.calls if c[0] == 'tf'] == ['world', 'base_link']
    assert not a.success and a.message.startswith('no transform base_link <- base_laser_link')


@pytest.mark.parametrize('error', [ValueError('ranges and angles disagree'),
                                   RuntimeError('ranges and angles disagree'),
                                   np.linalg.LinAlgError('ranges and angles disagree')])
def test_pipeline_error_is_an_answer_not_a_crash(clean, grid, error):
    svc = service(grid)

    def broken(*args, **kw):
        raise error
    svc.detector.locate = broken           # the call the service makes
    a = svc.handle('', 0.0, 0.0, FakeSensors(noisy_scan(clean)))
    assert not a.success and a.obstacles == ()
    assert a.message == 'detection failed on this scan: %s: ranges and angles disagree' \
        % type(error).__name__


def glitch(ranges, bad, fraction, seed=0):
    """``ranges`` with ``fraction`` of the beams (seeded random choice) set to ``bad``."""
    r = np.array(ranges, dtype=float)
    idx = np.random.default_rng(seed).choice(len(r), int(round(fraction * len(r))), replace=False)
    r[idx] = bad
    return r


@pytest.mark.parametrize('name, ranges', [
    ('dead laser (all NaN)', lambda r: np.full(len(r), np.nan)),
    ('all zero', lambda r: np.zeros(len(r))),
    ('60 % NaN burst', lambda r: glitch(r, np.nan, 0.6)),
    ('60 % below range_min', lambda r: glitch(r, 0.01, 0.6)),
    ('60 % beyond range_max', lambda r: glitch(r, 1e6, 0.6)),
    ('empty scan', lambda r: np.zeros(0)),
])
def test_a_scan_with_too_few_valid_beams_fails_instead_of_finding_none(clean, grid, name,
                                                                       ranges):
    for method in ('circle_fit', 'centroid', 'discontinuity'):
        sensors = FakeSensors(ranges(noisy_scan(clean)))
        a = service(grid).handle(method, 0.0, 0.0, sensors)
        assert not a.success, (name, method, a.message)
        assert a.obstacles == ()
        assert a.message.startswith('too few valid beams to judge'), a.message
        assert 'at least 50 % needed' in a.message
        assert not [c for c in sensors.calls if c[0] == 'tf']   # judged before any tf wait


def test_the_valid_fraction_is_a_parameter_and_inf_beams_count_as_valid(clean, grid):
    r = glitch(noisy_scan(clean), np.nan, 0.3)
    a = service(grid).handle('', 0.0, 0.0, FakeSensors(r))
    assert a.success, a.message                       # 70 % valid: judged
    assert len(a.obstacles) == len(clean[1])          # and the holes lose nothing
    a = service(grid, min_informative_fraction=0.8).handle('', 0.0, 0.0, FakeSensors(r))
    assert not a.success and '70 % of the 666 beams' in a.message
    # REP 117: +inf (no return) and -inf (too close) are measurements, not gaps
    r = glitch(glitch(noisy_scan(clean), np.inf, 0.3, 1), -np.inf, 0.3, 2)
    assert service(grid).handle('', 0.0, 0.0, FakeSensors(r)).success


def test_empty_world_answers_success_with_none():
    empty = GridMap(np.zeros((10, 10), dtype=np.int8), 0.05, (-0.25, -0.25))
    ranges = np.full(L.num_beams, np.inf)
    a = service(empty).handle('', 0.0, 0.0, FakeSensors(ranges))
    assert a.success and a.obstacles == ()


def test_params_are_checked_and_named():
    with pytest.raises(ParamError, match='method'):
        Params(method='hough')
    with pytest.raises(ParamError, match='scan_timeout'):
        Params(scan_timeout=0.0)
    with pytest.raises(ParamError, match='scan_topic'):
        Params(scan_topic='')
    p = Params()
    with pytest.raises(ParamError, match='min_radius'):
        replace(p.detection, min_radius=0.7)
    with pytest.raises(ParamError, match='cluster_threshold'):
        replace(p.detection, cluster_threshold=-0.1)


def test_the_nodes_tf_wait_is_counted_in_wall_time():
    """RosSensors.transform waits ``timeout`` wall seconds for a transform that is late (tf2's
    own timeout ran in ROS time: at 4x real time a call made while the node's /tf subscription
    was still connecting gave up after a quarter of its wait), and fails with LookupError."""
    import threading
    import time

    import rospy
    import tf2_ros
    from geometry_msgs.msg import TransformStamped

    from tiago_nav.nodes.obstacle_detection import RosSensors

    class Buffer:                           # tf that holds the transform once ``arrived`` is set
        arrived = threading.Event()

        def can_transform(self, target, source, stamp):
            return self.arrived.is_set()

        def lookup_transform(self, target, source, stamp):
            if not self.arrived.is_set():
                raise tf2_ros.LookupException('"map" passed to lookupTransform argument '
                                              'target_frame does not exist')
            t = TransformStamped()
            t.transform.translation.x, t.transform.rotation.w = 1.5, 1.0
            return t

    sensors = object.__new__(RosSensors)    # no subscriptions: only its tf wait is tested
    sensors.tf = Buffer()
    stamp = rospy.Time.from_sec(3.0)
    t0 = time.monotonic()
    with pytest.raises(LookupError):
        sensors.transform('map', 'base_laser_link', stamp, 0.3)
    assert time.monotonic() - t0 >= 0.3
    threading.Timer(0.2, Buffer.arrived.set).start()
    assert sensors.transform('map', 'base_laser_link', stamp, 2.0) == pytest.approx((1.5, 0, 0))


def test_a_reset_reuses_the_maps_detector_and_answers_as_a_new_one(clean, grid):
    """The node keeps one ObstacleDetector per map and detection parameters
    (``detector_for``): a reset's new state gets the same object for the same map, another map
    or other parameters a new one; the answer with the kept detector equals a new one's."""
    from tiago_nav.detection.detectors import detector_for
    p = Params()
    d = detector_for(grid, p.detection)
    same = GridMap(grid.data.copy(), grid.resolution, tuple(grid.origin))
    assert detector_for(same, p.detection) is d
    other = GridMap(grid.data.copy(), grid.resolution, (grid.origin[0] + 0.05, grid.origin[1]))
    assert detector_for(other, p.detection) is not d
    assert detector_for(grid, replace(p.detection, cluster_threshold=p.detection.cluster_threshold * 2)) \
        is not detector_for(grid, p.detection)
    ranges, _ = clean
    kept = DetectionService(p)
    kept.set_map(grid, detector_for(grid, p.detection))
    a = kept.handle('', 0.0, 0.0, FakeSensors(ranges))
    b = service(grid).handle('', 0.0, 0.0, FakeSensors(ranges))
    assert a.success
    # every field, NaN equal to NaN (from Python 3.13 a dataclass's == compares field by field,
    # so the unobserved fields' NaN made equal answers unequal)
    np.testing.assert_equal(asdict(a), asdict(b))
