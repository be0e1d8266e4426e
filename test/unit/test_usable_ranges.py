"""tiago_nav.scan.usable_ranges, the one filter every scan consumer applies, and the consumers
with the simulator's ``tiago`` laser model (self-hits, mixed pixels, dropouts): the costmap
marks no body next to the robot, detection invents nothing at cylinder edges, the corridor law
still centres, localisation still meets its bar. And tiago_nav.scan.median_ranges, detection's
combination of the scans at rest."""
import math
import os

import numpy as np
import pytest

from conftest import WORLDS
from tiago_nav.detection.pipeline import DetectionParams, ObstacleDetector
from tiago_nav.geometry import compose, inverse
from tiago_nav.scan import beam_angles, body_returns, median_ranges, usable_ranges
from tiago_nav.sim.laser import LaserModel
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import World, load_world
from tiago_nav.sim.worlds import corridor_world
from tiago_nav_tools.testing.corridor import run_in_simulator
from tiago_nav_tools.evaluate.matching import score, visible_truth
from tiago_nav_tools.testing.localisation import run_route
from tiago_nav_tools.testing.navigation import ClosedLoop

N, A0, INC = 361, -math.pi / 2, math.pi / 360       # a 180 deg fan, 0.5 deg steps
LASER = (0.2, 0.0, 0.0)
POSE_B = (11.0, 0.0, math.radians(-45.0))


def clean(r, **kw):
    kw.setdefault('laser_pose', LASER)
    return usable_ranges(r, A0, INC, 0.05, 25.0, **kw)


def wall_at(x):
    """Ranges of a wall across the fan ``x`` m ahead of the laser (beams within +-60 deg)."""
    a = beam_angles(A0, INC, N)
    return np.where(np.abs(a) < math.radians(60), x / np.cos(a), np.inf)


# --- the filter -------------------------------------------------------------------------------

def test_a_mixed_pixel_at_a_depth_edge_is_dropped_and_the_edge_kept():
    r = wall_at(4.0)
    r[170:181] = 2.0                        # something 2 m away in front of the wall
    r[181] = 3.0                            # the beam straddling its edge: half-way
    out = clean(r)
    assert np.isnan(out[181])
    assert np.all(out[170:181] == 2.0)      # the near edge is a real surface
    assert out[182] == r[182]               # the wall behind it continues the veil: kept


def test_range_noise_alone_makes_no_veil():
    r = wall_at(0.6) + np.random.default_rng(0).normal(0.0, 0.01, N)   # close: beams 5 mm apart
    out = clean(r)
    assert np.array_equal(np.isnan(out), np.isnan(r))


def test_a_wall_at_grazing_incidence_keeps_its_points():
    # a wall 0.5 m to the left running ahead, beams every 0.1 deg: beyond 2.9 m along it, the
    # wall is seen at under 10 deg, a chain of grazing steps
    inc = math.radians(0.1)
    a = beam_angles(0.0, inc, 900)
    with np.errstate(divide='ignore'):
        r = np.where(a > math.radians(2), 0.5 / np.sin(a), np.inf)
    r[r > 25.0] = np.inf
    out = usable_ranges(r, 0.0, inc, 0.05, 25.0, laser_pose=LASER)
    far = np.isfinite(r) & (r * np.cos(a) > 2.9)
    assert far.sum() > 50
    assert np.isnan(out[far]).sum() <= 1    # only where the chain of grazing steps begins


def test_a_mixed_pixel_past_a_grazing_walls_end_is_dropped_even_on_its_neighbours_line():
    # a wall 0.25 m to the left, seen at grazing incidence, ends 3 m ahead; past its end the
    # beams reach a wall across the fan 5 m ahead. The beam straddling the end returns a mixed
    # pixel, here where the line through its two neighbours (one on each wall) crosses it: on
    # that line, yet far from both walls (the course's wall end at (9.7, 0) seen from (10.2,
    # -3.2) made such a point, and move_base marked it)
    inc = math.radians(0.33)
    a = beam_angles(math.radians(1.0), inc, 200)
    along = 0.25 / np.tan(a)                     # where each beam meets the side wall's line
    side = along <= 3.0
    r = np.where(side, 0.25 / np.sin(a), 5.0 / np.cos(a))
    j = int(np.flatnonzero(side)[0]) - 1         # the last beam past the wall's end
    s21, s10, s20 = (math.sin(a[j + 1] - a[j]), math.sin(a[j] - a[j - 1]),
                     math.sin(a[j + 1] - a[j - 1]))
    r[j] = s20 / (s21 / r[j - 1] + s10 / r[j + 1])
    x, y = r[j] * math.cos(a[j]), r[j] * math.sin(a[j])
    assert x > 3.0 and min(math.hypot(x - 3.0, y - 0.25), 5.0 - x) > 0.3   # from either wall
    out = usable_ranges(r, a[0], inc, 0.05, 25.0, laser_pose=LASER)
    assert np.isnan(out[j])
    # the side wall's points along its last 2 m stay, but where its chain of grazing steps
    # begins and its last two points, beside the mixed pixel (no line of two points on that
    # side vouches for them)
    wall = np.flatnonzero(side & (along > 1.0))
    assert np.isnan(out[wall]).sum() == 3
    assert np.isnan(out[j + 1:j + 3]).all()
    assert np.isfinite(out[j - 3:j]).all()       # and so does the far wall


