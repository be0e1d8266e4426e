"""The corridor_controller node's decisions (tiago_nav.corridor.server.CorridorServer) without
ROS: a fake clock and action server, and a fake robot with an ideal laser in generated corridor
worlds (tiago_nav_tools.testing.corridor.FakeCorridorRobot, FakeCorridorIO). The node's ROS
wiring: test_corridor_node.py."""
import math
from dataclasses import replace

import numpy as np
import pytest

from tiago_nav.corridor.inputs import wait_ready
from tiago_nav.corridor.server import CorridorServer, Params
from tiago_nav.params import ParamError
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.sim.worlds import corridor_world
from tiago_nav_tools.testing.corridor import FakeCorridorIO, FakeCorridorRobot
from tiago_nav_tools.testing.fakes import FakeActionServer, FakeClock

OPEN_FLOOR = {'name': 'open', 'resolution': 0.05, 'bounds': [-5, -5, 5, 5],
              'robot_start': [0, 0, 0],
              'walls': [{'x': 4.5, 'y': 0, 'length': 8, 'width': 0.2, 'yaw_deg': 90}]}


class Rig:
    """One goal of the server against a fake robot in ``world``."""

    def __init__(self, world, params=Params(), preempt_at=None, **robot):
        self.clock = FakeClock()
        self.server = FakeActionServer(self.clock, preempt_at)
        self.robot = FakeCorridorRobot(world, self.clock, **robot)
        self.io = FakeCorridorIO(self.robot, self.server)
        self.node = CorridorServer(params, self.clock, self.io)

    def at(self, t, action):
        """Call ``action()`` once, when the clock reaches ``t`` [s]."""
        done = []

        @self.clock.on_advance
        def hook(_):
            if not done and self.clock.now() >= t:
                done.append(t)
                action()

    def run(self, max_speed=0.0, max_distance=0.0):
        self.node.execute(max_speed, max_distance)
        assert self.server.state is not None, 'the goal did not end'
        return self.server

    def assert_stopped(self):
        """The base was told to stop last, and it stands still."""
        assert self.robot.commands and self.robot.commands[-1] == (0.0, 0.0)
        assert self.robot.speed == (0.0, 0.0)

    def blocked_since(self):
        """When the base was first commanded to stand still after it had driven [s]."""
        driven = False
        for t, _, _, _, v in self.robot.track:
            driven = driven or v > 0.05
            if driven and v == 0.0:
                return t
        return None


def test_done_succeeds_with_the_exit_pose():
    rig = Rig(corridor_world(1.07, 4.0, start=(-0.8, 0.05, 5.0)))
    server = rig.run()
    assert server.state == 'succeeded', server.text
    assert server.text == server.result.reason == 'reached the end of the corridor'
    x, y, yaw = rig.robot.pose
    assert 4.0 + 0.1 < x < 4.0 + 0.7 and abs(y) < 0.05 and abs(yaw) < math.radians(5)
    frame, pose, stamp = server.result.exit_pose
    assert frame == 'map' and stamp == rig.clock.now()
    assert pose[:2] == pytest.approx((x, y), abs=0.005)
    assert server.result.distance == pytest.approx(math.hypot(x + 0.8, y - 0.05), abs=0.02)
    assert len(server.feedback) > 20 and server.feedback[-1].distance > 3.0
    rig.assert_stopped()


@pytest.mark.parametrize('blocked_timeout', [1.0, 3.0])
def test_blocked_past_blocked_timeout_aborts(blocked_timeout):
    params = replace(Params(), blocked_timeout=blocked_timeout)
    rig = Rig(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0), obstacle=(2.5, 0.0, 0.2)), params)
    server = rig.run()
    assert server.state == 'aborted' and server.text.startswith('blocked ahead'), server.text
    gap = 2.5 - 0.2 - ROBOT_RADIUS - rig.robot.pose[0]
    assert 0.0 < gap < 0.2
    # it waited blocked_timeout for the way to clear, then gave up
    waited = rig.clock.now() - rig.blocked_since()
    assert blocked_timeout < waited < blocked_timeout + 1.0
    rig.assert_stopped()


def test_failed_aborts_with_its_reason_without_moving():
    rig = Rig(OPEN_FLOOR)
    server = rig.run()
    assert server.state == 'aborted' and server.text.startswith('no corridor ahead within 3.0 m')
    assert server.result.reason == server.text
    assert math.hypot(*rig.robot.pose[:2]) < 1e-6
    rig.assert_stopped()


