"""Detection where the classic pipeline goes wrong: partly hidden cylinders (short arcs), range
spreading of the beams, dropouts beside an obstacle. Synthetic scans: pybullet cast of known
cylinders plus seeded noise; ground truth from the world and tiago_nav_tools.evaluate.inview.view_from."""
import math

import numpy as np
import pytest

from tiago_nav.detection import DetectionParams, ObstacleDetector
from tiago_nav.detection.centres import circle_fit, radius_std
from tiago_nav.detection.clustering import centroid_clusters
from tiago_nav_tools.evaluate.suite import DEFAULTS
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import LaserConfig, Scene, noisy
from tiago_nav.sim.world import World
from tiago_nav_tools.evaluate.inview import view_from

L = LaserConfig()
TOLERANCE = DEFAULTS['detection_tolerance']     # [m] the evaluator's centre tolerance (0.05)


def world(movable, walls=()):
    return World.from_dict({
        'name': 'robust', 'resolution': 0.05, 'bounds': [-1, -5, 12, 5], 'robot_start': [0, 0, 0],
        'walls': [dict(w) for w in walls],
        'movable_obstacles': [{'x': x, 'y': y, 'radius': r} for x, y, r in movable]})


def run(w, seed, pose=(0.0, 0.0, 0.0), **params):
    with Scene(w) as s:
        clean, ids = s.cast(pose)
        laser = s.laser_pose(pose)
        visible = view_from(s, pose).in_view
        hits = {i: int(np.sum(ids == b)) for i, b in enumerate(s.movable_ids)}
    r = noisy(clean, 0.01, np.random.default_rng(seed), L.range_min, L.range_max)
    det = ObstacleDetector(rasterise_world(w), DetectionParams(**params))
    found = det.detect(r, L.angle_min, L.angle_increment, L.range_min, L.range_max, laser)
    return found, visible, hits, r, laser


def errors(found, w, visible):
    assert len(found) == len(visible), [d.center for d in found]
    return [min(math.hypot(d.center[0] - c.x, d.center[1] - c.y) for d in found)
            for c in (w.movable_obstacles[i] for i in visible)]


def test_radius_std_flags_short_arcs():
    rng = np.random.default_rng(3)
    half = np.linspace(math.pi / 2, 3 * math.pi / 2, 30)
    short = np.linspace(math.pi - 0.35, math.pi + 0.35, 12)
    stds = []
    for t in (half, short):
        pts = np.column_stack((3 + 0.2 * np.cos(t), 0.2 * np.sin(t))) + rng.normal(0, 0.01, (len(t), 2))
        cx, cy, r, _ = circle_fit(pts)
        stds.append(radius_std(pts, cx, cy, r))
    assert stds[0] < 0.02 < stds[1]


@pytest.mark.parametrize('shapes', [False, True])
def test_partly_hidden_cylinder_is_placed_with_the_scans_common_radius(shapes):
    # the middle cylinder hides most of the one behind it; two more, of the same radius, are in
    # clear view, so their agreed radius is used for the short arc. With the shapes on, that
    # arc is no wider than a calf, but its end is cut by the nearer cylinder: no person's leg
    w = world([(2.0, 0.0, 0.183), (3.2, 0.33, 0.183), (2.5, -1.3, 0.183), (4.0, 1.6, 0.183)])
    worst = []
    for seed in range(10):
        found, visible, hits, _, _ = run(w, seed, shapes=shapes)
        assert all(d.shape == 'circle' for d in found), [(d.shape, d.note) for d in found]
        assert visible == [0, 1, 2, 3] and hits[1] < 15        # really a short arc
        worst.append(max(errors(found, w, visible)))
    assert max(worst) < 0.03, worst


@pytest.mark.parametrize('shapes', [False, True])
def test_hidden_cylinder_keeps_the_free_fit_when_radii_differ(shapes):
    # radii disagree: no common radius is assumed; the hidden one is still found within the
    # evaluator's tolerance (20 seeds: at most 3.4 cm), nothing invented
    w = world([(2.0, 0.0, 0.15), (3.2, 0.33, 0.25), (2.5, -1.3, 0.3), (4.0, 1.6, 0.1)])
    for seed in range(5):
        found, visible, _, _, _ = run(w, seed, shapes=shapes)
        e = errors(found, w, visible)
        assert max(e) < TOLERANCE and sorted(e)[len(e) - 2] < 0.03


def test_configured_radius_fixes_every_fit():
    w = world([(2.0, 0.0, 0.183), (3.2, 0.33, 0.183), (5.5, -2.0, 0.183)])
    for seed in range(5):
        found, visible, _, _, _ = run(w, seed, obstacle_radius=0.183)
        assert max(errors(found, w, visible)) < 0.03
        assert all(d.radius == pytest.approx(0.183) for d in found)


