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
from tiago_nav.nav.navigator import NavConfig, Navigator, ProgressWindow
from tiago_nav.nav.runner import (GoalError, GoalRunner, PoseUnavailable, frame_or, goal_pose,
                                  no_transform)
from tiago_nav.robot import LASER_OFFSET, ROBOT_RADIUS
from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive
from tiago_nav_tools.testing.fakes import FakeActionServer, FakeClock, FakePublisher

pytestmark = pytest.mark.ros         # tiago_nav.nodes.navigation (rospy, tf2_ros, move_base_msgs)
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
            raise no_transform(PoseUnavailable, 'map', 'base_footprint', 'transform lost')
        return self.base.pose, self.clock.now()

    def to_map(self, frame, pose):
        if frame_or(frame, 'map') != 'map':
            raise no_transform(GoalError, frame, 'map', 'unknown frame')
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
    assert out.message == 'goal reached'
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


@pytest.mark.parametrize('position, q, why', [
    ((float('nan'), 2.0), (0, 0, 0, 1), 'non-finite field (position.x=nan)'),
    ((3.0, 2.0), (0, 0, float('inf'), 1), 'non-finite field (orientation.z=inf)'),
    ((3.0, 2.0), (0, 0, 0, 0), 'cannot be normalised'),
    ((3.0, 2.0), (0, 0, 1e-5, 1e-5), 'cannot be normalised')])
def test_bad_goal_values_aborted_with_the_reason(position, q, why):
    rig = Rig()
    rig.run(*position, q=q)
    assert rig.server.state == 'aborted'
    assert why in rig.server.text, rig.server.text
    assert rig.base.pose == (1.0, 2.0, 0.0) and rig.stopped_at_end()


def test_unnormalised_quaternion_is_normalised():
    assert goal_pose((1, 2, 0), (0, 0, 2 * math.sin(0.5), 2 * math.cos(0.5)))[2] == pytest.approx(1.0)


def test_unknown_frame_rejected():
    rig = Rig()
    rig.run(3.0, 2.0, frame='odom_nowhere')
    assert rig.server.state == 'aborted'
    assert rig.server.text.startswith('goal rejected: no transform odom_nowhere -> map: ')


def test_preempt_stops_the_base():
    rig = Rig(preempt_at=1.5)
    rig.run(7.0, 2.0)
    assert rig.server.state == 'preempted'
    assert rig.stopped_at_end()
    assert rig.nav.state is None


def test_dead_clock_ends_the_loop_naming_the_reason():
    rig = Rig()
    dead = 'nothing publishes /clock any more (the simulator is not running)'

    def stall(dt):
        if rig.clock.t >= 1.0:
            rig.clock.stalled, rig.clock.dead = True, dead
    rig.clock.on_advance(stall)
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted'
    assert rig.server.text.startswith('ROS time stopped advancing at 1.')
    assert rig.server.text.endswith(dead)
    assert rig.stopped_at_end()


def test_slow_clock_is_waited_for():
    """ROS time stands still for 30 s of wall time, its source alive: the goal still arrives."""
    rig = Rig()

    def stall(dt):
        if rig.clock.t >= 1.0 and rig.clock.resume_at is None and rig.clock.w < 30.0:
            rig.clock.stalled, rig.clock.resume_at = True, rig.clock.w + 30.0
    rig.clock.on_advance(stall)
    rig.run(7.0, 2.0)
    assert rig.server.state == 'succeeded', rig.server.text
    assert rig.clock.w - rig.clock.t >= 29.9 and rig.clock.asked >= 10


def test_shutdown_ends_the_loop():
    rig = Rig()
    rig.clock.shutdown_at = 1.0
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted' and rig.server.text == 'node shutting down'


def test_unexpected_exception_stops_and_aborts_with_its_text():
    rig = Rig()
    rig.fail_at = 1.0
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted'
    assert rig.server.text == "unexpected error: KeyError: 'a bug'"
    assert rig.stopped_at_end()


