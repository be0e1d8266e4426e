"""The simulator library without ROS: commands move the base, time-outs stop it, walls stop it
and count one collision, the start pose is checked."""
import math

import numpy as np
import pytest

from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import World

ROOM = {
    'name': 'room', 'resolution': 0.05, 'bounds': [-1, -2, 5, 2], 'robot_start': [0, 0, 0],
    'walls': [{'x': 3.0, 'y': 0, 'length': 4.0, 'width': 0.2, 'yaw_deg': 90}],   # face at x = 2.9
}


@pytest.fixture
def sim():
    s = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.0))
    yield s
    s.close()


def run(sim, seconds, v=None, w=0.0):
    for _ in range(int(round(seconds * sim.config.rate))):
        if v is not None:
            sim.command(v, w)
        sim.step()


def test_commanded_velocity_moves_the_base(sim):
    run(sim, 2.0, v=0.5)
    # 0.5 s ramp at 1 m/s^2 covers 0.125 m, then 1.5 s at 0.5 m/s
    assert sim.pose[0] == pytest.approx(0.125 + 0.75, abs=1e-3)
    assert sim.velocity[0] == pytest.approx(0.5)
    assert sim.collisions == 0


def test_turning(sim):
    run(sim, 3.0, v=0.0, w=1.0)
    # 0.5 s ramp at 2 rad/s^2 covers 0.25 rad, then 2.5 s at 1 rad/s
    assert sim.pose[2] == pytest.approx(2.75 - 2 * math.pi + 2 * math.pi, abs=1e-3)
    assert sim.pose[:2] == pytest.approx((0, 0), abs=1e-9)


def test_command_timeout_stops_the_base(sim):
    sim.command(0.5, 0.0)
    run(sim, 2.0)                                 # the command is not repeated
    x = sim.pose[0]
    assert sim.velocity == (0.0, 0.0)
    assert 0.2 < x < 0.5                          # moved for 0.5 s, then braked to a stop
    run(sim, 1.0)
    assert sim.pose[0] == x


def test_wall_blocks_and_counts_one_collision(sim):
    run(sim, 6.0, v=1.0)
    # the base (radius 0.27) stops at the wall face x = 2.9, and does not go through
    assert 2.9 - 0.27 - 0.05 < sim.pose[0] <= 2.9 - 0.27 + 1e-3
    assert sim.collisions == 1
    run(sim, 1.0, v=1.0)                          # still pushing: the same contact
    assert sim.collisions == 1
    run(sim, 1.0, v=-0.3)                         # back off, then hit it again
    run(sim, 2.0, v=0.5)
    assert sim.collisions == 2


def test_scan_sees_the_wall(sim):
    r = sim.scan()
    assert r.size == 666
    assert r[333] == pytest.approx(2.7, abs=0.01)
    run(sim, 1.0, v=0.5)
    assert sim.scan()[333] == pytest.approx(2.9 - 0.2 - sim.pose[0], abs=0.01)


def test_odometry_is_relative_to_the_start():
    world = World.from_dict(dict(ROOM, robot_start=[1.0, 1.0, 90]))
    with_sim = Simulator(world, SimConfig(laser_noise=0.0))
    try:
        run(with_sim, 1.0, v=0.5)
        ox, oy, oth = with_sim.odom_pose
        assert oy == pytest.approx(0.0, abs=1e-9) and oth == pytest.approx(0.0, abs=1e-9)
        assert ox == pytest.approx(with_sim.pose[1] - 1.0, abs=1e-9)
        assert with_sim.map_to_odom == pytest.approx((1.0, 1.0, math.pi / 2))
    finally:
        with_sim.close()


def test_start_inside_an_obstacle_is_refused():
    with pytest.raises(ValueError, match='overlaps an obstacle'):
        Simulator(World.from_dict(dict(ROOM, robot_start=[2.9, 0, 0])))


def test_config_checks():
    with pytest.raises(ValueError, match='scan_rate'):
        SimConfig(rate=60, scan_rate=14)
    with pytest.raises(ValueError, match='laser_noise'):
        SimConfig(laser_noise=-0.1)


def test_noise_is_seeded():
    a = Simulator(World.from_dict(ROOM), SimConfig(seed=3))
    b = Simulator(World.from_dict(ROOM), SimConfig(seed=3))
    try:
        np.testing.assert_array_equal(a.scan(), b.scan())
    finally:
        a.close()
        b.close()


def test_commands_differing_in_the_last_bits_drive_exactly_the_same_path():
    """Commands are rounded to ``cmd_resolution``: the controllers' last-bit floating-point
    differences between runs (numpy/BLAS reductions) do not reach the robot's path, so lockstep
    runs repeat to the bit. With ``cmd_resolution`` 0 they did."""
    def path(resolution, eps):
        s = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.0,
                                                       cmd_resolution=resolution))
        try:
            for i in range(120):
                s.command(0.4 + 1e-4 * i + eps, 0.2 - 1e-4 * i - eps)
                s.step()
            return s.pose
        finally:
            s.close()
    assert path(1e-6, 0.0) == path(1e-6, 2e-16)          # the same doubles
    assert path(0.0, 0.0) != path(0.0, 2e-16)


def test_command_resolution_rounds_the_command():
    s = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.0, cmd_resolution=0.001))
    try:
        s.command(0.12345, -0.06789)
        assert s._cmd == pytest.approx((0.123, -0.068), abs=1e-12)
    finally:
        s.close()