def test_far_cylinders_keep_their_points_together_and_apart():
    # at 8-9 m the beams are ~5 cm apart: a far cylinder is still one cluster, and two far
    # cylinders 0.4 m apart (surfaces) stay two
    w = world([(8.0, 0.0, 0.2), (8.5, 1.0, 0.2), (8.5, 1.8, 0.2)])
    found, visible, _, _, _ = run(w, 1)
    assert visible == [0, 1, 2]
    assert max(errors(found, w, visible)) < 0.05


def test_gap_per_point_and_order_independence():
    # two arcs: a near one (dense) and a far one whose points are 6 cm apart
    near = np.column_stack((np.full(10, 1.0), np.linspace(0, 0.1, 10)))
    far = np.column_stack((np.full(8, 8.0), np.linspace(0, 0.42, 8)))
    pts = np.concatenate((near, far))
    gaps = np.maximum(0.02, 3 * np.hypot(*pts.T) * L.angle_increment)
    groups = centroid_clusters(pts, 0.4, gaps)
    assert sorted(len(g) for g in groups) == [8, 10]
    assert len(centroid_clusters(pts, 0.4, 0.02)) > 2         # one fixed small gap splits the far arc
    for seed in range(5):
        perm = np.random.default_rng(seed).permutation(len(pts))
        g = centroid_clusters(pts[perm], 0.4, gaps[perm])
        assert sorted(len(x) for x in g) == [8, 10]


def test_dropouts_beside_an_obstacle_do_not_pull_the_fit():
    w = world([(3.0, 0.4, 0.2)], walls=[{'x': 6.0, 'y': 0.0, 'length': 8.0, 'width': 0.15,
                                           'yaw_deg': 90}])
    found, visible, _, r, laser = run(w, 4)
    with Scene(w) as s:
        _, ids = s.cast((0.0, 0.0, 0.0))
        beams = np.flatnonzero(ids == s.movable_ids[0])
    bad = r.copy()
    bad[beams[0]] = np.inf            # no return from its first and last beams
    bad[beams[-1]] = np.nan
    bad[beams[-1] + 1] = np.inf
    det = ObstacleDetector(rasterise_world(w))
    again = det.detect(bad, L.angle_min, L.angle_increment, L.range_min, L.range_max, laser)
    assert max(errors(again, w, visible)) < 0.03


@pytest.mark.parametrize('neighbour, dip', [(5.0, True), (math.inf, True), (math.nan, True),
                                            (-math.inf, False)])
def test_discontinuity_reads_a_too_close_neighbour_per_rep_117(neighbour, dip):
    """A 10-beam segment at 2 m in front of a 5 m background is a dip (an obstacle); with its
    left neighbour -inf (REP 117: something nearer than range_min) it stands in front of
    nothing and is not one. +inf (no return) and NaN (says nothing) do not hide it."""
    w = world([(2.0, 0.0, 0.2)])
    det = ObstacleDetector(rasterise_world(w), DetectionParams())
    r = np.full(L.num_beams, 5.0)
    mid = L.num_beams // 2
    r[mid - 5:mid + 5] = 2.0
    r[mid - 6] = neighbour
    found = det.detect(r, L.angle_min, L.angle_increment, L.range_min, L.range_max,
                       (0.0, 0.0, 0.0), 'discontinuity')
    assert len(found) == (1 if dip else 0), [d.center for d in found]
    if dip:
        assert found[0].center[0] == pytest.approx(2.0 + DetectionParams().depth, abs=0.01)


def test_equal_cylinders_share_their_radius():
    """Four cylinders of one radius on the tiago laser: with the radius they agree on, each
    centre is placed better along its beams than by its own free fit (over 20 scans: RMS 8.0
    -> 4.4 mm, max 23.7 -> 9.9 mm; the free fits alone failed both bounds)."""
    from test_detection import world as row_world
    from tiago_nav.sim.laser import LaserModel
    w = row_world([(2.0, 1.2, 0.183), (3.0, -0.6, 0.183), (4.0, 0.8, 0.183), (2.5, -1.8, 0.183)])
    grid = rasterise_world(w)
    with Scene(w) as s:
        clean, _ = s.cast((0.0, 0.0, 0.0))
        laser = s.laser_pose((0.0, 0.0, 0.0))
    errs = {}
    for shared in (False, True):
        det = ObstacleDetector(grid, DetectionParams(correct_pose=False, shared_radius=shared))
        e = []
        for seed in range(20):
            r = LaserModel().apply(clean, L, 0.01, np.random.default_rng(seed)).ranges
            found = det.detect(r, L.angle_min, L.angle_increment, L.range_min, L.range_max, laser,
                               laser_in_base=laser)      # the robot at the origin
            assert len(found) == 4
            e += [min(math.hypot(d.center[0] - c.x, d.center[1] - c.y) for d in found)
                  for c in w.movable_obstacles]
        errs[shared] = np.array(e)
    on, off = errs[True], errs[False]
    assert np.sqrt(np.mean(on ** 2)) < 0.006 and on.max() < 0.015
    assert np.sqrt(np.mean(off ** 2)) > 0.006 and off.max() > 0.015   # the free fits alone


