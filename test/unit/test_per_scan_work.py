"""The work every scan costs, done once where it can be (no ROS): the beam geometry of
tiago_nav.scan.usable_ranges kept per geometry, the localiser's information split from the
scan's heading-free Jacobian, the distance field's look-up with its three values at once. Each
must give what the direct computation gives."""
import math

import numpy as np
from scipy import ndimage

from tiago_nav.localisation.localiser import (DistanceField, observable_directions, scan_information,
                                    scan_normals)
from tiago_nav import scan as scan_module
from tiago_nav.scan import beam_angles, body_returns, usable_ranges
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.world import World
from tiago_nav.sim.worlds import corridor_world


def test_usable_ranges_follows_each_beam_geometry():
    """Scans of two lasers (different fans and mountings) alternate: each is filtered
    with its own geometry, as a first call with that geometry filters it."""
    rng = np.random.default_rng(3)
    fans = [(-1.9, 0.0058, 666, (0.2, 0.0, 0.0)), (-2.0, 0.006, 666, (0.15, 0.0, 0.0))]
    scans = []
    for a0, inc, n, pose in fans:
        a = beam_angles(a0, inc, n)
        # a wall 1 m ahead of the laser, a post in front of it (veils at its edges), the body
        # behind (returns within the footprint) and dropouts
        r = np.where(np.abs(np.sin(a)) < 0.99, 1.0 / np.maximum(np.abs(np.cos(a)), 0.05), 8.0)
        r[n // 2 - 5:n // 2 + 5] = 0.5
        r[n // 2 - 6], r[n // 2 + 5] = 0.75, 0.75        # mixed pixels
        r[np.cos(a + pose[2]) < -0.3] = 0.25
        r[rng.integers(0, n, 8)] = np.nan
        scans.append((r + rng.normal(0.0, 0.002, n), a0, inc, pose))
    first = []
    for r, a0, inc, pose in scans:      # each alone: nothing kept from another geometry
        scan_module._GEOMETRIES.clear()
        first.append(usable_ranges(r, a0, inc, 0.05, 25.0, pose))
    for _ in range(2):
        for (r, a0, inc, pose), want in zip(scans, first):
            got = usable_ranges(r, a0, inc, 0.05, 25.0, pose)
            np.testing.assert_array_equal(got, want)    # NaN equal to NaN (numpy 1.17 has no equal_nan)
    for (r, a0, inc, pose), got in zip(scans, first):
        # the body's returns are gone, the mixed pixels too, the wall and the post are kept
        body = body_returns(r, beam_angles(a0, inc, len(r)), pose) & np.isfinite(r)
        assert body.any() and np.isnan(got[body]).all()
        n = len(r)
        assert np.isnan(got[n // 2 - 6]) and np.isnan(got[n // 2 + 5])
        assert np.isfinite(got[n // 2 - 4:n // 2 + 4]).all()


def test_information_at_any_heading_is_the_heading_free_one_turned():
    """scan_information at heading ``yaw`` against J written out in map: rows
    ``(nx, ny, n · ∂q/∂yaw)`` with the normal and the point turned by ``yaw``."""
    rng = np.random.default_rng(5)
    pts = rng.uniform(-4.0, 4.0, (60, 2))
    ang = rng.uniform(-math.pi, math.pi, 60)
    normals = np.column_stack((np.cos(ang), np.sin(ang)))
    w = rng.uniform(0.0, 1.0, 60)
    for yaw in (0.0, 0.7, -2.5, math.pi):
        c, s = math.cos(yaw), math.sin(yaw)
        nx, ny = c * normals[:, 0] - s * normals[:, 1], s * normals[:, 0] + c * normals[:, 1]
        dqx, dqy = -s * pts[:, 0] - c * pts[:, 1], c * pts[:, 0] - s * pts[:, 1]
        j = np.column_stack((nx, ny, nx * dqx + ny * dqy))
        want = (j * w[:, None]).T @ j
        assert np.allclose(scan_information(pts, normals, w, yaw), want, rtol=1e-12, atol=1e-12)


def test_corridor_axis_is_the_weak_direction_at_every_heading():
    """A corridor's scan (two parallel walls) turned by any heading: one weak direction, the
    corridor's axis in map, and the same eigenvalues."""
    xs = np.linspace(-3.0, 3.0, 61)
    pts = np.concatenate([np.column_stack((xs, np.full_like(xs, y))) for y in (-0.55, 0.55)])
    normals, ok = scan_normals(pts)
    assert ok.sum() > 100
    w = ok.astype(float)
    vals0 = None
    for yaw in (0.0, 0.4, 2.0):
        strong, weak, vals, _ = observable_directions(scan_information(pts, normals, w, yaw),
                                                      pts, w, 0.01)
        assert weak.shape[1] == 1
        axis = weak[:2, 0] / np.linalg.norm(weak[:2, 0])
        assert abs(abs(axis @ np.array([math.cos(yaw), math.sin(yaw)])) - 1.0) < 1e-9
        vals0 = vals if vals0 is None else vals0
        assert np.allclose(vals, vals0, rtol=1e-9, atol=1e-12)


def test_distance_field_lookup_is_bilinear_with_the_border_kept():
    """The field's three values at once against scipy's map_coordinates of each (order 1,
    the border's value beyond it), inside, on and far outside the grid."""
    grid = rasterise_world(World.from_dict(corridor_world(1.1, length=4.0)))
    f = DistanceField(grid)
    g = f.grid
    rng = np.random.default_rng(2)
    lo = np.array(g.origin[:2])
    hi = lo + np.array(g.data.shape[::-1]) * g.resolution
    pts = np.concatenate((rng.uniform(lo - 1.0, hi + 1.0, (500, 2)),
                          [lo, hi, lo - 1e6, hi + 1e6]))
    got = f(pts)
    rows = (pts[:, 1] - g.origin[1]) / g.resolution - 0.5
    cols = (pts[:, 0] - g.origin[0]) / g.resolution - 0.5
    for a, v in zip((f.values,) + f.gradient, got):
        want = ndimage.map_coordinates(a.astype(float), np.vstack((rows, cols)), order=1,
                                       mode='nearest')
        np.testing.assert_allclose(v, want, rtol=0, atol=1e-6)
    x, y = pts[:, 0].copy(), pts[:, 1].copy()
    for v, w in zip(f.at(x, y), got):
        assert np.array_equal(v, w)