@pytest.mark.parametrize('ranges, mixed', [
    # from (10.04, -3.19) facing west, along the wall x = 9.7 to its end at y = 0 and past it
    # to a cylinder 4.5 m away: 3.534 continues the wall's line, 0.32 m past its end
    ([4.496, 4.496, 4.513, 4.514, 4.133, 3.534, 3.126, 2.81, 2.796, 2.501, 2.499], 5),
    # from (8.06, -0.76): the same wall's end (1.742), a cylinder's tangent (2.225) and the far
    # wall (5.947); 3.208 lies on the line of the two near points (at 2 m the test allows
    # centimetres along the beam), 0.54 m from anything
    ([1.721, 1.732, 1.734, 1.742, 2.225, 3.208, 5.947, 5.954, 5.963, 5.99, 5.995], 5),
])
def test_a_mixed_pixel_on_one_sides_line_only_is_dropped(ranges, mixed):
    """Two mixed pixels move_base marked in navigation.test, as the laser (the simulator's
    tiago model) gave them: each inside a chain of grazing steps, on the line through its two
    neighbours and on the line through the two points on its near side, not on the far side's."""
    inc = math.radians(220.0) / 665
    out = usable_ranges(np.array(ranges), 0.3, inc, 0.05, 25.0, laser_pose=LASER)
    assert np.isnan(out[mixed])
    assert np.isfinite(out[:4]).all() and np.isfinite(out[-2:]).all()   # the surfaces


def test_rep117_values_keep_their_meaning_and_the_body_goes():
    r = wall_at(3.0)
    r[:5], r[5], r[6], r[-3:] = np.nan, -np.inf, 0.01, 0.15   # 0.01: out of limits (invalid)
    backwards = (0.2, 0.0, math.pi / 2)     # the fan's last beams point backwards in the base
    out = clean(r, laser_pose=backwards)
    assert np.isnan(out[:5]).all() and out[5] == -np.inf and out[6] == 0.01
    assert np.isinf(out[r == np.inf]).all()
    # 0.15 m from the laser along them is inside the body
    assert np.isnan(out[-3:]).all()
    assert not np.isnan(clean(r, laser_pose=backwards, radius=0.0, margin=0.0)[-3:]).any()


def test_the_body_follows_the_laser_pose_from_tf():
    a = beam_angles(A0, INC, N)
    r = np.full(N, 0.3)
    facing_back = (0.0, 0.0, math.pi)       # every beam points backwards
    # 0.3 m from the base centre is inside the 0.27 + 0.05 m body, 0.6 m outside
    inner = slice(1, -1)                    # the +-90 deg beams point exactly sideways
    assert body_returns(r, a, facing_back).all()
    assert np.isnan(clean(r, laser_pose=facing_back)[inner]).all()
    assert not np.isnan(clean(r * 2, laser_pose=facing_back)).any()


def test_a_return_ahead_of_the_laser_is_never_the_body():
    """An obstacle 3 cm from the front bumper (inside the body's margin) must stop the robot."""
    r = np.full(N, np.inf)
    r[180] = 0.1                            # straight ahead: 0.3 m from the base centre
    assert clean(r)[180] == 0.1


