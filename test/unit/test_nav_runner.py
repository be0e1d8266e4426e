"""The move_base node's goal handling driven with fakes (no ROS master): the node's ActionIO
over a FakeActionServer and FakePublishers, a FakeClock, and a kinematic base (DiffDrive) as
the pose source; scans are synthetic REP 117 scans of an empty floor plus, where a test says
so, a round obstacle the map does not have."""
import math

import numpy as np
import pytest

from tiago_nav.geometry import wrap_angle, yaw_to_quaternion
from tiago_nav.gridmap import GridMap
from tiago_nav.nav.costmap import MapScan
from tiago_nav.nav.navigator import NavConfig, Navigator
from tiago_nav.nav.runner import GoalError, GoalRunner, PoseUnavailable
from tiago_nav.robot import LASER_OFFSET, ROBOT_RADIUS
from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive
from tiago_nav.testing.fakes import FakeActionServer, FakeClock, FakePublisher

navigation = pytest.importorskip('tiago_nav.nodes.navigation')

N_BEAMS, A_MIN, A_INC, R_MIN, R_MAX = 221, -math.radians(110), math.radians(1), 0.05, 25.0


def empty_grid(w=8.0, h=4.0, res=0.05):
    return GridMap(np.zeros((int(h / res), int(w / res)), dtype=np.int8), res, (0.0, 0.0))


class Rig:
    """A goal runner wired to fakes. ``obstacle``: ``(x, y, radius)`` the laser sees but the map
    lacks; ``glitch(ranges) -> ranges`` corrupts each scan; ``laser_on`` / ``pose_on`` kill a
    sensor; ``fail_at``: ROS time at which the pose source raises a bug."""

    def __init__(self, start=(1.0, 2.0, 0.0), config=NavConfig(), preempt_at=None, obstacle=None):
        self.clock = FakeClock()
        self.base = DiffDrive(start, BaseLimits())
        self.nav = Navigator(empty_grid(), config)
        self.server = FakeActionServer(self.clock, preempt_at)
        self.cmd, self.plan = FakePublisher(), FakePublisher()
        self.obstacle, self.glitch = obstacle, None
        self.laser_on = self.pose_on = True
        self.fail_at = None
        self.next_scan = 0.0
        self.trail = []
        io = navigation.ActionIO(self.server, self.cmd, self.plan, self.clock, self.pose,
                                 self.to_map, 'map')
        self.runner = GoalRunner(self.nav, io, 0.1)
        self.clock.on_advance(self.advance)
        self.scan()

    def pose(self):
        if self.fail_at is not None and self.clock.now() >= self.fail_at:
            raise KeyError('a bug')
        if not self.pose_on:
            raise PoseUnavailable('tf map -> base_footprint lost')
        return self.base.pose, self.clock.now()

    def to_map(self, frame, pose):
        if frame != 'map':
            raise GoalError('no transform %s -> map' % frame)
        return pose

    def laser_pose(self):
        x, y, th = self.base.pose
        return (x + LASER_OFFSET * math.cos(th), y + LASER_OFFSET * math.sin(th), th)

    def ranges(self):
        lx, ly, th = self.laser_pose()
        r = np.full(N_BEAMS, np.inf)
        if self.obstacle:
            ox, oy, rad = self.obstacle
            a = th + A_MIN + A_INC * np.arange(N_BEAMS)
            dx, dy = ox - lx, oy - ly
            b = dx * np.cos(a) + dy * np.sin(a)
            disc = b * b - (dx * dx + dy * dy - rad * rad)
            hit = (disc >= 0) & (b > 0)
            r[hit] = b[hit] - np.sqrt(disc[hit])
        return r if self.glitch is None else self.glitch(r)

    def scan(self):
        if self.laser_on:
            self.nav.add_scan(MapScan(self.laser_pose(), self.ranges(), A_MIN, A_INC, R_MIN, R_MAX,
                                      self.clock.now()))

    def advance(self, dt):
        last = self.cmd.last
        v, w = (last.linear.x, last.angular.z) if last is not None else (0.0, 0.0)
        self.base.step(v, w, dt)
        self.trail.append(self.base.pose)
        if self.clock.now() >= self.next_scan:
            self.next_scan += 1 / 15.0
            self.scan()

    def run(self, x, y, yaw=0.0, frame='map', q=None):
        return self.runner.run(frame, (x, y, 0.0), q if q is not None else yaw_to_quaternion(yaw))

    def stopped_at_end(self):
        last = self.cmd.last
        return last is not None and last.linear.x == 0.0 and last.angular.z == 0.0


