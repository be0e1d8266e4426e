"""Lost detection, global search and relocalisation (no ROS): synthetic scans ray-cast in an
occupancy grid; the localiser must say when it is lost, find itself from anywhere on the map,
and never accept one of two look-alike places (a symmetric corridor)."""
import math
import re

import numpy as np
import pytest

from tiago_nav.geometry import compose, inverse
from tiago_nav.gridmap import GridMap
from tiago_nav.localisation import global_search
from tiago_nav.localisation.health import ERROR, OK, WARN, FitMonitor
from tiago_nav.localisation.recovery import RecoveringLocaliser
from tiago_nav_tools.testing.localisation import raster_config

RES = 0.05
SENSOR = (0.0, 0.0)


def room_map():
    """A 16 m × 10 m floor with inner walls and boxes placed without symmetry."""
    data = np.zeros((int(10 / RES), int(16 / RES)), dtype=np.int8)

    def box(x0, y0, x1, y1):
        data[int(y0 / RES):int(math.ceil(y1 / RES)), int(x0 / RES):int(math.ceil(x1 / RES))] = 100
    box(0, 0, 16, 0.1)
    box(0, 9.9, 16, 10)
    box(0, 0, 0.1, 10)
    box(15.9, 0, 16, 10)
    box(6, 0, 6.1, 6)           # inner walls with gaps of different widths
    box(11, 3.5, 11.1, 10)
    box(2, 7, 3.5, 7.6)         # furniture
    box(8.5, 2, 9.2, 2.4)
    box(13, 1, 13.4, 2.5)
    box(3, 2, 3.3, 3.8)
    return GridMap(data, RES, (0.0, 0.0))


def corridor_map(length=40.0, width=1.2):
    """A straight corridor, ends beyond the registration's 12 m range from its middle."""
    data = np.zeros((int((width + 0.4) / RES), int(length / RES)), dtype=np.int8)
    data[:4, :] = 100
    data[-4:, :] = 100
    data[:, :4] = 100
    data[:, -4:] = 100
    return GridMap(data, RES, (0.0, 0.0))


def scan(grid, pose, n=181, max_range=12.0):
    """Points [m] in base_footprint of a 180° scan ray-cast from ``pose`` in ``grid``."""
    occ = grid.data >= 50
    out = []
    for b in np.linspace(-math.pi / 2, math.pi / 2, n):
        th = pose[2] + b
        for r in np.arange(0.1, max_range, RES / 2):
            x, y = pose[0] + r * math.cos(th), pose[1] + r * math.sin(th)
            i, j = int((y - grid.origin[1]) / RES), int((x - grid.origin[0]) / RES)
            if not (0 <= i < occ.shape[0] and 0 <= j < occ.shape[1]):
                break
            if occ[i, j]:
                out.append((r * math.cos(b), r * math.sin(b)))
                break
    return np.array(out)


def drive(loc, grid, poses, odom_start=(0.0, 0.0, 0.0), true_odom=None):
    """Feed the scans at the true ``poses``, odometry exact (or ``true_odom``'s); returns the
    estimates and the health levels after each scan."""
    est, levels = [], []
    for k, p in enumerate(poses):
        odom = compose(odom_start, compose(inverse(poses[0]), p)) if true_odom is None \
            else true_odom[k]
        if loc.due(odom):
            pts = loc.scan_points(*_as_scan(scan(grid, p)))
            up = loc.update(odom, pts, SENSOR)
            est.append(up.pose)
        else:
            est.append(loc.follow(odom)[0])
        levels.append(loc.health.level)
    return est, levels


def _as_scan(pts):
    """Polar ranges of ``pts`` for :meth:`scan_points` (one range per integer-degree beam)."""
    ranges = np.full(181, np.inf)
    ang = np.degrees(np.arctan2(pts[:, 1], pts[:, 0]))
    idx = np.round(ang + 90).astype(int)
    ranges[idx] = np.hypot(pts[:, 0], pts[:, 1])
    return ranges, -math.pi / 2, math.radians(1.0), 0.02, 30.0, (0.0, 0.0, 0.0)


