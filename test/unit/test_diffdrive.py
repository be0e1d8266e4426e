"""Differential-drive kinematics: exact arcs, speed and acceleration limits."""
import math

import pytest

from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive, integrate, limit_velocity


def test_straight_and_arc_integration():
    assert integrate((0, 0, 0), 1.0, 0.0, 2.0) == pytest.approx((2.0, 0.0, 0.0))
    # a quarter circle of radius 1
    x, y, th = integrate((0, 0, 0), 1.0, 1.0, math.pi / 2)
    assert (x, y, th) == pytest.approx((1.0, 1.0, math.pi / 2), abs=1e-9)
    # turning in place
    assert integrate((1, 2, 0), 0.0, -1.0, 1.0) == pytest.approx((1, 2, -1.0))


def test_speed_limits_clamp():
    lim = BaseLimits(max_linear_velocity=1.0, max_angular_velocity=1.5,
                     max_linear_acceleration=100, max_angular_acceleration=100)
    assert limit_velocity(3.0, -4.0, 0, 0, 1.0, lim) == (1.0, -1.5)


def test_acceleration_limits():
    lim = BaseLimits()
    v, w = limit_velocity(1.0, 1.5, 0.0, 0.0, 0.1, lim)
    assert v == pytest.approx(0.1) and w == pytest.approx(0.2)


def test_ramp_distance_under_acceleration():
    base = DiffDrive((0, 0, 0), BaseLimits(max_linear_velocity=1.0, max_linear_acceleration=1.0))
    dt = 1 / 60
    for _ in range(120):                       # 2 s: 1 s ramp to 1 m/s, then 1 s at 1 m/s
        base.step(5.0, 0.0, dt)
    assert base.v == pytest.approx(1.0)
    assert base.pose[0] == pytest.approx(0.5 + 1.0, abs=1e-6)


def test_bad_limits_rejected():
    with pytest.raises(ValueError, match='max_linear_velocity'):
        BaseLimits(max_linear_velocity=0)