def test_goal_reached_with_feedback_and_plan():
    rig = Rig()
    out = rig.run(5.0, 2.5, math.pi / 2)
    assert rig.server.state == 'succeeded', rig.server.text
    assert out.text == 'goal reached'
    x, y, yaw = rig.base.pose
    assert math.hypot(x - 5.0, y - 2.5) <= 0.15
    assert abs(wrap_angle(yaw - math.pi / 2)) <= 0.1
    assert rig.stopped_at_end()
    assert len(rig.server.feedback) >= 10 * rig.clock.now() * 0.9   # ~every 0.1 s
    assert rig.plan.messages and rig.plan.messages[0].poses[-1].pose.position.x == pytest.approx(5.0)


@pytest.mark.parametrize('goal, why', [((20.0, 2.0), 'outside the map'),
                                       ((-1.0, 1.0), 'outside the map')])
def test_goal_outside_the_map_rejected_at_once(goal, why):
    rig = Rig()
    rig.run(*goal)
    assert rig.server.state == 'aborted'
    assert 'goal rejected' in rig.server.text and why in rig.server.text
    assert rig.clock.now() == 0.0 and rig.stopped_at_end()


def test_goal_in_a_wall_rejected():
    rig = Rig()
    rig.nav.costmap.static[:, 100:102] = True      # a wall across x = 5 m
    rig.nav.costmap.update()
    rig.run(5.02, 2.0)
    assert rig.server.state == 'aborted' and 'inside an obstacle' in rig.server.text
    assert rig.base.pose[0] == 1.0


def test_unknown_frame_rejected():
    rig = Rig()
    rig.run(3.0, 2.0, frame='odom_nowhere')
    assert rig.server.state == 'aborted' and 'no transform odom_nowhere' in rig.server.text


def test_preempt_stops_the_base():
    rig = Rig(preempt_at=1.5)
    rig.run(7.0, 2.0)
    assert rig.server.state == 'preempted'
    assert rig.stopped_at_end()
    assert rig.nav.state is None


def test_stopped_clock_ends_the_loop():
    rig = Rig()
    rig.clock.on_advance(lambda dt: setattr(rig.clock, 'stalled', rig.clock.t >= 1.0))
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted'
    assert 'ROS time stopped advancing' in rig.server.text
    assert rig.stopped_at_end()


def test_shutdown_ends_the_loop():
    rig = Rig()
    rig.clock.shutdown_at = 1.0
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted' and rig.server.text == 'node shutting down'


def test_params_cross_field_checks():
    from tiago_nav.nav.controller import ControllerConfig
    from tiago_nav.params import ParamError
    with pytest.raises(ParamError) as e:
        NavConfig(inflation_radius=0.2)
    assert e.value.name == 'inflation_radius'
    with pytest.raises(ParamError) as e:
        NavConfig(robot_radius=0.3)
    assert e.value.name == 'robot_radius'
    assert NavConfig(robot_radius=0.3, controller=ControllerConfig(robot_radius=0.3)).robot_radius == 0.3
    assert NavConfig().robot_radius == ControllerConfig().robot_radius == ROBOT_RADIUS


def test_node_params_read_every_name():
    from tiago_nav.params import ParamError, read_params
    p = read_params(navigation.Params, lambda n, d: {'~robot_radius': 0.3, '~max_vel_x': 0.5,
                                                     '~controller_frequency': 20}.get(n, d))
    assert p.nav.robot_radius == p.nav.controller.robot_radius == 0.3
    assert p.nav.controller.max_vel_x == 0.5 and p.controller_frequency == 20.0
    with pytest.raises(ParamError, match='inflation_radius'):
        read_params(navigation.Params, lambda n, d: {'~robot_radius': 0.9}.get(n, d))