def path(start, n, step=0.3, turn=math.radians(4.0)):
    out = [tuple(start)]
    for _ in range(n - 1):
        out.append(compose(out[-1], (step, 0.0, turn)))
    return out


def err(a, b):
    return math.hypot(a[0] - b[0], a[1] - b[1])


def test_monitor_levels():
    m = FitMonitor()
    for _ in range(3):
        h = m.add(0.9, False)
    assert h.level == OK
    h = m.add(0.35, True)
    assert h.level == WARN and 'rejected' in h.message
    for _ in range(3):
        h = m.add(0.1, True)
    assert h.level == ERROR and h.message.startswith('lost')
    m.clear()
    levels = [m.add(0.4, False).level for _ in range(8)]
    assert levels[0] == WARN and levels[-1] == ERROR    # degraded for long: lost


def test_monitor_a_fit_that_falls_well_below_its_usual_is_degraded_then_lost():
    # a pose carried along a corridor: the walls still fit, the doors and the ends do not
    m = FitMonitor()
    for _ in range(30):
        assert m.add(0.97, False).level == OK
    healths = [m.add(0.6, False) for _ in range(10)]
    levels = [h.level for h in healths]
    assert OK in levels[:2] and WARN in levels and levels[-1] == ERROR
    assert any(re.search(r'usually 9\d %', h.message) for h in healths if h.level == WARN)
    # a person passing a few metres away takes a few points off: still OK
    m.clear()
    for _ in range(30):
        m.add(0.97, False)
    assert all(m.add(f, False).level == OK for f in (0.85, 0.8, 0.78, 0.85, 0.95))
    # a building whose usual share is lower (furniture) is judged by its own usual
    m.clear()
    assert all(m.add(f, False).level == OK for f in [0.62] * 30 + [0.55] * 5)


def test_global_search_finds_the_pose_anywhere():
    grid = room_map()
    pyr = global_search.LikelihoodPyramid(grid)
    for pose in [(2.0, 5.0, 0.3), (9.0, 7.5, -2.0), (13.5, 4.0, 2.8), (4.5, 1.0, 1.2)]:
        poses, scores = global_search.search(pyr, scan(grid, pose))
        assert len(poses)
        assert err(poses[0], pose) < 0.15, (pose, poses[0], scores)
        assert abs(math.remainder(poses[0][2] - pose[2], 2 * math.pi)) < math.radians(3)


def test_global_localization_converges_and_reports_lost_meanwhile():
    grid = room_map()
    truth = path((2.0, 5.0, 0.0), 12)
    loc = RecoveringLocaliser(grid, (12.0, 8.0, 2.0), odom=(0.0, 0.0, 0.0), config=raster_config())
    loc.global_localization()
    assert loc.health.level == ERROR
    est, levels = drive(loc, grid, truth)
    ok = [k for k in range(len(truth)) if err(est[k], truth[k]) < 0.1]
    assert ok and ok[0] <= 6
    assert levels[0] == ERROR
    assert all(err(est[k], truth[k]) < 0.1 for k in range(ok[0], len(truth)))
    assert levels[-1] == OK and not loc.relocalising


def test_kidnap_is_detected_and_recovered():
    grid = room_map()
    before = path((2.0, 5.0, 0.0), 6)
    after = path((4.5, 1.0, 1.2), 14)
    truth = before + after
    # the odometry says nothing about the jump
    odom = [compose(inverse(before[0]), p) for p in before]
    odom += [compose(odom[-1], compose(inverse(after[0]), p)) for p in after]
    loc = RecoveringLocaliser(grid, before[0], odom=odom[0], config=raster_config())
    est, levels = drive(loc, grid, truth, true_odom=odom)
    assert all(err(est[k], truth[k]) < 0.1 for k in range(len(before)))
    assert all(v == OK for v in levels[2:len(before)])
    tail = range(len(before), len(truth))
    back = [k for k in tail if err(est[k], truth[k]) < 0.1]
    assert back and back[0] - len(before) <= 10
    assert ERROR in levels[len(before):back[0]]         # lost said meanwhile
    assert levels[-1] == OK


