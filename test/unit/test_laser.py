"""The pybullet laser: ranges match exact geometry, beams never pass through walls, noise is
as configured, and the in-view ground truth counts beams per movable obstacle."""
import math

import numpy as np
import pytest

from tiago_nav.sim.scene import LaserConfig, Scene, noisy
from tiago_nav.sim.world import World
from tiago_nav_tools.evaluate.inview import view_from

BOX = {
    'name': 'box', 'resolution': 0.05, 'bounds': [-5, -5, 5, 5], 'robot_start': [0, 0, 0],
    'walls': [{'x': 3.0, 'y': 0, 'length': 8.0, 'width': 0.2, 'yaw_deg': 90},     # face at x = 2.9
              {'x': -3.0, 'y': 0, 'length': 8.0, 'width': 0.2, 'yaw_deg': 90},
              {'x': 0, 'y': 3.0, 'length': 8.0, 'width': 0.2},                      # face at y = 2.9
              {'x': 0, 'y': -3.0, 'length': 8.0, 'width': 0.2}],
}


@pytest.fixture
def scene():
    with Scene(World.from_dict(BOX)) as s:
        yield s


def test_config_is_tiago_like():
    c = LaserConfig()
    a = c.angles()
    assert a.size == 666
    assert math.degrees(a[0]) == pytest.approx(-110) and math.degrees(a[-1]) == pytest.approx(110)
    assert a[1] - a[0] == pytest.approx(c.angle_increment)
    assert (c.range_min, c.range_max) == (0.05, 25.0)


def test_forward_beam_measures_wall_distance(scene):
    ranges, ids = scene.cast((0.0, 0.0, 0.0))
    mid = 333  # beams 332/333 straddle 0 rad; beam 333 is 0.0029 rad left
    angle = LaserConfig().angles()[mid]
    # laser at x = 0.2: the wall face at x = 2.9 is 2.7 m ahead along the beam
    assert ranges[mid] == pytest.approx(2.7 / math.cos(angle), abs=1e-3)
    assert ids[mid] == scene.static_id


def test_every_beam_matches_exact_box_geometry(scene):
    pose = (0.7, -0.4, 0.6)
    ranges, _ = scene.cast(pose)
    lx, ly, lyaw = scene.laser_pose(pose)
    ang = lyaw + LaserConfig().angles()
    c, s = np.cos(ang), np.sin(ang)
    with np.errstate(divide='ignore'):
        tx = np.where(c > 0, (2.9 - lx) / c, (-2.9 - lx) / c)
        ty = np.where(s > 0, (2.9 - ly) / s, (-2.9 - ly) / s)
    expected = np.minimum(np.abs(tx), np.abs(ty))
    assert np.all(np.isfinite(ranges))
    np.testing.assert_allclose(ranges, expected, atol=2e-3)


def test_beams_never_pass_through_walls(scene):
    rng = np.random.default_rng(1)
    for _ in range(20):
        pose = (rng.uniform(-2.3, 2.3), rng.uniform(-2.3, 2.3), rng.uniform(-math.pi, math.pi))
        ranges, _ = scene.cast(pose)
        lx, ly, lyaw = scene.laser_pose(pose)
        ang = lyaw + LaserConfig().angles()
        hx, hy = lx + ranges * np.cos(ang), ly + ranges * np.sin(ang)
        assert np.all(np.abs(hx) <= 2.9 + 1e-3) and np.all(np.abs(hy) <= 2.9 + 1e-3)


def test_open_space_reads_inf():
    open_world = dict(BOX, walls=[{'x': 3.0, 'y': 0, 'length': 1.0, 'width': 0.2, 'yaw_deg': 90}])
    with Scene(World.from_dict(open_world)) as s:
        ranges, ids = s.cast((0, 0, 0))
        assert np.isinf(ranges[0]) and ids[0] == -1        # beam at -110 deg sees nothing
        assert np.isfinite(ranges[333])


def test_cylinder_range_and_visibility():
    w = dict(BOX, movable_obstacles=[{'x': 2.0, 'y': 0.0, 'radius': 0.2},
                                     {'x': -2.0, 'y': 0.0, 'radius': 0.2}])  # behind the robot
    with Scene(World.from_dict(w)) as s:
        ranges, ids = s.cast((0, 0, 0))
        # front of the cylinder: 2.0 - 0.2 - 0.2 (laser offset) = 1.6 m
        assert ranges[333] == pytest.approx(1.6, abs=2e-3)
        assert ids[333] == s.movable_ids[0]
        assert view_from(s, (0, 0, 0)).in_view == [0]
        assert view_from(s, (0, 0, math.pi)).in_view == [1]


def test_noise_statistics_and_limits():
    rng = np.random.default_rng(0)
    clean = np.full(20000, 3.0)
    r = noisy(clean, 0.01, rng, 0.05, 25.0)
    assert np.std(r - 3.0) == pytest.approx(0.01, rel=0.05)
    assert abs(np.mean(r - 3.0)) < 1e-3
    edge = noisy(np.array([0.04, 24.999, np.inf, 25.5]), 0.0, rng, 0.05, 25.0)
    assert edge[0] == -np.inf                            # too close to measure
    assert edge[1] == pytest.approx(24.999)
    assert edge[2] == np.inf and edge[3] == np.inf       # nothing within range_max


def test_noise_out_of_the_limits_follows_rep117():
    rng = np.random.default_rng(2)
    near = noisy(np.full(20000, 0.06), 0.05, rng, 0.05, 25.0)      # 0.2 sigma above range_min
    far = noisy(np.full(20000, 24.99), 0.05, rng, 0.05, 25.0)      # 0.2 sigma below range_max
    too_close = near == -np.inf
    assert np.mean(too_close) == pytest.approx(0.42, abs=0.02)     # P(z < -0.2)
    assert np.all((near[~too_close] >= 0.05) & np.isfinite(near[~too_close]))
    no_return = far == np.inf
    assert np.mean(no_return) == pytest.approx(0.42, abs=0.02)
    assert np.all(far[~no_return] <= 25.0)
    # a true range below range_min reads -inf even when the noise would lift it above
    assert np.all(noisy(np.full(1000, 0.049), 0.5, rng, 0.05, 25.0) == -np.inf)