def speed_after(rig, t):
    """The commanded forward speeds [m/s] published after ROS time ``t`` (cmd published at
    each cycle; the trail has one pose per clock nap)."""
    return [m.linear.x for m in rig.cmd.messages[int(t / 0.1) + 1:]]


@pytest.mark.parametrize('sensor, text, stop_by', [
    ('laser_on', 'no laser data for 3.', 2.0 + 0.5 + 0.1),     # stale after sensor_timeout
    ('pose_on', 'no odometry/pose for 3.', 2.0 + 0.1)])        # a missing pose at once
def test_dead_sensor_stops_the_base_then_aborts(sensor, text, stop_by):
    rig = Rig()
    rig.clock.on_advance(lambda dt: setattr(rig, sensor, rig.clock.t < 2.0))
    rig.run(7.5, 2.0)
    assert rig.server.state == 'aborted'
    assert rig.server.text.startswith(text), rig.server.text
    assert 4.8 <= rig.clock.now() <= 5.3          # last seen at 1.9-2.0 s, abort 3 s later
    assert max(speed_after(rig, 0.0)[:20]) > 0.5  # it was driving
    assert all(v == 0.0 for v in speed_after(rig, stop_by))
    assert rig.stopped_at_end()
    if sensor == 'pose_on':
        assert '(no transform map -> base_footprint: ' in rig.server.text, rig.server.text


def test_a_short_laser_gap_only_pauses():
    rig = Rig()
    rig.clock.on_advance(lambda dt: setattr(rig, 'laser_on', not 2.0 <= rig.clock.t < 3.5))
    rig.run(7.0, 2.0)
    assert rig.server.state == 'succeeded', rig.server.text
    assert all(v == 0.0 for v in speed_after(rig, 2.6)[:7])   # stopped while stale


def lost_between(rig, t0, t1):
    """The rig's localisation says it is lost from ROS time ``t0`` to ``t1``."""
    rig.runner.io.localisation_lost = \
        lambda: 'lost for the test' if t0 <= rig.clock.now() < t1 else ''


def test_a_lost_pose_stops_the_base_until_relocalised():
    rig = Rig()
    lost_between(rig, 2.0, 4.0)
    rig.run(7.0, 2.0)
    assert rig.server.state == 'succeeded', rig.server.text
    assert max(speed_after(rig, 0.0)[:20]) > 0.5             # it was driving
    assert all(v == 0.0 for v in speed_after(rig, 2.05)[:19])  # stopped while lost
    assert max(speed_after(rig, 4.0)) > 0.0                  # and drove on once relocalised


def test_lost_beyond_the_patience_aborts_naming_the_localisation():
    rig = Rig(config=NavConfig(localisation_patience=3.0))
    lost_between(rig, 2.0, 1e9)
    rig.run(7.5, 2.0)
    assert rig.server.state == 'aborted'
    assert rig.server.text.startswith('localisation lost for 3.'), rig.server.text
    assert 'lost for the test' in rig.server.text
    assert 4.9 <= rig.clock.now() <= 5.3
    assert all(v == 0.0 for v in speed_after(rig, 2.05))
    assert rig.stopped_at_end()


@pytest.mark.parametrize('glitch', [lambda r: np.full(0, 0.0), lambda r: np.full(len(r), np.nan),
                                    lambda r: np.zeros(len(r))])
def test_empty_or_all_invalid_scan_is_blocked(glitch):
    rig = Rig(config=NavConfig(no_progress_timeout=10.0))
    rig.glitch = glitch
    rig.scan()
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted'
    assert max(m.linear.x for m in rig.cmd.messages) == 0.0      # never drove forward
    assert rig.base.pose[0] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize('value', [np.nan, 0.0, -np.inf])