def test_wide_initialpose_is_searched_around():
    grid = room_map()
    truth = path((9.0, 7.5, -2.0), 10)
    given = (truth[0][0] + 1.5, truth[0][1] - 1.0, truth[0][2] + math.radians(60))
    loc = RecoveringLocaliser(grid, given, odom=(0.0, 0.0, 0.0), config=raster_config())
    loc.reset(given, np.diag([1.0, 1.0, math.radians(40) ** 2]))
    assert loc.relocalising
    est, _ = drive(loc, grid, truth)
    assert err(est[-1], truth[-1]) < 0.1


def test_narrow_initialpose_keeps_the_tracker_search():
    grid = room_map()
    loc = RecoveringLocaliser(grid, (2.0, 5.0, 0.0), odom=(0.0, 0.0, 0.0), config=raster_config())
    loc.reset((2.1, 5.0, 0.0), np.diag([0.1 ** 2, 0.1 ** 2, math.radians(5) ** 2]))
    assert not loc.relocalising


def test_symmetric_corridor_never_accepts_a_look_alike():
    grid = corridor_map()
    # in the middle, both ends out of range: every place along it fits alike
    truth = path((20.0, 0.8, 0.0), 8, step=0.2, turn=0.0)
    loc = RecoveringLocaliser(grid, (12.0, 0.8, 0.0), odom=(0.0, 0.0, 0.0), config=raster_config())
    loc.global_localization()
    est, levels = drive(loc, grid, truth)
    assert loc.relocalising and all(v == ERROR for v in levels)
    # the estimate did not jump to one of the look-alikes: it stayed where odometry took it
    assert all(err(e, (12.0 + 0.2 * k, 0.8)) < 1e-6 for k, e in enumerate(est))


@pytest.mark.parametrize('bad', [dict(window=0), dict(good_fit=0.2, lost_fit=0.3)])
def test_monitor_rejects_bad_settings(bad):
    with pytest.raises(ValueError):
        FitMonitor(**bad)


def test_a_degraded_estimate_is_judged_over_scans_of_time_not_of_motion():
    from tiago_nav.localisation.health import DEGRADED_LIMIT
    grid = room_map()
    # the room as the laser sees it: things the map does not have hide most of the walls in
    # front of the robot, so about 60 % of the points are off the map
    world = GridMap(grid.data.copy(), RES, (0.0, 0.0))

    def box(x0, y0, x1, y1):
        world.data[int(y0 / RES):int(math.ceil(y1 / RES)),
                   int(x0 / RES):int(math.ceil(x1 / RES))] = 100
    box(9.8, 5.0, 10.0, 9.0)
    box(7.0, 5.8, 9.5, 6.0)
    box(8.2, 9.0, 10.0, 9.2)
    box(8.2, 6.4, 9.8, 6.6)
    # creeping: 1 cm a scan, far below the distance between registrations
    truth = path((8.0, 7.5, 0.0), DEGRADED_LIMIT + 4, step=0.01, turn=0.0)
    loc = RecoveringLocaliser(grid, truth[0], odom=(0.0, 0.0, 0.0), config=raster_config())
    levels = []
    for p in truth:
        odom = compose(inverse(truth[0]), p)
        if loc.due(odom):
            loc.update(odom, loc.scan_points(*_as_scan(scan(world, p))), SENSOR)
        else:
            loc.follow(odom)
        levels.append(loc.health.level)
    assert levels[0] == WARN
    assert ERROR in levels[:DEGRADED_LIMIT + 1], levels
