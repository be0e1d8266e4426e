"""Odometry: ``ideal`` is exact (nothing changes), ``drift`` drifts from the truth at the rate its
parameters document (over seeds), whatever the step size, and the ground-truth map → odom
always closes the loop: map → odom → base_footprint is the true pose."""
import math
from dataclasses import replace

import numpy as np
import pytest

from tiago_nav.geometry import compose, inverse, wrap_angle
from tiago_nav.params import ParamError
from tiago_nav.sim.odometry import Odometry, OdometryNoise
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import World

ROOM = {
    'name': 'room', 'resolution': 0.05, 'bounds': [-6, -6, 6, 6], 'robot_start': [-1, 0.5, 0.3],
    'walls': [{'x': 5.5, 'y': 0, 'length': 11.0, 'width': 0.2, 'yaw_deg': 90}],
}
NO_NOISE = OdometryNoise(distance_scale_error=0, rotation_scale_error=0, dist_per_metre=0,
                         dist_per_rad=0, rot_per_rad=0, rot_per_metre=0)
START = (1.0, -2.0, 0.5)
SEEDS = 400


def drive(noise, seed, path, step):
    """Drive ``path`` (a list of ``(distance [m], rotation [rad])`` legs, each as a constant-
    curvature arc) in steps of ``step`` [m or rad]; returns the odometry error
    ``(along [m], across [m], yaw [rad])`` in the true final pose's frame."""
    odo = Odometry(noise, START, np.random.default_rng(seed))
    pose = START
    for dist, rot in path:
        n = max(1, int(round(max(abs(dist), abs(rot)) / step)))
        for _ in range(n):
            ds, da = dist / n, rot / n
            chord = ds if da == 0 else 2 * ds / da * math.sin(da / 2)
            new = compose(pose, (chord * math.cos(da / 2), chord * math.sin(da / 2), da))
            odo.advance(pose, new)
            pose = new
    est = compose(START, odo.odom_pose(pose))
    ex, ey, eyaw = compose(inverse(pose), est)
    return ex, ey, wrap_angle(eyaw)


def errors(noise, path, step=0.05, seeds=SEEDS):
    return np.array([drive(noise, s, path, step) for s in range(seeds)])


def test_ideal_odometry_is_the_true_pose_from_the_start():
    odo = Odometry(OdometryNoise(odometry_model='ideal'), START, np.random.default_rng(0))
    pose = (3.0, 1.0, -2.0)
    odo.advance(START, pose)
    assert odo.odom_pose(pose) == compose(inverse(START), pose)
    assert odo.map_to_odom(pose) == START


def test_drift_without_noise_integrates_the_truth():
    e = drive(NO_NOISE, 0, [(3.0, 0.0), (2.0, 1.5), (0.0, -2.0), (-1.0, 0.0)], 0.01)
    np.testing.assert_allclose(e, 0.0, atol=1e-9)


def test_random_distance_error_grows_with_the_square_root_of_distance():
    noise = replace(NO_NOISE, dist_per_metre=0.01)
    for dist in (4.0, 16.0):
        along = errors(noise, [(dist, 0.0)])[:, 0]
        assert along.std() == pytest.approx(0.01 * math.sqrt(dist), rel=0.12)
        assert abs(along.mean()) < 4 * 0.01 * math.sqrt(dist / SEEDS)


def test_random_error_does_not_depend_on_the_step_size():
    noise = replace(NO_NOISE, dist_per_metre=0.01, rot_per_metre=0.005)
    fine = errors(noise, [(4.0, 0.0)], step=0.01)
    coarse = errors(noise, [(4.0, 0.0)], step=0.2)
    assert fine[:, 0].std() == pytest.approx(coarse[:, 0].std(), rel=0.15)
    assert fine[:, 2].std() == pytest.approx(coarse[:, 2].std(), rel=0.15)
    assert fine[:, 2].std() == pytest.approx(0.005 * 2.0, rel=0.12)