def test_cancel_preempts_and_stops():
    rig = Rig(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0)), preempt_at=2.0)
    server = rig.run()
    assert server.state == 'preempted' and server.text == 'cancelled'
    assert 0.5 < rig.robot.pose[0] < 3.0                 # it was driving when cancelled
    # the distance includes the braking after the cancel
    assert server.result.distance == pytest.approx(rig.robot.pose[0] + 0.5, abs=0.02)
    rig.assert_stopped()


DEAD = 'the connection to /simulator, which publishes /clock, is closed (did it die?)'


def test_a_dead_clock_aborts_naming_the_reason():
    rig = Rig(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0)))
    rig.at(1.5, lambda: (setattr(rig.clock, 'stalled', True), setattr(rig.clock, 'dead', DEAD)))
    server = rig.run()
    assert server.state == 'aborted' and server.text.startswith('ROS time stopped'), server.text
    assert server.text.endswith(DEAD), server.text
    assert rig.robot.commands[-1] == (0.0, 0.0)


def test_a_slow_clock_is_waited_for():
    """ROS time stands still for 60 s of wall time while its source lives (a starved
    simulator): the goal goes on when time moves again and ends as without the stall."""
    def run(stall):
        rig = Rig(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0)))
        if stall:
            rig.at(1.5, lambda: (setattr(rig.clock, 'stalled', True),
                                 setattr(rig.clock, 'resume_at', rig.clock.wall() + 60.0)))
        return rig, rig.run()
    rig, server = run(True)
    _, calm = run(False)
    assert rig.clock.wall() - rig.clock.now() >= 59.9       # it did stand still that long
    assert rig.clock.asked >= 10                            # and asked whether it was dead
    assert server.state == 'succeeded' == calm.state, server.text
    assert server.text == calm.text
    assert server.result.distance == pytest.approx(calm.result.distance, abs=1e-6)


def test_goal_timeout_aborts():
    rig = Rig(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0)), replace(Params(), timeout=2.0))
    server = rig.run(max_speed=0.3)
    assert server.state == 'aborted' and server.text == 'timeout after 2 s'
    assert 2.0 <= rig.clock.now() < 5.0
    rig.assert_stopped()


def test_no_tf_aborts_with_the_tf_error():
    rig = Rig(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0)))
    rig.robot.tf_ok = False
    server = rig.run()
    assert server.state == 'aborted'
    assert 'tf' in server.text and '"odom"' in server.text, server.text
    assert rig.clock.now() < 1.0 + 2.0 + 0.5          # scan_timeout, then the stop wait
    assert server.result.exit_pose is None                        # no pose to report
    assert rig.robot.commands[-1][0] == 0.0


def test_invalid_goal_aborts_at_once():
    rig = Rig(corridor_world(1.07, 5.0))
    server = rig.run(max_speed=float('nan'))
    assert server.state == 'aborted' and server.text.startswith('invalid goal')
    rig.assert_stopped()


# --- every failure is loud ------------------------------------------------------------------------

def test_stale_scan_stops_the_base_then_aborts():
    rig = Rig(corridor_world(1.07, 6.0, start=(-0.5, 0.0, 0.0)))
    p = Params()
    rig.at(2.0, lambda: setattr(rig.robot, 'laser_on', False))
    server = rig.run()
    assert server.state == 'aborted' and server.text.startswith('no laser data for 1.'), server.text
    last_scan = rig.robot.scan.stamp
    stopped = next(t for t, _, _, _, v in rig.robot.track if t > last_scan and v == 0.0)
    # held still once the newest scan was older than sensor_timeout (within a control period)
    assert p.sensor_timeout < stopped - last_scan < p.sensor_timeout + 1.5 / p.control_rate
    rig.assert_stopped()


def test_a_short_sensor_gap_stops_the_base_and_then_goes_on():
    rig = Rig(corridor_world(1.07, 4.0, start=(-0.5, 0.0, 0.0)))

    @rig.clock.on_advance
    def gap(_):
        rig.robot.laser_on = not 2.0 <= rig.clock.now() < 2.8      # 0.8 s without scans
    server = rig.run()
    assert server.state == 'succeeded', server.text
    during = [v for t, _, _, _, v in rig.robot.track if 2.0 + 0.6 < t < 2.8]
    assert during and max(during) == 0.0                          # held still while blind