def test_glitch_over_an_unmapped_obstacle_keeps_it_and_blocks(value):
    obstacle = (2.2, 2.0, 0.25)               # 1 m ahead of the laser, not in the map
    rig = Rig(obstacle=obstacle)
    cell = rig.nav.costmap.grid.world_to_cell([(obstacle[0] - 0.25, 2.0)])[0]
    assert rig.nav.costmap.obstacles[cell[0], cell[1]]
    seen = np.isfinite(rig.ranges())
    rig.glitch = lambda r: np.where(seen, value, r)    # every beam on the obstacle glitches
    rig.scan()
    cm = rig.nav.costmap
    assert cm.obstacles[cell[0], cell[1]], 'the glitch erased the obstacle'
    pose = rig.base.pose
    assert not rig.nav.controller.safe(pose, 0.8, 0.0, rig.nav.points, 0.1, rig.nav.blind)


def test_too_close_beam_blocks_forward_motion():
    rig = Rig()
    rig.glitch = lambda r: np.where(np.arange(len(r)) == N_BEAMS // 2, -np.inf, r)
    rig.scan()
    assert not rig.nav.controller.safe(rig.base.pose, 0.3, 0.0, rig.nav.points, 0.1)


def test_derived_goal_timeout():
    cfg = NavConfig(goal_timeout_factor=0.5, goal_timeout_allowance=1.0)
    rig = Rig(config=cfg)
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted'
    assert rig.server.text.startswith('timeout: goal not reached in 4 s (0.5 x the 6.0 m plan')
    assert rig.clock.now() == pytest.approx(4.0, abs=0.15)
    assert rig.stopped_at_end()


def test_explicit_goal_timeout_zero_means_none():
    rig = Rig(config=NavConfig(goal_timeout=0.0, goal_timeout_factor=0.01,
                               goal_timeout_allowance=0.0))
    rig.run(5.0, 2.0)
    assert rig.server.state == 'succeeded', rig.server.text


def test_progress_window_catches_oscillation_and_passes_progress():
    w = ProgressWindow(10.0, 0.5)
    # swinging 1 m back and forth along the plan: never 0.5 m below the window's start for long
    hopeless = [w.update(t * 0.1, 5.0 + math.sin(t * 0.1)) for t in range(400)]
    assert any(hopeless)
    assert not any(hopeless[:100])            # the window must be full first
    w.reset()
    assert not any(w.update(t * 0.1, 10.0 - 0.06 * t * 0.1) for t in range(400))   # 6 cm/s
    assert not ProgressWindow(0.0, 0.5).update(100.0, 1.0)


def test_oscillating_robot_aborts_with_no_progress():
    """A controller that swings the base back and forth over 0.6 m (more than the recovery
    trigger's 0.15 m) is ended by the no-progress check."""
    cfg = NavConfig(no_progress_timeout=8.0, goal_timeout=0.0)
    rig = Rig(config=cfg)

    def swing(pose, goal, points, dt, blind=False, margins=None):
        return (0.6 if int(rig.clock.now() / 1.5) % 2 == 0 else -0.6), 0.0, 'follow'
    rig.nav.controller.command = swing
    rig.run(7.0, 2.0)
    assert rig.server.state == 'aborted'
    assert rig.server.text.startswith('no progress: the path still to go has not shrunk by 0.50 m '
                                      'in 8 s'), rig.server.text
    assert rig.stopped_at_end()


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
    with pytest.raises(ParamError, match='sensor_abort_timeout'):
        NavConfig(sensor_timeout=2.0, sensor_abort_timeout=1.0)


def test_node_params_read_every_name():
    from tiago_nav.params import ParamError, read_params
    p = read_params(navigation.Params, lambda n, d: {'~robot_radius': 0.3, '~max_vel_x': 0.5,
                                                     '~controller_frequency': 20}.get(n, d))
    assert p.nav.robot_radius == p.nav.controller.robot_radius == 0.3
    assert p.nav.controller.max_vel_x == 0.5 and p.controller_frequency == 20.0
    with pytest.raises(ParamError, match='inflation_radius'):
        read_params(navigation.Params, lambda n, d: {'~robot_radius': 0.9}.get(n, d))