def test_a_mixed_pixel_at_the_bodys_edge_is_the_body():
    """The fan's last beams hit the robot's own body (TIAGo's self-hits); the beam beside the
    first of them can return a mixed pixel between the body and what lies past it. Within
    ``shadow_min_jump`` of the body's return it makes no grazing step, yet it can lie just
    outside the body's margin: move_base marked one (0.303 m on the fan's last beam before the
    self-hits, 0.32 m from the base centre), beyond the footprint it clears, and kept it there
    after the robot left. It is the body's, not a surface's. Here the beams past the body see a
    wall 0.41 m to the left."""
    from tiago_nav.sim.laser import body_ranges
    n, inc = 666, math.radians(220.0) / 665
    a = beam_angles(-math.radians(110.0), inc, n)
    body = body_ranges(a, 0.2, 0.27, math.radians(103.5))
    r = np.where(np.isfinite(body), body, np.inf)
    wall = np.flatnonzero((a > 0) & ~np.isfinite(body))
    r[wall] = 0.41 / np.sin(a[wall])               # the wall y = 0.41 m, to the left
    j = int(wall[-1])                               # the last beam before the body's
    r[j + 1] += 0.02                                # range noise: 2 sigma
    r[j] = 0.303                                    # the mixed pixel, 4.8 cm past the body's
    x, y = 0.2 + r[j] * math.cos(a[j]), r[j] * math.sin(a[j])
    assert 0.32 < math.hypot(x, y) and 0.41 - y > 0.1    # off the body and the wall
    out = usable_ranges(r, a[0], inc, 0.05, 25.0, laser_pose=LASER)
    assert np.isnan(out[j])
    assert np.isnan(out[j + 1:]).all()              # the body
    # the wall's hits within 5 m stay, but where its chain of grazing steps begins and the
    # veil point beside the mixed pixel
    kept = wall[(r[wall] < 5.0) & (wall < j)]
    assert len(kept) > 200 and np.isfinite(out[kept]).sum() == len(kept) - 2


# --- the consumers with the tiago laser -------------------------------------------------------

@pytest.fixture(scope='module')
def course():
    return load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))


def tiago_sim(world, pose, seed=0):
    return Simulator(world, SimConfig(seed=seed, laser_model=LaserModel()), start_pose=pose)


@pytest.mark.parametrize('pose', [None, POSE_B, (5.0, 0.0, 0.0)])
def test_the_costmap_marks_no_body_next_to_the_robot(course, pose):
    loop = ClosedLoop(course, start=pose, laser=LaserModel())
    try:
        for _ in range(30):
            loop.scan()
        cm = loop.nav.costmap
        centres = np.argwhere(cm.obstacles)
        xy = cm.grid.cell_to_world(centres)
        x, y, _ = loop.sim.pose
        near = np.hypot(xy[:, 0] - x, xy[:, 1] - y) < 0.45     # the corridor's walls: 0.53 m
        assert not near.any(), xy[near]
    finally:
        loop.close()


def test_without_the_filter_the_body_would_be_marked(course):
    """The test above can fail: the tiago laser's self-hits, unfiltered, are marked."""
    from tiago_nav.nav.costmap import MapScan
    loop = ClosedLoop(course, laser=LaserModel())
    try:
        las = loop.sim.config.laser
        scan = MapScan(loop.sim.scene.laser_pose(), loop.sim.scan(), las.angle_min,
                       las.angle_increment, las.range_min, las.range_max)   # no laser_in_base
        pts, _ = scan.obstacles
        x, y, _ = loop.sim.pose
        assert (np.hypot(pts[:, 0] - x, pts[:, 1] - y) < 0.35).sum() >= 30
    finally:
        loop.close()


def test_detection_finds_no_mixed_pixels_at_cylinder_edges(course):
    det = ObstacleDetector(rasterise_world(course), DetectionParams())
    errors, false_positives, mixed = [], 0, 0
    for seed in range(20):
        sim = tiago_sim(course, POSE_B, seed)
        try:
            las = sim.config.laser
            r = sim.scan()
            exact, _ = sim.scene.cast(sim.pose)
            laser = sim.scene.laser_pose()
            found = det.detect(r, las.angle_min, las.angle_increment, las.range_min, las.range_max,
                               laser, laser_in_base=compose(inverse(sim.pose), laser))
            truth = visible_truth(course, sim.pose)
        finally:
            sim.close()
        ok = np.isfinite(r) & np.isfinite(exact)
        mixed += int(np.sum(np.abs(r[ok] - exact[ok]) > 0.1))
        s = score([(tx, ty) for _, tx, ty, _ in truth], [d.center for d in found])
        assert s['matched'] == len(truth) == 4, (seed, s)
        false_positives += s['false_positives']
        errors += [e for _, _, e in s['pairs']]
    assert mixed >= 40                          # the model made mixed pixels (and self-hits)
    assert false_positives == 0
    assert math.sqrt(np.mean(np.square(errors))) <= 0.02


def test_the_corridor_law_still_centres_with_the_tiago_laser():
    sim = Simulator(World.from_dict(corridor_world(1.07, 5.0, start=(-1.5, -0.15, math.radians(-15)))),
                    SimConfig(seed=7, laser_model=LaserModel()))
    track = []
    try:
        cmd, _ = run_in_simulator(sim, timeout=40.0, on_step=lambda s, c: track.append(s.pose))
        collisions = sim.collisions
    finally:
        sim.close()
    track = np.array(track)
    assert cmd.state == 'done', cmd.reason
    assert collisions == 0
    assert 5.1 < track[-1, 0] < 5.7 and abs(track[-1, 1]) < 0.05
    inside = track[(track[:, 0] > 1.0) & (track[:, 0] < 5.0)]
    assert np.sqrt(np.mean(inside[:, 1] ** 2)) < 0.03


