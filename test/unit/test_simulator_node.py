"""The simulator node's decisions without a ROS master: driven step by step with fake
publishers, it publishes /clock every step, odometry/tf/ground truth at 30 Hz and /scan at 15 Hz
of simulated time with the right stamps and frames, everything before the first /clock,
collisions once per change, REP 117 ranges and injected laser faults; it ignores bad commands,
paces itself against real_time_factor and refuses bad parameters naming them."""
import math
import os
from dataclasses import fields

import numpy as np
import pytest
import rospy
from geometry_msgs.msg import Twist
from std_msgs.msg import String

from conftest import ROOT
from tiago_nav.geometry import compose
from tiago_nav.params import ParamError, read_params
from tiago_nav import scan as rep117
from tiago_nav.ros.conversions import gridmap_from_msg, pose_from_msg, pose_from_transform
from tiago_nav.sim.raster import rasterise_world
from tiago_nav_tools.testing.fakes import FakeClock, FakePublisher

from tiago_nav.clock import Pacer
from tiago_nav.nodes.simulator import Outputs, Params, SimulatorNode, read_config

# needs ROS: rospy, message packages, tiago_nav.nodes.simulator
pytestmark = pytest.mark.ros

BOX = os.path.join(ROOT, 'test', 'worlds', 'sim_box.yaml')   # robot at (1, 1.5) facing the wall x = 2.5


class Log:
    """Collects what the node logs."""

    def __init__(self):
        self.warnings, self.infos = [], []

    def logwarn(self, text):
        self.warnings.append(text)

    def loginfo(self, text):
        self.infos.append(text)


def fake_outputs():
    return Outputs(**{f.name: FakePublisher() for f in fields(Outputs)})


def make_node(use_sim_time=True, now=None, **kw):
    """A node on ``BOX`` with the exact laser and odometry unless ``kw`` says otherwise (the
    node's defaults are the ``tiago`` laser and drifting odometry)."""
    kw.setdefault('world', BOX)
    kw.setdefault('laser_model', 'ideal')
    kw.setdefault('odometry_model', 'ideal')
    node = SimulatorNode(read_params(Params, lambda n, d: {'~' + k: v for k, v in kw.items()}.get(n, d)),
                         fake_outputs(), use_sim_time=use_sim_time, now=now, log=Log())
    return node


@pytest.fixture
def node():
    n = make_node(laser_noise=0.0)
    yield n
    n.close()


def twist(v, w=0.0):
    t = Twist()
    t.linear.x, t.angular.z = v, w
    return t


def run(node, steps, cmd=None):
    for _ in range(steps):
        if cmd is not None:
            node.on_cmd_vel(cmd)
        node.step()


def ns(stamp):
    return stamp.to_nsec()


