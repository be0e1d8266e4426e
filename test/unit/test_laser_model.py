"""Laser model profiles: ``ideal`` is today's laser bit for bit; each effect of ``tiago``
(self-hits, mixed pixels, noise, quantisation, dropouts) has the statistics its parameters
say; the consumers' self-filter drops every self-hit and no wall hit."""
import math
import os
from dataclasses import replace

import numpy as np
import pytest

from tiago_nav.params import ParamError
from tiago_nav.robot import LASER_OFFSET, ROBOT_RADIUS
from tiago_nav.scan import BODY_MARGIN, body_returns
from tiago_nav.sim.laser import (DROPOUT, EXACT, MIXED, SELF_HIT, LaserModel, body_ranges,
                                 incidence_angles)
from tiago_nav.sim.scene import LaserConfig, Scene, noisy
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import World, load_world

LASER = LaserConfig()
ANGLES = LASER.angles()
# tiago with every random effect off: what is left is deterministic geometry
QUIET = LaserModel(mixed_pixel_probability=0.0, dropout_rate=0.0, grazing_dropout_rate=0.0,
                   range_resolution=0.0)
BOX = {
    'name': 'box', 'resolution': 0.05, 'bounds': [-5, -5, 5, 5], 'robot_start': [0, 0, 0],
    'walls': [{'x': 3.0, 'y': 0, 'length': 8.0, 'width': 0.2, 'yaw_deg': 90},     # face at x = 2.9
              {'x': -3.0, 'y': 0, 'length': 8.0, 'width': 0.2, 'yaw_deg': 90},
              {'x': 0, 'y': 3.0, 'length': 8.0, 'width': 0.2},
              {'x': 0, 'y': -3.0, 'length': 8.0, 'width': 0.2}],
    # a post 1.5 m ahead of the laser, well in front of the wall: two depth edges
    'movable_obstacles': [{'x': 1.7, 'y': 0.0, 'radius': 0.2}],
}
COURSE = os.path.join(os.path.dirname(__file__), '..', '..', 'worlds', 'ias_lab_room_full.yaml')


@pytest.fixture(scope='module')
def box_cast():
    with Scene(World.from_dict(BOX)) as s:
        ranges, _ = s.cast((0.0, 0.0, 0.0))
    return ranges


def wall_ranges(distance):
    """Exact ranges from the laser to an infinite wall ``distance`` ahead (x = distance)."""
    with np.errstate(divide='ignore'):
        return np.where(np.cos(ANGLES) > 1e-9, distance / np.cos(ANGLES), np.inf)


# --- ideal ------------------------------------------------------------------------------------
def test_ideal_is_the_exact_cast_plus_gaussian_noise_bit_for_bit(box_cast):
    got = LaserModel(laser_model='ideal').apply(box_cast, LASER, 0.01, np.random.default_rng(7))
    want = noisy(box_cast, 0.01, np.random.default_rng(7), LASER.range_min, LASER.range_max)
    np.testing.assert_array_equal(got.ranges, want)
    assert not got.effect.any()


def test_simulator_scan_with_the_ideal_model_is_unchanged():
    world = World.from_dict(BOX)
    sim = Simulator(world, SimConfig(seed=5))
    try:
        rng = np.random.default_rng(5)
        for _ in range(3):
            want = noisy(sim.scene.cast()[0], 0.01, rng, LASER.range_min, LASER.range_max)
            np.testing.assert_array_equal(sim.scan(), want)
    finally:
        sim.close()


def test_tiago_is_reproducible_from_the_seed(box_cast):
    a = LaserModel().apply(box_cast, LASER, 0.01, np.random.default_rng(3)).ranges
    b = LaserModel().apply(box_cast, LASER, 0.01, np.random.default_rng(3)).ranges
    np.testing.assert_array_equal(a, b)


def test_bad_parameters_are_refused_naming_the_parameter():
    with pytest.raises(ParamError, match='laser_model'):
        LaserModel(laser_model='sick')
    with pytest.raises(ParamError, match='grazing_dropout_rate'):
        LaserModel(dropout_rate=0.1, grazing_dropout_rate=0.01)


# --- self-hits ----------------------------------------------------------------------------------
def test_twenty_beams_at_each_end_hit_the_body_at_the_shell(box_cast):
    out = QUIET.apply(box_cast, LASER, 0.0, np.random.default_rng(0))
    self_hit = out.effect == SELF_HIT
    assert np.flatnonzero(self_hit).tolist() == list(range(20)) + list(range(646, 666))
    r = out.ranges[self_hit]
    a = ANGLES[self_hit]
    # each return lies on the base's shell: ROBOT_RADIUS from base_footprint's origin
    dist = np.hypot(LASER_OFFSET + r * np.cos(a), r * np.sin(a))
    np.testing.assert_allclose(dist, ROBOT_RADIUS, atol=1e-9)
    assert np.all((r > 0.2) & (r < 0.3))
    np.testing.assert_array_equal(out.ranges[~self_hit], box_cast[~self_hit])


def test_self_hits_follow_the_geometry_not_a_beam_count():
    wide = replace(LASER, num_beams=1000)
    r = body_ranges(wide.angles(), wide.offset, ROBOT_RADIUS, math.radians(103.5))
    per_degree = (wide.num_beams - 1) / 220.0
    assert int(np.isfinite(r).sum()) == pytest.approx(2 * 6.5 * per_degree, abs=2)


# --- mixed pixels -----------------------------------------------------------------------------
def edges_of(exact, min_jump):
    """Indices i where beams i and i + 1 see surfaces more than ``min_jump`` apart."""
    near, far = np.minimum(exact[:-1], exact[1:]), np.maximum(exact[:-1], exact[1:])
    return np.flatnonzero(np.isfinite(far) & (far - near > min_jump))


