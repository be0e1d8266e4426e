"""Detection on synthetic scans of known cylinders, walls and maps (pybullet cast + seeded noise)."""
import math

import numpy as np
import pytest

from tiago_nav.detection import DetectionParams, ObstacleDetector
from tiago_nav.detection.centres import algebraic_circle, circle_fit
from tiago_nav.detection.clustering import centroid_clusters
from tiago_nav.detection.subtraction import MapDistance, brute_force_distance, subtract
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import LaserConfig, Scene, noisy
from tiago_nav.sim.world import World
from tiago_nav_tools.evaluate.inview import view_from

L = LaserConfig()


def world(movable, walls=None, bounds=(-1, -4, 8, 4)):
    return World.from_dict({
        'name': 'det', 'resolution': 0.05, 'bounds': list(bounds), 'robot_start': [0, 0, 0],
        'walls': walls if walls is not None else [
            {'x': 3.5, 'y': 3.0, 'length': 9.0, 'width': 0.15},
            {'x': 3.5, 'y': -3.0, 'length': 9.0, 'width': 0.15},
            {'x': 7.5, 'y': 0.0, 'length': 6.0, 'width': 0.15, 'yaw_deg': 90}],
        'movable_obstacles': [{'x': x, 'y': y, 'radius': r} for x, y, r in movable]})


def scan_of(w, pose=(0.0, 0.0, 0.0), noise=0.01, seed=0):
    with Scene(w) as s:
        r, _ = s.cast(pose)
        laser = s.laser_pose(pose)
        visible = view_from(s, pose).in_view
    return noisy(r, noise, np.random.default_rng(seed), L.range_min, L.range_max), laser, visible


def detect(w, pose=(0.0, 0.0, 0.0), method='circle_fit', noise=0.01, seed=0, **kw):
    r, laser, visible = scan_of(w, pose, noise, seed)
    det = ObstacleDetector(rasterise_world(w), DetectionParams(**kw))
    return det.detect(r, L.angle_min, L.angle_increment, L.range_min, L.range_max, laser, method), visible


def match(found, w, visible, tol):
    """Every visible obstacle found once within ``tol``, nothing else; returns the errors."""
    errs = []
    assert len(found) == len(visible), [d.center for d in found]
    for i in visible:
        c = w.movable_obstacles[i]
        e = min(math.hypot(d.center[0] - c.x, d.center[1] - c.y) for d in found)
        assert e < tol, (i, e)
        errs.append(e)
    return errs


def test_distance_transform_matches_brute_force():
    w = world([])
    grid = rasterise_world(w)
    pts = np.random.default_rng(1).uniform((-1, -4), (8, 4), (500, 2))
    fast = MapDistance(grid)(pts)
    slow = brute_force_distance(pts, grid)
    # the transform measures from the point's cell centre: within half a cell diagonal
    assert np.max(np.abs(fast - slow)) <= 0.05 * math.sqrt(2) / 2 + 1e-9
    assert np.isinf(MapDistance(grid)(np.array([[50.0, 50.0]])))[0]


def test_subtraction_keeps_an_obstacle_next_to_a_wall():
    # a cylinder 0.1 m from the east wall's face (face at x = 7.425)
    w = world([(7.425 - 0.1 - 0.2, 0.5, 0.2)])
    r, laser, visible = scan_of(w)
    grid = rasterise_world(w)
    from tiago_nav.geometry import transform_points
    from tiago_nav.scan import scan_to_points
    pts = transform_points(laser, scan_to_points(r, L.angle_min, L.angle_increment, 0.05, 25)[0])
    keep = subtract(pts, MapDistance(grid), 0.12)
    kept = pts[keep]
    on_cyl = np.abs(np.hypot(kept[:, 0] - 7.125, kept[:, 1] - 0.5) - 0.2) < 0.05
    assert on_cyl.sum() >= 5
    assert on_cyl.mean() > 0.95                          # the wall itself is gone
    found, visible = detect(w)
    match(found, w, visible, 0.03)


def test_circle_fit_accuracy_at_1_to_5_m():
    rng = np.random.default_rng(7)
    errs = []
    for dist in (1.0, 2.0, 3.0, 4.0, 5.0):
        for _ in range(20):
            theta = rng.uniform(-0.6, 0.6)
            cx, cy = dist * math.cos(theta), dist * math.sin(theta)
            w = world([(cx + 0.2, cy, 0.2)], walls=[])        # laser at x = 0.2
            r, laser, _ = scan_of(w, noise=0.01, seed=int(rng.integers(1e6)))
            from tiago_nav.geometry import transform_points
            from tiago_nav.scan import scan_to_points
            pts = transform_points(laser, scan_to_points(r, L.angle_min, L.angle_increment, 0.05, 25)[0])
            fx, fy, fr, _ = circle_fit(pts)
            errs.append(math.hypot(fx - cx - 0.2, fy - cy))
    assert np.sqrt(np.mean(np.square(errs))) < 0.015
    assert max(errs) < 0.04