def test_systematic_scale_errors_grow_in_proportion_to_distance_and_rotation():
    along = errors(replace(NO_NOISE, distance_scale_error=0.01), [(10.0, 0.0)], step=0.05)[:, 0]
    assert along.std() == pytest.approx(0.01 * 10.0, rel=0.12)
    yaw = errors(replace(NO_NOISE, rotation_scale_error=0.01), [(0.0, 2 * math.pi)], step=0.05)[:, 2]
    assert yaw.std() == pytest.approx(0.01 * 2 * math.pi, rel=0.12)


def test_rotation_noise_grows_with_rotation():
    yaw = errors(replace(NO_NOISE, rot_per_rad=0.02), [(0.0, 4 * math.pi)], step=0.05)[:, 2]
    assert yaw.std() == pytest.approx(0.02 * math.sqrt(4 * math.pi), rel=0.12)


def test_default_drift_heading_error_makes_lateral_error_grow_with_distance():
    short = errors(OdometryNoise(), [(2.0, 0.0)], step=0.05, seeds=200)
    long = errors(OdometryNoise(), [(8.0, 0.0)], step=0.05, seeds=200)
    assert np.abs(long[:, 1]).mean() > 3 * np.abs(short[:, 1]).mean()
    assert np.abs(long[:, 0]).mean() > 2 * np.abs(short[:, 0]).mean()


def test_bad_parameters_are_refused_naming_the_parameter():
    with pytest.raises(ParamError, match='odometry_model'):
        OdometryNoise(odometry_model='perfect')
    with pytest.raises(ParamError, match='dist_per_metre'):
        OdometryNoise(dist_per_metre=-0.1)


# --- in the simulator -----------------------------------------------------------------------------
def run(sim, seconds, v, w):
    for _ in range(int(round(seconds * sim.config.rate))):
        sim.command(v, w)
        sim.step()


def test_simulator_with_ideal_odometry_is_unchanged():
    sim = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.0))
    try:
        run(sim, 3.0, 0.4, 0.5)
        start = World.from_dict(ROOM).start_pose
        assert sim.map_to_odom == start
        assert sim.odom_pose == compose(inverse(start), sim.pose)
    finally:
        sim.close()


def test_simulator_odometry_drifts_and_map_to_odom_closes_the_loop():
    sim = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.0, odometry=OdometryNoise()))
    try:
        run(sim, 6.0, 0.5, 0.3)
        truth = sim.pose
        assert math.hypot(truth[0] + 1, truth[1] - 0.5) > 1.5
        naive = compose(World.from_dict(ROOM).start_pose, sim.odom_pose)
        assert math.hypot(naive[0] - truth[0], naive[1] - truth[1]) > 1e-3   # it drifted
        closed = compose(sim.map_to_odom, sim.odom_pose)
        np.testing.assert_allclose(closed[:2], truth[:2], atol=1e-12)
        assert wrap_angle(closed[2] - truth[2]) == pytest.approx(0.0, abs=1e-12)
        # the laser's draws do not depend on the odometry model
        ideal = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.01))
        drift = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.01, odometry=OdometryNoise()))
        np.testing.assert_array_equal(ideal.scan(), drift.scan())
        ideal.close()
        drift.close()
    finally:
        sim.close()


def test_a_standing_base_adds_no_drift():
    """The relative motion of a pose to itself is not exactly zero in floating point (about
    10⁻¹⁶ m); with drift its noise moved a standing robot's odometry by about 10⁻¹⁰ m per step,
    and how long the robot stood (a free-running detection call) changed every later pose."""
    pose = (11.005442059344205, 0.0008226933250628158, -0.808669033333338)
    assert compose(inverse(pose), pose) != (0.0, 0.0, 0.0)
    odo = Odometry(OdometryNoise(), START, np.random.default_rng(0))
    before = odo.odom_pose(pose)
    for _ in range(1000):
        odo.advance(pose, pose)
    assert odo.odom_pose(pose) == before
    odo.advance(pose, compose(pose, (0.01, 0.0, 0.0)))
    assert odo.odom_pose(pose) != before                 # moving still drifts