def test_mixed_pixels_lie_between_the_near_and_far_surface(box_cast):
    model = replace(QUIET, mixed_pixel_probability=1.0)
    exact = QUIET.apply(box_cast, LASER, 0.0, np.random.default_rng(0)).ranges  # world + body
    edges = edges_of(exact, model.mixed_pixel_min_jump)
    assert len(edges) == 4          # the post's two sides and the two body/wall transitions
    out = model.apply(box_cast, LASER, 0.0, np.random.default_rng(1))
    mixed = np.flatnonzero(out.effect == MIXED)
    assert len(mixed) == len(edges)
    for i, m in zip(edges, mixed):
        assert m in (i, i + 1)
        lo, hi = sorted((exact[i], exact[i + 1]))
        assert lo < out.ranges[m] < hi
    others = out.effect != MIXED
    np.testing.assert_array_equal(out.ranges[others], exact[others])


def test_mixed_pixel_rate_matches_its_probability(box_cast):
    model = replace(QUIET, mixed_pixel_probability=0.3)
    rng = np.random.default_rng(2)
    n = 2000
    count = sum(int((model.apply(box_cast, LASER, 0.0, rng).effect == MIXED).sum()) for _ in range(n))
    rate = count / (4.0 * n)
    assert rate == pytest.approx(0.3, abs=4 * math.sqrt(0.3 * 0.7 / (4 * n)))


# --- noise and quantisation --------------------------------------------------------------------
def test_ranges_are_quantised_to_the_resolution(box_cast):
    out = LaserModel().apply(box_cast, LASER, 0.01, np.random.default_rng(4)).ranges
    finite = out[np.isfinite(out)]
    assert finite.size > 600
    np.testing.assert_allclose(finite * 1000.0, np.round(finite * 1000.0), atol=1e-6)
    assert len(np.unique(np.round(finite * 1000.0))) > 100      # not all on one value


def test_range_proportional_noise_grows_with_range():
    model = replace(QUIET, noise_per_metre=0.01)
    exact = np.full(666, np.inf)
    exact[200:300], exact[400:500] = 2.0, 10.0
    rng = np.random.default_rng(5)
    r = np.array([model.apply(exact, LASER, 0.005, rng).ranges for _ in range(300)])
    near, far = r[:, 200:300] - 2.0, r[:, 400:500] - 10.0
    assert near.std() == pytest.approx(math.hypot(0.005, 0.02), rel=0.05)
    assert far.std() == pytest.approx(math.hypot(0.005, 0.10), rel=0.05)


# --- dropouts -----------------------------------------------------------------------------------
def test_incidence_angle_from_neighbouring_beams_on_a_flat_wall():
    exact = wall_ranges(2.0)
    inc = incidence_angles(exact, ANGLES)
    hit = np.isfinite(exact)
    # on a wall facing the laser, the incidence from the wall's normal is the beam's angle
    np.testing.assert_allclose(inc[hit], np.abs(ANGLES[hit]), atol=2e-3)


def test_dropout_rate_matches_its_parameter_and_is_higher_at_grazing_incidence():
    model = LaserModel()
    exact = wall_ranges(2.0)
    rng = np.random.default_rng(6)
    n = 3000
    nan = np.zeros(666)
    for _ in range(n):
        nan += np.isnan(model.apply(exact, LASER, 0.01, rng).ranges)
    true_incidence = np.degrees(np.abs(ANGLES))
    normal = true_incidence < model.grazing_angle - 1
    grazing = (true_incidence > model.grazing_angle + 1) & (true_incidence < 89)
    for mask, p in ((normal, model.dropout_rate), (grazing, model.grazing_dropout_rate)):
        trials = n * int(mask.sum())
        assert nan[mask].sum() / trials == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / trials))


def test_dropouts_are_nan_and_labelled(box_cast):
    model = replace(LaserModel(), dropout_rate=0.2, grazing_dropout_rate=0.2)
    out = model.apply(box_cast, LASER, 0.01, np.random.default_rng(8))
    np.testing.assert_array_equal(np.isnan(out.ranges), out.effect == DROPOUT)
    assert 0.1 < np.mean(out.effect == DROPOUT) < 0.3


# --- the consumers' self-filter ------------------------------------------------------------------
@pytest.mark.parametrize('pose', [(11.0, 0.0, -math.pi / 4), (0.0, 0.0, 0.0), (5.0, 0.0, 0.0),
                                  (8.0, 2.0, 1.0)])
def test_self_filter_drops_every_self_hit_and_no_wall_hit(pose):
    world = load_world(COURSE)
    sim = Simulator(world, SimConfig(seed=9, laser_model=LaserModel()), start_pose=pose)
    try:
        # the scene's exact world ranges, to tell which beams are real hits
        exact, _ = sim.scene.cast()
        for _ in range(20):
            reading = sim.config.laser_model.apply(exact, LASER, 0.01, sim.rng)
            dropped = body_returns(reading.ranges, ANGLES)
            self_hit = reading.effect == SELF_HIT
            assert np.all(dropped[self_hit]), 'a self-hit escaped the filter'
            assert not np.any(dropped[reading.effect == EXACT]), 'a wall hit was dropped'
    finally:
        sim.close()


def test_self_filter_is_geometry():
    r = np.array([0.05, ROBOT_RADIUS - LASER_OFFSET + BODY_MARGIN - 1e-6, 0.5, np.nan, np.inf,
                  -np.inf, 0.30])
    a = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, math.pi])
    # 0.3 m straight back from the laser is 0.1 m behind base_footprint's origin: inside
    assert body_returns(r, a).tolist() == [True, True, False, False, False, False, True]