def test_fixed_radius_fit_and_algebraic_start():
    t = np.linspace(-1.2, 1.2, 30) + math.pi
    pts = np.column_stack((2 + 0.3 * np.cos(t), 1 + 0.3 * np.sin(t)))
    assert algebraic_circle(pts) == pytest.approx((2, 1, 0.3), abs=1e-9)
    cx, cy, r, rms = circle_fit(pts + 0.001, radius=0.3, sensor=(0, 1))
    assert (cx, cy, r) == pytest.approx((2.001, 1.001, 0.3), abs=1e-6) and rms < 1e-6


def test_two_cylinders_a_tenth_apart_are_two():
    w = world([(2.5, 0.25, 0.2), (2.5, -0.25, 0.2)])      # surfaces 0.1 m apart
    found, visible = detect(w)
    assert visible == [0, 1]
    match(found, w, visible, 0.03)


def test_clusters_split_and_merge():
    a = np.column_stack((np.linspace(0, 0.3, 10), np.zeros(10)))
    b = a + (1.0, 0.0)
    c = np.concatenate((a, b))
    groups = centroid_clusters(c, threshold=0.4, gap=0.1)
    assert sorted(len(g) for g in groups) == [10, 10]
    # point order does not matter for well-separated clusters
    perm = np.random.default_rng(0).permutation(len(c))
    assert sorted(len(g) for g in centroid_clusters(c[perm], 0.4, 0.1)) == [10, 10]
    assert centroid_clusters(np.empty((0, 2)), 0.4, 0.1) == []


def test_unmapped_wall_and_noise_are_not_obstacles():
    # a 1.5 m wall segment that is not in the map: a straight cluster, not round
    w = world([])
    grid = rasterise_world(w)
    extra = World.from_dict({'name': 'x', 'resolution': 0.05, 'bounds': [-1, -4, 8, 4],
                             'robot_start': [0, 0, 0],
                             'walls': [{'x': 3.5, 'y': 3.0, 'length': 9.0, 'width': 0.15},
                                       {'x': 3.5, 'y': -3.0, 'length': 9.0, 'width': 0.15},
                                       {'x': 7.5, 'y': 0.0, 'length': 6.0, 'width': 0.15, 'yaw_deg': 90},
                                       {'x': 3.0, 'y': 1.2, 'length': 1.5, 'width': 0.1, 'yaw_deg': 20}]})
    r, laser, _ = scan_of(extra)
    # nothing round: no circle (with shapes off, nothing at all). With them, the wall's near
    # end, 0.1 m wide and seen square on while its side lies along the beams, is a flat run as
    # narrow as a calf with nothing nearer beside it: a trouser leg looks the same in one scan
    # (docs/detection.md), so the only legs may stand there, and nowhere along the wall
    det = ObstacleDetector(grid, DetectionParams(shapes=False))
    assert det.detect(r, L.angle_min, L.angle_increment, 0.05, 25, laser) == []
    found = ObstacleDetector(grid, DetectionParams(shapes=True)).detect(r, L.angle_min, L.angle_increment, 0.05, 25, laser)
    assert [d.shape for d in found if d.shape == 'circle'] == []
    end = (3.0 - 0.75 * math.cos(math.radians(20)), 1.2 - 0.75 * math.sin(math.radians(20)))
    for d in found:
        if d.shape == 'legs':
            assert math.hypot(d.center[0] - end[0], d.center[1] - end[1]) < 0.15, d.center


def test_bad_ranges_are_ignored():
    w = world([(3.0, 0.5, 0.2)])
    r, laser, visible = scan_of(w)
    r = r.copy()
    r[::7] = np.nan
    r[3::11] = np.inf
    r[5::13] = -1.0
    r[6::17] = 100.0
    det = ObstacleDetector(rasterise_world(w))
    found = det.detect(r, L.angle_min, L.angle_increment, 0.05, 25, laser)
    match(found, w, visible, 0.03)
    assert det.detect(np.full(666, np.nan), L.angle_min, L.angle_increment, 0.05, 25, laser) == []


@pytest.mark.parametrize('method, tol', [('circle_fit', 0.03), ('centroid', 0.25), ('discontinuity', 0.1)])
def test_methods_find_every_cylinder(method, tol):
    w = world([(2.0, 1.0, 0.183), (3.5, -0.8, 0.25), (5.0, 1.6, 0.12)])
    found, visible = detect(w, method=method)
    assert visible == [0, 1, 2]
    match(found, w, visible, tol)


def test_centroid_is_biased_toward_the_robot_and_the_fit_is_not():
    w = world([(3.0, 0.0, 0.25)], walls=[])
    (fit,), _ = detect(w, method='circle_fit')
    (cen,), _ = detect(w, method='centroid')
    assert abs(fit.center[0] - 3.0) < 0.015
    assert 3.0 - cen.center[0] > 0.1                 # pulled toward the laser at x = 0.2


def test_unknown_method():
    det = ObstacleDetector(rasterise_world(world([])))
    with pytest.raises(ValueError, match='unknown method'):
        det.detect(np.full(666, 1.0), L.angle_min, L.angle_increment, 0.05, 25, (0, 0, 0), 'hough')