# The course suite's rooms_110 at pose B: a cylinder (0.22 m, 6.8 m away) half hidden behind a
# nearer one (0.214 m, 5.3 m): 6 beams from its left silhouette edge to just past its nearest
# point. Its free fit's radius is not measurable (std error 4-10 cm): 0.29-0.30 m came out, the
# centre 8-9 cm off. The one well-measured cylinder of the scan is now a soft prior.
ROOMS_110 = dict(movable=[(6.498, 1.166, 0.214), (8.04, 1.192, 0.22)],
                 pose=(1.2828739, 2.1296778, -0.0425537))


def rooms_110_world():
    walls = [{'x': 3.5, 'y': 3.09, 'length': 13.0, 'width': 0.15},
             {'x': 3.5, 'y': -3.09, 'length': 13.0, 'width': 0.15},
             {'x': 9.38, 'y': 0.0, 'length': 6.33, 'width': 0.15, 'yaw_deg': 90},
             {'x': -0.075, 'y': 0.0, 'length': 6.33, 'width': 0.15, 'yaw_deg': 90}]
    return World.from_dict({
        'name': 'rooms_110_b', 'resolution': 0.05, 'bounds': [-1, -3.3, 9.6, 3.3],
        'robot_start': [1, 2, 0], 'walls': walls,
        'movable_obstacles': [{'x': x, 'y': y, 'radius': r} for x, y, r in ROOMS_110['movable']]})


def test_half_hidden_cylinder_borrows_the_one_well_measured_radius():
    from tiago_nav.geometry import compose, inverse
    from tiago_nav.scan import median_ranges
    from tiago_nav.sim.laser import LaserModel
    w = rooms_110_world()
    pose = ROOMS_110['pose']
    lm = LaserModel()                                   # the tiago laser, as the suite's profile
    with Scene(w) as s:
        clean, ids = s.cast(pose)
        laser = s.laser_pose(pose)
        hits = [int(np.sum(ids == b)) for b in s.movable_ids]
    lib = compose(inverse(pose), laser)
    assert hits[1] <= 8 < hits[0]                      # the far one: a short arc
    grid = rasterise_world(w)
    new = ObstacleDetector(grid, DetectionParams(correct_pose=False))
    old = ObstacleDetector(grid, DetectionParams(correct_pose=False, single_radius_std=0))
    rng = np.random.default_rng(2)
    worst = {'new': 0.0, 'old': 0.0}
    for _ in range(30):
        # the service's median of 5 scans at rest
        r = median_ranges([lm.apply(clean, L, 0.01, rng).ranges for _ in range(5)],
                          L.range_min, L.range_max)
        for name, det in (('new', new), ('old', old)):
            found = det.detect(r, L.angle_min, L.angle_increment, L.range_min, L.range_max,
                               laser, laser_in_base=lib)
            assert len(found) == 2
            e = max(min(math.hypot(d.center[0] - x, d.center[1] - y) for d in found)
                    for x, y, _ in ROOMS_110['movable'])
            worst[name] = max(worst[name], e)
    assert worst['new'] < 0.04 < 0.05 < worst['old'], worst


def test_the_veil_filters_drop_at_a_silhouette_edge_does_not_hide_the_passing_beams():
    from tiago_nav.detection.pipeline import _passing_rays
    inc = math.radians(1.0)
    raw = np.array([8.0, 8.0, 8.0, 3.0, 3.0, 3.0, 8.0, 8.0, 8.0, 8.0])
    usable = raw.copy()
    usable[6] = np.nan            # the filter's drop: the step 3 -> 8 m lies along the beam
    beams, rng = np.array([3, 4, 5]), np.array([3.0, 3.0, 3.0])
    right = _passing_rays(usable, beams, rng, 0.0, inc, 0.0, 25.0, raw)
    assert len(right) == 3 + 2     # beams 2, 1, 0 and, past the dropped 6, beams 7 and 8
    ang = np.degrees(np.arctan2(right[:, 1], right[:, 0]))
    assert sorted(np.round(ang).astype(int)) == [0, 1, 2, 7, 8]
    # a dropout (no raw return either) still ends the walk: it may lie on the obstacle
    raw2 = raw.copy()
    raw2[6] = np.nan
    assert len(_passing_rays(usable, beams, rng, 0.0, inc, 0.0, 25.0, raw2)) == 3
    # and so does a drop in front of the cluster (something nearer)
    raw3 = raw.copy()
    raw3[6] = 2.0
    assert len(_passing_rays(usable, beams, rng, 0.0, inc, 0.0, 25.0, raw3)) == 3