@pytest.mark.parametrize('corrupt', [
    lambda r: np.full_like(r, np.nan),                              # all invalid
    lambda r: np.zeros(0),                                          # empty
    lambda r: np.where(np.arange(r.size) % 5 == 0, r, np.nan),      # 80 % invalid
    lambda r: np.where(np.abs(np.arange(r.size) - r.size / 2) < 150, np.nan, r),   # blind ahead
], ids=['all-nan', 'empty', 'mostly-nan', 'front-nan'])
def test_an_unusable_scan_is_blocked_never_free(corrupt):
    rig = Rig(corridor_world(1.07, 6.0, start=(-0.5, 0.0, 0.0)))
    since = []
    rig.at(2.0, lambda: (setattr(rig.robot, 'corrupt', corrupt),
                         since.append((rig.clock.now(), rig.robot.pose[0]))))
    server = rig.run()
    assert server.state == 'aborted', server.text
    assert server.text.startswith('blocked: the laser scan is unusable'), server.text
    t0, x0 = since[0]
    assert all(math.isfinite(f.left_distance) for f in server.feedback)     # no NaN sent out
    # it stopped instead of driving on: braking from <= 1 m/s at 1 m/s^2 within one scan period
    assert rig.robot.pose[0] - x0 < 0.5 + 1.0 / 15
    assert rig.clock.now() - t0 > Params().blocked_timeout
    rig.assert_stopped()


def test_too_close_beams_ahead_block_but_nan_beams_do_not():
    def front(value):
        return lambda r: np.where(np.abs(np.arange(r.size) - r.size / 2) < 5, value, r)
    for value, state in ((-np.inf, 'aborted'), (np.nan, 'succeeded')):
        rig = Rig(corridor_world(1.07, 4.0, start=(-0.5, 0.0, 0.0)), corrupt=front(value))
        server = rig.run()
        assert server.state == state, (value, server.text)
        if state == 'aborted':
            assert server.text.startswith('blocked ahead'), server.text
            assert abs(rig.robot.pose[0] - (-0.5)) < 1e-6               # never moved
        rig.assert_stopped()


def test_an_unexpected_error_stops_the_base_and_aborts_with_its_text():
    rig = Rig(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0)))
    lookup = rig.robot.lookup

    def broken(*args, **kw):
        if rig.clock.now() > 1.5:
            raise RuntimeError('boom')
        return lookup(*args, **kw)
    rig.robot.lookup = broken
    server = rig.run()
    assert server.state == 'aborted' and server.text == 'RuntimeError: boom'
    assert server.result.reason == 'RuntimeError: boom'
    assert rig.robot.commands[-1] == (0.0, 0.0)


def test_ready_only_with_a_scan_and_the_tf():
    clock = FakeClock()
    robot = FakeCorridorRobot(corridor_world(1.07, 5.0), clock)
    p = Params()
    assert wait_ready(p, clock, robot, 5.0) == ''
    robot.scan, robot.laser_on = None, False
    assert wait_ready(p, clock, robot, 5.0) == 'no laser scan on /scan within 5 s'
    assert clock.wall() >= 5.0
    robot.laser_on, robot.tf_ok = True, False
    missing = wait_ready(p, clock, robot, 5.0)
    assert missing.startswith('no tf odom -> base_footprint') and missing.endswith('within 5 s')
    # what arrives late is waited for
    robot.scan, robot.laser_on, robot.tf_ok = None, False, True

    @clock.on_advance
    def laser_starts(_):
        robot.laser_on = robot.laser_on or clock.now() > 12.0
    assert wait_ready(p, clock, robot, 5.0) == ''


def test_scan_timeout_must_exceed_sensor_timeout():
    with pytest.raises(ParamError, match='scan_timeout'):
        Params(sensor_timeout=1.0, scan_timeout=0.8)


def test_a_run_time_change_comes_in_force_at_the_next_cycle():
    """A speed_limit change (dynamic_reconfigure) requested inside a cycle, before its command is
    computed: that cycle's command still uses the old limit, every later one the new."""
    rig = Rig(corridor_world(1.07, 8.0, start=(-0.5, 0.0, 0.0)))
    sent, asked = [], []
    command, latest_scan = rig.robot.command, rig.robot.latest_scan

    def record(v, w):
        sent.append((rig.clock.now(), v))
        command(v, w)

    def scan_then_change():
        if not asked and rig.clock.now() >= 2.5:
            asked.append(rig.clock.now())
            rig.node.changes.request({'speed_limit': 0.3})
            assert rig.node.p.law.speed_limit == 1.0          # not within this cycle
        return latest_scan()
    rig.robot.command, rig.robot.latest_scan = record, scan_then_change
    server = rig.run()
    assert server.state == 'succeeded', server.text
    t0 = asked[0]
    assert [v for t, v in sent if t == t0][0] > 0.8            # the old limit in that cycle
    later = [v for t, v in sent if t > t0]
    assert later and max(later) <= 0.3 + 1e-9 and max(later) > 0.25
    assert rig.node.p.law.speed_limit == 0.3                   # in force after the goal too