def test_clock_every_step_odom_and_ground_truth_at_30hz_and_scan_at_15hz(node):
    node.start()
    run(node, 60)                                   # one second of simulated time
    out = node.out
    assert [ns(m.clock) for m in out.clock.messages] == [k * 10**9 // 60 for k in range(61)]
    assert [ns(m.header.stamp) for m in out.odom.messages] == [k * 10**9 // 30 for k in range(31)]
    assert [ns(m.header.stamp) for m in out.scan.messages] == [k * 10**9 // 15 for k in range(16)]
    assert len(out.tf.messages) == len(out.ground_truth.messages) == 31
    for odom, tf, truth in zip(out.odom.messages, out.tf.messages, out.ground_truth.messages):
        assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_footprint')
        assert (truth.header.frame_id, truth.child_frame_id) == ('map', 'base_footprint')
        assert [(t.header.frame_id, t.child_frame_id) for t in tf.transforms] == \
            [('map', 'odom'), ('odom', 'base_footprint')]
        assert all(t.header.stamp == odom.header.stamp for t in tf.transforms)
        assert truth.header.stamp == odom.header.stamp
    scan = out.scan.last
    assert scan.header.frame_id == 'base_laser_link' and len(scan.ranges) == 666
    assert (scan.range_min, scan.range_max) == (0.05, 25.0)
    assert math.degrees(scan.angle_min) == pytest.approx(-110)
    assert scan.angle_min + 665 * scan.angle_increment == pytest.approx(scan.angle_max)
    assert scan.ranges[333] == pytest.approx(2.5 - 1.0 - 0.2, abs=0.01)   # the east wall ahead


def test_start_publishes_the_latched_map_and_the_laser_transform(node):
    node.start()
    out = node.out
    grid = gridmap_from_msg(out.map.last)
    assert out.map.last.header.frame_id == 'map' and len(out.map.messages) == 1
    np.testing.assert_array_equal(grid.data, rasterise_world(node.world).data)
    assert out.map_metadata.last.width == grid.width
    assert [m.data for m in out.collisions.messages] == [0]
    run(node, 60)
    assert len(out.map.messages) == len(out.tf_static.messages) == 1     # latched: sent once


def test_odometry_and_ground_truth_follow_cmd_vel(node):
    node.start()
    run(node, 120, cmd=twist(0.5))                  # 0.5 s ramp then 1.5 s at 0.5 m/s
    odom = node.out.odom.last
    x, y, yaw = pose_from_msg(odom.pose.pose)
    assert x == pytest.approx(0.125 + 0.75, abs=1e-3) and y == pytest.approx(0, abs=1e-9)
    assert odom.twist.twist.linear.x == pytest.approx(0.5)
    map_odom = pose_from_transform(node.out.tf.last.transforms[0].transform)
    assert map_odom == pytest.approx((1.0, 1.5, 0.0))                 # the world's start pose
    truth = node.out.ground_truth.last
    assert pose_from_msg(truth.pose.pose) == pytest.approx((1.0 + 0.875, 1.5, 0.0), abs=1e-3)
    assert truth.twist.twist.linear.x == pytest.approx(0.5)


def test_ground_truth_is_the_map_pose_when_map_and_odom_differ():
    node = make_node(robot_start=[1.5, 1.0, 90], laser_noise=0.0)
    try:
        node.start()
        run(node, 120, cmd=twist(0.3, 0.4))
        odom = pose_from_msg(node.out.odom.last.pose.pose)
        map_odom = pose_from_transform(node.out.tf.last.transforms[0].transform)
        truth = pose_from_msg(node.out.ground_truth.last.pose.pose)
        assert truth == pytest.approx(compose(map_odom, odom), abs=1e-9)   # odometry is exact
        assert math.hypot(truth[0] - 1.5, truth[1] - 1.0) > 0.3              # and it moved
        assert truth[2] > math.pi / 2 + 0.3
    finally:
        node.close()


def test_static_frames_base_link_and_laser(node):
    node.start()
    (body, laser), = [m.transforms for m in node.out.tf_static.messages]
    assert (body.header.frame_id, body.child_frame_id) == ('base_footprint', 'base_link')
    t = body.transform.translation
    assert (t.x, t.y, t.z, body.transform.rotation.w) == (0, 0, pytest.approx(0.0985), 1)  # the URDF's
    assert (laser.header.frame_id, laser.child_frame_id) == ('base_link', 'base_laser_link')
    t = laser.transform.translation
    assert (t.x, t.y, t.z + 0.0985) == pytest.approx((0.2, 0.0, 0.3))   # 0.3 m above the floor


def test_defaults_are_the_tiago_laser_and_drifting_odometry():
    p = Params(world=BOX)
    assert (p.sim.laser_model.laser_model, p.sim.odometry.odometry_model) == ('tiago', 'drift')
    assert p.publish_map_to_odom and p.publish_robot_frames


def test_with_drift_map_to_odom_composes_odometry_into_the_truth():
    node = make_node(odometry_model='drift', seed=3)
    try:
        node.start()
        run(node, 240, cmd=twist(0.4, 0.5))
        map_odom_tf, odom_tf = node.out.tf.last.transforms
        assert (map_odom_tf.header.frame_id, map_odom_tf.child_frame_id) == ('map', 'odom')
        map_odom = pose_from_transform(map_odom_tf.transform)
        odom = pose_from_msg(node.out.odom.last.pose.pose)
        truth = pose_from_msg(node.out.ground_truth.last.pose.pose)
        assert truth == pytest.approx(compose(map_odom, odom), abs=1e-9)
        assert map_odom != pytest.approx((1.0, 1.5, 0.0), abs=1e-4)          # odometry drifted
        assert pose_from_transform(odom_tf.transform) == pytest.approx(odom)
    finally:
        node.close()


def test_map_to_odom_and_robot_frames_can_be_left_to_other_nodes():
    node = make_node(publish_map_to_odom=False, publish_robot_frames=False)
    try:
        node.start()
        run(node, 30)
        assert node.out.tf.messages
        assert all([(t.header.frame_id, t.child_frame_id) for t in m.transforms]
                   == [('odom', 'base_footprint')] for m in node.out.tf.messages)
        assert not node.out.tf_static.messages
        assert node.out.map.messages and node.out.ground_truth.messages
    finally:
        node.close()


class Recorder(FakePublisher):
    """A fake publisher that also writes ``(topic, msg)`` into one log shared by all."""

    def __init__(self, name, log):
        super().__init__()
        self.name, self.log = name, log

    def publish(self, msg):
        super().publish(msg)
        self.log.append(self.name)


def test_everything_is_published_before_the_first_clock():
    log = []
    outputs = Outputs(**{f.name: Recorder(f.name, log) for f in fields(Outputs)})
    node = SimulatorNode(Params(world=BOX), outputs, log=Log())
    try:
        node.start()
        first_clock = log.index('clock')
        needed = {'map', 'map_metadata', 'tf_static', 'tf', 'odom', 'scan', 'collisions',
                  'ground_truth'}
        assert needed <= set(log[:first_clock])
        run(node, 4)                                # then /clock leads each step
        assert log[first_clock + 1:] == ['clock', 'clock', 'odom', 'tf', 'ground_truth',
                                         'clock', 'clock', 'odom', 'tf', 'ground_truth', 'scan']
    finally:
        node.close()


def test_ranges_are_rep117_values():
    # the east wall is 1.3 m ahead of the laser: nearer than range_min, the others beyond range_max
    node = make_node(laser_range_min=1.5, laser_range_max=1.6, laser_noise=0.05)
    try:
        node.start()
        run(node, 60)
        r = np.array([m.ranges for m in node.out.scan.messages])
        kinds = rep117.classify(r, 1.5, 1.6)
        assert not np.any(kinds == rep117.INVALID)
        assert np.all(r[:, 300:366] == -np.inf)             # the wall ahead: too close
        assert np.any(kinds == rep117.NO_RETURN) and np.any(kinds == rep117.HIT)
    finally:
        node.close()


def test_a_non_finite_command_is_ignored_with_one_warning(node):
    node.start()
    run(node, 30, cmd=twist(float('nan'), 0.5))
    run(node, 30, cmd=twist(0.2, float('inf')))
    assert node.sim.pose == (1.0, 1.5, 0.0)
    assert len(node.log.warnings) == 1 and 'non-finite' in node.log.warnings[0]


def test_collisions_are_published_once_per_change(node):
    node.start()
    run(node, 300, cmd=twist(0.5))                  # the wall is 1.5 m ahead
    assert node.sim.pose[0] < 2.5 - 0.27 + 0.01
    assert [m.data for m in node.out.collisions.messages] == [0, 1]
    assert sum('collision #1' in w for w in node.log.warnings) == 1
    run(node, 60, cmd=twist(0.5))                   # still pushing: the same contact
    assert [m.data for m in node.out.collisions.messages] == [0, 1]


def test_frames_and_start_pose_come_from_the_parameters():
    node = make_node(map_frame='world', odom_frame='o', base_frame='base', laser_frame='laser',
                     robot_start=[1.5, 1.0, 90])
    try:
        node.start()
        out = node.out
        assert out.scan.last.header.frame_id == 'laser'
        assert out.map.last.header.frame_id == 'world'
        assert (out.odom.last.header.frame_id, out.odom.last.child_frame_id) == ('o', 'base')
        assert [(t.header.frame_id, t.child_frame_id) for t in out.tf.last.transforms] == \
            [('world', 'o'), ('o', 'base')]
        assert node.sim.pose == pytest.approx((1.5, 1.0, math.pi / 2))
    finally:
        node.close()


def test_without_sim_time_stamps_are_wall_time_and_there_is_no_clock():
    node = make_node(use_sim_time=False, now=lambda: rospy.Time(1234, 5))
    try:
        node.start()
        run(node, 4)
        assert node.out.scan.last.header.stamp == rospy.Time(1234, 5)
        assert node.out.clock.messages == []
    finally:
        node.close()


def reader(values):
    return lambda name, default: values.get(name, default)


@pytest.mark.parametrize('values, name', [
    ({}, 'world'),                                                   # required
    ({'~real_time_factor': -1.0}, 'real_time_factor'),
    ({'~scan_rate': 14.0}, 'scan_rate'),                             # does not divide rate
    ({'~odom_rate': 120.0}, 'odom_rate'),
    ({'~laser_noise': 1.5}, 'laser_noise'),
    ({'~robot_start': [1.0, 2.0]}, 'robot_start'),
    ({'~robot_start': [1.0, 2.0, 'x']}, 'robot_start'),
    ({'~max_linear_velocity': 0.0}, 'max_linear_velocity'),
    ({'~laser_range_max': 0.01}, 'laser_range_max'),                 # below laser_range_min
    ({'~laser_height': 0.1}, 'laser_height'),                        # inside the base body
    ({'~laser_frame': ''}, 'laser_frame'),
    ({'~seed': -1}, 'seed'),
    ({'~gui': 'yes'}, 'gui'),
])
def test_bad_parameters_are_refused_naming_them(values, name):
    values = dict(values)
    if name != 'world':
        values['~world'] = BOX
    values['/use_sim_time'] = True
    with pytest.raises(ParamError) as e:
        read_config(reader(values), resolve=lambda n: '/simulator/' + n[1:])
    assert str(e.value).startswith('parameter /simulator/%s: ' % name), str(e.value)


def test_real_time_factor_needs_sim_time():
    with pytest.raises(ParamError, match=r'~real_time_factor: 2 needs /use_sim_time true'):
        read_config(reader({'~world': BOX, '~real_time_factor': 2.0, '/use_sim_time': False}))
    params, use_sim_time = read_config(reader({'~world': BOX, '~real_time_factor': 0.0,
                                               '/use_sim_time': True}))
    assert use_sim_time and params.real_time_factor == 0.0
    with pytest.raises(ParamError, match='real_time_factor'):
        SimulatorNode(params, fake_outputs(), use_sim_time=False)


def test_a_missing_world_file_is_refused():
    with pytest.raises(ValueError, match='world file not found'):
        make_node(world='/nonexistent/world.yaml')


class TestPacer:
    def test_real_time_factor_sets_the_wall_time(self):
        clock = FakeClock()
        pacer = Pacer(clock, 1 / 60.0, 2.0)
        for k in range(1, 121):
            pacer.pace(k)
            assert clock.wall() == pytest.approx(k / 120.0)        # never ahead, never behind

    def test_zero_runs_as_fast_as_possible(self):
        clock = FakeClock()
        pacer = Pacer(clock, 1 / 60.0, 0.0)
        for k in range(1, 200):
            pacer.pace(k)
        assert clock.wall() == 0.0

    def test_a_slow_run_does_not_try_to_catch_up(self):
        clock = FakeClock()
        pacer = Pacer(clock, 0.1, 1.0)
        pacer.pace(1)
        assert clock.wall() == pytest.approx(0.1)
        clock.w += 2.0                                  # the machine stalled for 2 s
        pacer.pace(2)                                   # behind: pacing restarts from here
        assert clock.wall() == pytest.approx(2.1)
        pacer.pace(3)                                   # then one step per 0.1 s again
        assert clock.wall() == pytest.approx(2.2)


def fault(node, text):
    node.on_laser_fault(String(text))


def scans_between(node, t0, t1):
    return [m for m in node.out.scan.messages if t0 <= m.header.stamp.to_sec() < t1 - 1e-9]


def test_injected_laser_faults(node):
    node.start()
    run(node, 30)                                   # t = 0.5 s
    fault(node, 'nan 0.5')
    run(node, 60, cmd=twist(0.3))                   # t = 1.5 s
    nan = scans_between(node, 0.51, 1.0)
    assert len(nan) == 7 and all(np.isnan(m.ranges).all() for m in nan)
    healthy = scans_between(node, 1.0, 1.51)
    assert len(healthy) == 8 and all(np.isfinite(m.ranges).all() for m in healthy)

    fault(node, 'zero')                             # until cleared
    run(node, 60)
    assert all(np.array_equal(m.ranges, np.zeros(666)) for m in scans_between(node, 1.51, 2.51))
    fault(node, 'dead 1')
    run(node, 64)                                   # t = 3.567 s
    assert scans_between(node, 2.51, 3.5) == []
    assert len(scans_between(node, 3.5, 3.57)) == 1  # the laser is back after 1 s (scan at 3.533)

    last = node.out.scan.last
    fault(node, 'freeze')
    run(node, 60, cmd=twist(0.3))                   # the robot moves; the laser is stuck
    frozen = scans_between(node, 3.57, 4.57)
    assert len(frozen) == 15 and all(m.ranges == last.ranges for m in frozen)
    assert len({m.header.stamp for m in frozen}) == 15
    fault(node, 'none')
    run(node, 4)
    assert node.out.scan.last.ranges != last.ranges
    assert not node.log.warnings


@pytest.mark.parametrize('text', ['', 'explode', 'nan -1', 'nan soon', 'dead 1 2', 'none 3'])
def test_a_bad_fault_command_is_logged_and_changes_nothing(node, text):
    node.start()
    fault(node, 'dead 2')
    fault(node, text)
    assert len(node.log.warnings) == 1 and 'ignoring laser fault command' in node.log.warnings[0]
    run(node, 60)
    assert node.out.scan.messages[1:] == []         # still dead


def test_objects_ground_truth_of_shapes_and_walkers_and_a_reset_puts_walkers_back(tmp_path):
    import yaml
    world = tmp_path / 'shapes.yaml'
    world.write_text(yaml.safe_dump({
        'name': 'shapes', 'resolution': 0.05, 'bounds': [-4, -4, 4, 4], 'robot_start': [0, 0, 0],
        'movable_obstacles': [{'x': 2, 'y': 2, 'radius': 0.2},
                              {'shape': 'box', 'x': 2, 'y': -2, 'length': 0.8, 'width': 0.4, 'yaw_deg': 30},
                              {'shape': 'table', 'x': -2, 'y': 2, 'length': 1.2, 'width': 0.8}],
        'walkers': [{'path': [[3, 1], [-3, 1]], 'speed': 1.0, 'loop': True}]}))
    node = make_node(world=str(world))
    try:
        node.start()
        first = node.out.objects.last
        assert [o.shape for o in first.objects] == ['cylinder', 'box', 'table', 'walker']
        assert [o.name for o in first.objects][-1] == 'walkers[0]'
        box, table, walker = first.objects[1:]
        assert box.pose.theta == pytest.approx(math.radians(30)) and box.length == pytest.approx(0.8)
        assert len(table.legs) == 4 and table.leg_radius == pytest.approx(0.03)
        assert (walker.pose.x, walker.pose.y) == (3.0, 1.0) and len(walker.legs) == 2
        assert node.out.markers.last.markers, 'drawn for RViz'
        n = len(node.out.objects.messages)
        run(node, 60)                       # 1 s: 15 scans, each with the objects
        assert len(node.out.objects.messages) == n + 15
        walker = node.out.objects.last.objects[-1]
        assert walker.pose.x == pytest.approx(2.0) and walker.velocity.x == pytest.approx(-1.0)
        assert walker.state == 'walking'
        node.reset(node.params)
        walker = node.out.objects.last.objects[-1]
        assert (walker.pose.x, walker.pose.y) == (3.0, 1.0) and walker.velocity.x == 0.0
    finally:
        node.close()