def test_localisation_meets_its_bar_with_the_tiago_laser(course):
    res = run_route(course, route=((2.0, 0.0), (5.5, 0.0), (7.2, -0.3), (8.6, -0.9)), seed=5,
                    laser=LaserModel())
    assert res.p95('loc_xy') <= 0.05 and res.p95('loc_yaw') <= math.radians(2.0), \
        (res.p95('loc_xy'), math.degrees(res.p95('loc_yaw')))


def test_a_repeated_scan_is_frozen_only_once_the_laser_moved():
    from tiago_nav.scan import FrozenScanCheck
    rng = np.random.default_rng(0)
    live = FrozenScanCheck()
    # a live, noisy laser: never frozen, moving or not
    assert not any(live(5.0 + rng.normal(0, 0.01, 666), (0.01 * k, 0.0, 0.0)) for k in range(20))
    stuck = FrozenScanCheck()
    r = 5.0 + rng.normal(0, 0.01, 666)
    r[::7] = np.nan
    assert not stuck(r, (0.0, 0.0, 0.0))
    assert not stuck(r.copy(), (0.0, 0.0, 0.0))          # a standing robot: nothing to gain
    assert not stuck(r.copy(), (0.01, 0.0, 0.0))         # moved 1 cm: not yet
    assert stuck(r.copy(), (0.03, 0.0, 0.0))             # moved 3 cm with the same ranges
    assert stuck(r.copy(), (0.0, 0.0, 0.05))             # or turned 3 deg
    assert not stuck(r + 0.001, (0.1, 0.0, 0.0))         # a new scan: live again


def test_same_ranges_takes_nan_for_nan_and_nothing_else():
    from tiago_nav.scan import same_ranges
    a = np.array([1.0, np.nan, np.inf, 2.0])
    assert same_ranges(a, a.copy())
    assert not same_ranges(a, np.array([1.0, 3.0, np.inf, 2.0]))       # a NaN is not a range
    assert not same_ranges(a, np.array([1.0, np.nan, np.inf, np.nan]))  # nor a range a NaN
    assert not same_ranges(a, np.array([1.0, np.nan, 25.0, 2.0]))
    assert same_ranges(np.full(3, np.nan), np.full(3, np.nan))


def test_the_corridor_law_blocks_on_a_frozen_laser():
    from tiago_nav.corridor.law import CorridorFollower, CorridorParams
    from tiago_nav.scan import Scan
    rng = np.random.default_rng(1)
    f = CorridorFollower(CorridorParams())
    a = np.linspace(-1.92, 1.92, 666)
    with np.errstate(divide='ignore'):
        r = np.where(np.abs(np.sin(a)) > 1e-6, 0.55 / np.abs(np.sin(a)), np.inf)
    r = np.where(r * np.cos(a) < 4.0, r + rng.normal(0, 0.005, 666), np.inf)
    scan = Scan(r, a[0], a[1] - a[0], 0.05, 25.0, 0.0, 'base_laser_link')
    f.update_laser(scan, (0.2, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert not f.unusable
    f.update_laser(scan, (0.3, 0.0, 0.0), (0.1, 0.0, 0.0))          # same ranges 10 cm further on
    assert 'repeats its last scan' in f.unusable
    assert f.command((0.1, 0.0, 0.0)).state == 'blocked'


def test_median_ranges_outvotes_one_scan_and_keeps_rep117_meanings():
    inf, nan = math.inf, math.nan
    scans = [[1.00, inf, nan, 2.0, -inf, 3.0],
             [1.02, 4.0, 5.0, nan, -inf, 9.0],      # 9.0: a mixed pixel in one scan
             [0.98, 4.0, 5.1, nan, 0.01, 3.1]]
    out = median_ranges(scans, 0.05, 25.0)
    assert out[0] == 1.0                     # the median of three hits
    assert out[1] == 4.0                     # most hit: their median, not the reference's +inf
    assert out[2] == 5.05                    # the reference's NaN outvoted
    assert out[3] == 2.0                     # one hit of three: the reference's own value
    assert out[4] == -inf                    # too close stays too close
    assert out[5] == 3.1                     # the mixed pixel outvoted


def test_median_of_five_scans_halves_the_range_noise():
    rng = np.random.default_rng(0)
    truth = np.full(2000, 3.0)
    single = truth + rng.normal(0, 0.01, truth.size)
    five = median_ranges([truth + rng.normal(0, 0.01, truth.size) for _ in range(5)], 0.05, 25.0)
    assert np.std(five - truth) < 0.6 * np.std(single - truth)
